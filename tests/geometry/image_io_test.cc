// Tests of image reading/writing through OpenCV: RGB order, real JPEG/PNG
// files, sizes, and errors for missing, non-image and truncated files.

#include "geometry/image_io.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

const char kNuscenesJpeg[] =
    "nuscenes_n015/"
    "n015-2018-07-24-11-22-45+0800__CAM_FRONT__1532402927612460.jpg";
const char kKittiPng[] = "kitti_000008/000008.png";

template <typename Fn>
std::string ErrorOf(Fn fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void WriteAll(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

cv::Mat RandomImage(int rows, int cols, int type) {
  cv::Mat image(rows, cols, type);
  cv::randu(image, cv::Scalar::all(0),
            cv::Scalar::all(type == CV_16UC1 ? 65535 : 255));
  return image;
}

double MaxAbsDiff(const cv::Mat& a, const cv::Mat& b) {
  return cv::norm(a, b, cv::NORM_INF);
}

TEST(ImageIo, PngRoundTripIsExactAndRgb) {
  const std::string path = test::MakeTempDir("img_png") + "/a.png";
  cv::Mat rgb(2, 3, CV_8UC3, cv::Scalar(0, 0, 0));
  rgb.at<cv::Vec3b>(0, 0) = cv::Vec3b(255, 0, 0);  // pure red in RGB order
  rgb.at<cv::Vec3b>(1, 2) = cv::Vec3b(10, 20, 30);
  WriteImageRgb(path, rgb);
  const cv::Mat back = ReadImageRgb(path);
  ASSERT_EQ(back.type(), CV_8UC3);
  EXPECT_EQ(MaxAbsDiff(back, rgb), 0.0);
  // On disk (and for OpenCV) the channels are BGR: red is the last channel.
  const cv::Mat bgr = cv::imread(path, cv::IMREAD_UNCHANGED);
  EXPECT_EQ(bgr.at<cv::Vec3b>(0, 0), cv::Vec3b(0, 0, 255));
  EXPECT_EQ(ReadImageUnchanged(path).at<cv::Vec3b>(1, 2),
            cv::Vec3b(30, 20, 10));
}

TEST(ImageIo, RandomRgbGrayAnd16BitPngRoundTrips) {
  const std::string dir = test::MakeTempDir("img_types");
  const cv::Mat rgb = RandomImage(37, 53, CV_8UC3);
  WriteImageRgb(dir + "/rgb.png", rgb);
  EXPECT_EQ(MaxAbsDiff(ReadImageRgb(dir + "/rgb.png"), rgb), 0.0);

  const cv::Mat gray = RandomImage(37, 53, CV_8UC1);
  WriteImageRgb(dir + "/gray.png", gray);
  const cv::Mat gray_back = ReadImageGray(dir + "/gray.png");
  ASSERT_EQ(gray_back.type(), CV_8UC1);
  EXPECT_EQ(MaxAbsDiff(gray_back, gray), 0.0);

  const cv::Mat depth16 = RandomImage(11, 7, CV_16UC1);
  WriteImageRgb(dir + "/depth.png", depth16);
  const cv::Mat depth_back = ReadImageUnchanged(dir + "/depth.png");
  ASSERT_EQ(depth_back.type(), CV_16UC1);
  EXPECT_EQ(MaxAbsDiff(depth_back, depth16), 0.0);
}

TEST(ImageIo, PngWritesAreDeterministic) {
  const std::string dir = test::MakeTempDir("img_determinism");
  const cv::Mat rgb = RandomImage(64, 64, CV_8UC3);
  WriteImageRgb(dir + "/a.png", rgb);
  WriteImageRgb(dir + "/b.png", rgb);
  EXPECT_EQ(ReadAll(dir + "/a.png"), ReadAll(dir + "/b.png"));
}

TEST(ImageIo, JpegRoundTripIsClose) {
  const std::string path = test::MakeTempDir("img_jpeg") + "/a.jpg";
  cv::Mat rgb(64, 96, CV_8UC3);
  for (int r = 0; r < rgb.rows; ++r) {
    for (int c = 0; c < rgb.cols; ++c)
      rgb.at<cv::Vec3b>(r, c) = cv::Vec3b(200, 2 * c, 3 * r);
  }
  WriteImageRgb(path, rgb);
  const cv::Mat back = ReadImageRgb(path);
  // Smooth gradients at quality 95: mean error well under 2 levels; a channel
  // swap would be off by ~100 on average.
  cv::Mat diff;
  cv::absdiff(back, rgb, diff);
  EXPECT_LT(cv::mean(diff)[0] + cv::mean(diff)[1] + cv::mean(diff)[2], 6.0);
}

TEST(ImageIo, ReadsRealNuscenesJpeg) {
  const cv::Mat rgb = ReadImageRgb(test::RealDataPath(kNuscenesJpeg));
  EXPECT_EQ(rgb.cols, 1600);
  EXPECT_EQ(rgb.rows, 900);
  EXPECT_EQ(rgb.type(), CV_8UC3);
  // Consistent with OpenCV's own decode, channels swapped.
  const cv::Mat bgr =
      cv::imread(test::RealDataPath(kNuscenesJpeg), cv::IMREAD_COLOR);
  cv::Mat swapped;
  cv::cvtColor(bgr, swapped, cv::COLOR_BGR2RGB);
  EXPECT_EQ(MaxAbsDiff(rgb, swapped), 0.0);
  const cv::Mat gray = ReadImageGray(test::RealDataPath(kNuscenesJpeg));
  EXPECT_EQ(gray.type(), CV_8UC1);
  EXPECT_EQ(gray.size(), rgb.size());
}

TEST(ImageIo, ReadsRealKittiPng) {
  const cv::Mat rgb = ReadImageRgb(test::RealDataPath(kKittiPng));
  EXPECT_EQ(rgb.size(), cv::Size(1242, 375));
}

TEST(ImageIo, ReadImageSizeMatchesDecodedSize) {
  EXPECT_EQ(ReadImageSize(test::RealDataPath(kNuscenesJpeg)),
            cv::Size(1600, 900));
  EXPECT_EQ(ReadImageSize(test::RealDataPath(kKittiPng)), cv::Size(1242, 375));
  const std::string dir = test::MakeTempDir("img_size");
  WriteImageRgb(dir + "/a.png", RandomImage(17, 29, CV_8UC1));
  WriteImageRgb(dir + "/b.jpg", RandomImage(31, 13, CV_8UC3));
  WriteImageRgb(dir + "/c.bmp", RandomImage(5, 9, CV_8UC3));
  EXPECT_EQ(ReadImageSize(dir + "/a.png"), cv::Size(29, 17));
  EXPECT_EQ(ReadImageSize(dir + "/b.jpg"), cv::Size(13, 31));
  EXPECT_EQ(ReadImageSize(dir + "/c.bmp"), cv::Size(9, 5));
}

TEST(ImageIo, MissingFileSaysCannotOpen) {
  const std::string path = test::MakeTempDir("img_missing") + "/missing.png";
  EXPECT_EQ(ErrorOf([&] { ReadImageRgb(path); }),
            path + ": cannot open (No such file or directory)");
  EXPECT_EQ(ErrorOf([&] { ReadImageSize(path); }),
            path + ": cannot open (No such file or directory)");
}

TEST(ImageIo, NonImageFileIsRejected) {
  const std::string dir = test::MakeTempDir("img_not_image");
  WriteAll(dir + "/notes.png", "this is a text file, not a PNG\n");
  EXPECT_EQ(
      ErrorOf([&] { ReadImageRgb(dir + "/notes.png"); }),
      dir +
          "/notes.png: not a readable image (unknown format or corrupt data)");
  WriteAll(dir + "/empty.jpg", "");
  EXPECT_EQ(ErrorOf([&] { ReadImageGray(dir + "/empty.jpg"); }),
            dir + "/empty.jpg: empty file (expected an image)");
  EXPECT_THAT(ErrorOf([&] { ReadImageRgb(dir); }),
              StartsWith(dir + ": is a directory"));
}

TEST(ImageIo, TruncatedJpegIsRejected) {
  // libjpeg only warns ("Premature end of JPEG file") and returns a half-grey
  // image; the reader must refuse it instead.
  const std::string path = test::MakeTempDir("img_trunc_jpeg") + "/cut.jpg";
  const std::string full = ReadAll(test::RealDataPath(kNuscenesJpeg));
  for (size_t keep :
       {full.size() / 2, full.size() - 2, size_t{1000}, size_t{3}}) {
    WriteAll(path, full.substr(0, keep));
    EXPECT_EQ(ErrorOf([&] { ReadImageRgb(path); }),
              path + ": truncated or corrupt JPEG (no end-of-image marker)")
        << keep;
  }
  WriteAll(path, full.substr(0, full.size() / 2));
  EXPECT_THAT(ErrorOf([&] { ReadImageSize(path); }), HasSubstr("truncated"));
}

TEST(ImageIo, TruncatedPngIsRejected) {
  const std::string path = test::MakeTempDir("img_trunc_png") + "/cut.png";
  const std::string full = ReadAll(test::RealDataPath(kKittiPng));
  for (size_t keep :
       {full.size() / 2, full.size() - 1, size_t{40}, size_t{9}}) {
    WriteAll(path, full.substr(0, keep));
    EXPECT_EQ(ErrorOf([&] { ReadImageRgb(path); }),
              path + ": truncated or corrupt PNG (no IEND chunk)")
        << keep;
  }
  // A complete chunk structure with corrupt pixel data still fails (in the
  // decoder).
  std::string corrupt = full;
  for (size_t i = 200; i < 2000; ++i)
    corrupt[i] = static_cast<char>(corrupt[i] ^ 0x5a);
  WriteAll(path, corrupt);
  EXPECT_EQ(ErrorOf([&] { ReadImageRgb(path); }),
            path + ": cannot decode image (truncated or corrupt data)");
}

TEST(ImageIo, WriteErrorsNameTheFile) {
  const std::string dir = test::MakeTempDir("img_write_errors");
  EXPECT_THAT(
      ErrorOf([&] { WriteImageRgb(dir + "/f.png", cv::Mat(4, 4, CV_32FC1)); }),
      StartsWith(dir + "/f.png: cannot write image of OpenCV type"));
  EXPECT_THAT(ErrorOf([&] { WriteImageRgb(dir + "/e.png", cv::Mat()); }),
              StartsWith(dir + "/e.png: cannot write an empty image"));
  EXPECT_THAT(ErrorOf([&] {
                WriteImageRgb(dir + "/a.xyz", RandomImage(4, 4, CV_8UC3));
              }),
              StartsWith(dir + "/a.xyz: cannot encode image as .xyz"));
  EXPECT_THAT(ErrorOf([&] {
                WriteImageRgb(dir + "/no/dir/a.png",
                              RandomImage(4, 4, CV_8UC3));
              }),
              StartsWith(dir + "/no/dir/a.png: cannot write"));
  EXPECT_TRUE(std::filesystem::is_empty(dir));
}

}  // namespace
}  // namespace geodrive

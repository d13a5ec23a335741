#include "render/video/video.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgproc.hpp>

#include "geometry/image_io.h"
#include "geometry/util/status.h"
#include "render/video/video_io.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

std::vector<cv::Mat> MakeFrames(int n, int w, int h) {
  std::vector<cv::Mat> frames;
  for (int i = 0; i < n; ++i) {
    cv::Mat m(h, w, CV_8UC3);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        m.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uint8_t>(x * 255 / w),
                                          static_cast<uint8_t>(y * 255 / h),
                                          static_cast<uint8_t>(i * 255 / n));
      }
    }
    frames.push_back(m);
  }
  return frames;
}

TEST(Video, H264Mp4WritesAndReadsBack) {
  const std::string dir = test::MakeTempDir("video_h264");
  const std::vector<cv::Mat> frames = MakeFrames(12, 160, 96);
  const std::string path = dir + "/clip.mp4";
  const VideoWriteResult r = WriteVideo(path, frames);
  std::cout << "[video] fourcc used: " << r.fourcc
            << (r.fell_back ? " (fallback)" : "") << "\n";
  // Debian's OpenCV 4.6 + FFmpeg 5.1 (libx264) provides avc1; a fallback here
  // means the install lost H.264 support.
  EXPECT_EQ(r.fourcc, "avc1");
  EXPECT_FALSE(r.fell_back);
  EXPECT_EQ(r.frames, 12);
  // Our FFmpeg reader (equal to cv2.VideoCapture frame for frame:
  // video_reader_test.cc).
  const std::vector<cv::Mat> back = ReadVideoFrames(path);
  int count = 0;
  double max_mean_err = 0;
  for (const cv::Mat& rgb : back) {
    ASSERT_EQ(rgb.cols, 160);
    ASSERT_EQ(rgb.rows, 96);
    cv::Mat diff;
    cv::absdiff(rgb, frames[count], diff);
    const cv::Scalar m = cv::mean(diff);
    max_mean_err = std::max({max_mean_err, m[0], m[1], m[2]});
    ++count;
  }
  EXPECT_EQ(count, 12);
  // Lossy but close on smooth gradients (RGB order preserved: a swapped R/B
  // gives ~100).
  EXPECT_LT(max_mean_err, 6.0);
}

TEST(Video, OddSizesArePaddedForH264) {
  const std::string dir = test::MakeTempDir("video_odd");
  const VideoWriteResult r =
      WriteVideo(dir + "/odd.mp4", MakeFrames(3, 99, 51));
  EXPECT_EQ(r.width, 100);
  EXPECT_EQ(r.height, 52);
}

TEST(Video, UnknownCodecFallsBackWithWarning) {
  const std::string dir = test::MakeTempDir("video_fallback");
  VideoWriteOptions o;
  o.fourcc = "zzzz";  // no such encoder
  const VideoWriteResult r =
      WriteVideo(dir + "/fb.mp4", MakeFrames(3, 64, 48), o);
  EXPECT_TRUE(r.fell_back);
  EXPECT_EQ(r.fourcc, "mp4v");
  o.fallback_fourcc = "";
  EXPECT_THROW(WriteVideo(dir + "/none.mp4", MakeFrames(3, 64, 48), o),
               InputError);
}

TEST(Video, PngSequenceIsLossless) {
  const std::string dir = test::MakeTempDir("video_png");
  const std::vector<cv::Mat> frames = MakeFrames(4, 33, 17);
  const std::vector<std::string> paths =
      WritePngSequence(dir + "/frames", "render_", frames);
  ASSERT_EQ(paths.size(), 4u);
  EXPECT_EQ(std::filesystem::path(paths[3]).filename().string(),
            "render_0003.png");
  for (size_t i = 0; i < paths.size(); ++i) {
    const cv::Mat back = ReadImageRgb(paths[i]);
    EXPECT_EQ(cv::norm(back, frames[i], cv::NORM_INF), 0.0);
  }
}

TEST(Video, ContactSheetLayoutWithGroundTruthAbove) {
  std::vector<cv::Mat> renders, gt;
  for (int i = 0; i < 7; ++i) {
    renders.emplace_back(48, 64, CV_8UC3, cv::Scalar(200, 0, 0));
    gt.emplace_back(48, 64, CV_8UC3, cv::Scalar(0, 0, 200));
  }
  ContactSheetOptions o;
  o.columns = 3;
  o.thumb_width = 64;
  o.gap = 2;
  const cv::Mat sheet = MakeContactSheet(renders, gt, o);
  // 7 frames in 3 columns: 3 grid rows, each a GT row + a render row.
  EXPECT_EQ(sheet.cols, 3 * 64 + 4 * 2);
  EXPECT_EQ(sheet.rows, 6 * 48 + 7 * 2);
  EXPECT_EQ(sheet.at<cv::Vec3b>(2 + 10, 2 + 10),
            cv::Vec3b(0, 0, 200));  // GT, row 0
  EXPECT_EQ(sheet.at<cv::Vec3b>(2 + 48 + 2 + 10, 2 + 10),
            cv::Vec3b(200, 0, 0));  // render, row 1
  const cv::Mat plain = MakeContactSheet(renders, {}, o);
  EXPECT_EQ(plain.rows, 3 * 48 + 4 * 2);
  EXPECT_THROW(MakeContactSheet(renders, {gt[0]}, o), InputError);
  EXPECT_THROW(WriteVideo("/nonexistent_dir/x.mp4", {}), InputError);
}

// Thumbnails take AreaResizeRgb when they shrink an RGB frame: cv::resize's
// INTER_AREA within 1 level (its float sums run in another order), at the
// builder's 720x480 -> 160 (a non-integer 4.5x) and an integer 2x; other
// cases (growing, gray) are cv::resize itself.
TEST(Video, ContactSheetThumbnailIsInterArea) {
  cv::RNG rng(5);
  cv::Mat frame(480, 720, CV_8UC3);
  rng.fill(frame, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(frame, frame, cv::Size(5, 5), 1.0);  // some structure
  for (int width : {160, 360, 719}) {
    ContactSheetOptions o;
    o.thumb_width = width;
    const cv::Mat thumb = ContactSheetThumbnail(frame, o);
    cv::Mat ref;
    cv::resize(frame, ref, thumb.size(), 0, 0, cv::INTER_AREA);
    ASSERT_EQ(thumb.type(), CV_8UC3);
    EXPECT_EQ(thumb.size(), ref.size());
    EXPECT_LE(cv::norm(thumb, ref, cv::NORM_INF), 1.0) << width;
    // A sheet of thumbnails is the sheet of the frames.
    EXPECT_EQ(cv::norm(MakeContactSheet({thumb}, {thumb}, o),
                       MakeContactSheet({frame}, {frame}, o), cv::NORM_INF),
              0.0);
  }
  ContactSheetOptions grow;
  grow.thumb_width = 800;
  cv::Mat ref;
  const cv::Mat big = ContactSheetThumbnail(frame, grow);
  cv::resize(frame, ref, big.size(), 0, 0, cv::INTER_AREA);
  EXPECT_EQ(cv::norm(big, ref, cv::NORM_INF), 0.0);
  cv::Mat gray(48, 64, CV_8UC1, cv::Scalar(9));
  EXPECT_EQ(ContactSheetThumbnail(gray, grow).type(), CV_8UC1);
}

}  // namespace
}  // namespace geodrive

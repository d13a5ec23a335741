// Tests of image reading/writing through TurboJPEG and libspng: pixels
// identical to cv::imdecode (JPEG of every subsampling, progressive, gray and
// CMYK; PNG of every colour type and bit depth, tRNS, interlaced; the real
// nuScenes and KITTI images; EXIF orientation), RGB order, sizes from headers,
// hardening (corrupt or cut JPEG scans, huge headers, bad CRCs) and errors for
// missing, non-image and truncated files.

#include "geometry/image_io.h"

#include <gtest/gtest.h>
#include <spng.h>
#include <sys/resource.h>
#include <turbojpeg.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace image_io_test {
namespace {

namespace fs = std::filesystem;
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

cv::Mat RandomImage(int rows, int cols, int type) {
  cv::Mat image(rows, cols, type);
  cv::randu(image, cv::Scalar::all(0),
            cv::Scalar::all(CV_MAT_DEPTH(type) == CV_16U ? 65535 : 255));
  return image;
}

// A smooth colour image with some noise: realistic input for JPEG.
cv::Mat SmoothImage(int rows, int cols) {
  cv::Mat rgb(rows, cols, CV_8UC3);
  std::uniform_int_distribution<int> noise(-12, 12);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      rgb.at<cv::Vec3b>(r, c) = cv::Vec3b(
          cv::saturate_cast<uint8_t>(200 - r + noise(test::Rng())),
          cv::saturate_cast<uint8_t>(3 * c + noise(test::Rng())),
          cv::saturate_cast<uint8_t>(128 + 100 * std::sin(0.3 * (r + c))));
    }
  }
  return rgb;
}

double MaxAbsDiff(const cv::Mat& a, const cv::Mat& b) {
  return cv::norm(a, b, cv::NORM_INF);
}

// Same type, size and bytes.
::testing::AssertionResult Identical(const cv::Mat& ours,
                                     const cv::Mat& opencv) {
  if (ours.type() != opencv.type() || ours.size() != opencv.size()) {
    return ::testing::AssertionFailure()
           << "type/size " << ours.type() << " " << ours.size() << " vs "
           << opencv.type() << " " << opencv.size();
  }
  const size_t row_bytes = ours.cols * ours.elemSize();
  int differing_rows = 0;
  for (int r = 0; r < ours.rows; ++r)
    differing_rows += std::memcmp(ours.ptr(r), opencv.ptr(r), row_bytes) != 0;
  if (differing_rows > 0) {
    return ::testing::AssertionFailure()
           << differing_rows << " of " << ours.rows << " rows differ";
  }
  return ::testing::AssertionSuccess();
}

cv::Mat CvDecode(const std::string& bytes, int flags) {
  const std::vector<uint8_t> buf(bytes.begin(), bytes.end());
  return cv::imdecode(buf, flags);
}

// ReadImageRgb/Gray/Unchanged and ReadImageSize against cv::imdecode with
// IMREAD_COLOR (channels swapped), IMREAD_GRAYSCALE and IMREAD_UNCHANGED.
void ExpectSameAsOpenCv(const std::string& path, const std::string& what) {
  SCOPED_TRACE(what);
  const std::string bytes = test::ReadFile(path);
  const cv::Mat bgr = CvDecode(bytes, cv::IMREAD_COLOR);
  ASSERT_FALSE(bgr.empty());
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  EXPECT_TRUE(Identical(ReadImageRgb(path), rgb)) << "colour";
  EXPECT_TRUE(
      Identical(ReadImageGray(path), CvDecode(bytes, cv::IMREAD_GRAYSCALE)))
      << "gray";
  EXPECT_TRUE(Identical(ReadImageUnchanged(path),
                        CvDecode(bytes, cv::IMREAD_UNCHANGED)))
      << "unchanged";
  EXPECT_EQ(ReadImageSize(path), bgr.size());
}

// ---- Crafting files ----

std::string Be16(uint32_t v) { return {char(v >> 8), char(v)}; }
std::string Be32(uint32_t v) {
  return {char(v >> 24), char(v >> 16), char(v >> 8), char(v)};
}
std::string Le16(uint32_t v) { return {char(v), char(v >> 8)}; }
std::string Le32(uint32_t v) {
  return {char(v), char(v >> 8), char(v >> 16), char(v >> 24)};
}

uint32_t Crc32(const std::string& s) {
  uint32_t c = 0xFFFFFFFFu;
  for (unsigned char b : s) {
    c ^= b;
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return ~c;
}

std::string PngChunk(const std::string& type, const std::string& data) {
  return Be32(data.size()) + type + data + Be32(Crc32(type + data));
}

// A zlib stream of stored (uncompressed) deflate blocks.
std::string ZlibStored(const std::string& raw) {
  std::string out = "\x78\x01";
  size_t i = 0;
  do {
    const size_t n = std::min<size_t>(65535, raw.size() - i);
    out += char(i + n == raw.size() ? 1 : 0);
    out += Le16(n) + Le16(~n & 0xFFFF) + raw.substr(i, n);
    i += n;
  } while (i < raw.size());
  uint32_t a = 1, b = 0;
  for (unsigned char c : raw) {
    a = (a + c) % 65521;
    b = (b + a) % 65521;
  }
  return out + Be32((b << 16) | a);
}

// A PNG of `samples` (rows x cols*channels values of `bit_depth` bits, packed
// MSB first; 16-bit big-endian), not interlaced.
std::string MakePng(int cols,
                    int rows,
                    int color_type,
                    int bit_depth,
                    const std::vector<int>& samples,
                    const std::string& before_idat = "",
                    const std::string& after_idat = "") {
  const int channels = color_type == 0   ? 1
                       : color_type == 2 ? 3
                       : color_type == 3 ? 1
                       : color_type == 4 ? 2
                                         : 4;
  std::string raw;
  const size_t per_row = size_t(cols) * channels;
  for (int r = 0; r < rows; ++r) {
    raw += '\0';  // filter: none
    if (bit_depth >= 8) {
      for (size_t k = 0; k < per_row; ++k) {
        const int v = samples[r * per_row + k];
        raw += bit_depth == 16 ? Be16(v) : std::string(1, char(v));
      }
    } else {
      int acc = 0, bits = 0;
      for (size_t k = 0; k < per_row; ++k) {
        acc = (acc << bit_depth) | samples[r * per_row + k];
        bits += bit_depth;
        if (bits == 8) {
          raw += char(acc);
          acc = bits = 0;
        }
      }
      if (bits > 0) raw += char(acc << (8 - bits));
    }
  }
  const std::string ihdr = Be32(cols) + Be32(rows) + char(bit_depth) +
                           char(color_type) + std::string(3, '\0');
  return std::string("\x89PNG\r\n\x1a\n", 8) + PngChunk("IHDR", ihdr) +
         before_idat + PngChunk("IDAT", ZlibStored(raw)) + after_idat +
         PngChunk("IEND", "");
}

std::vector<int> RandomSamples(size_t n, int max_value) {
  std::uniform_int_distribution<int> dist(0, max_value);
  std::vector<int> v(n);
  for (int& x : v) x = dist(test::Rng());
  return v;
}

// A JPEG through TurboJPEG (pixel_format TJPF_*, subsampling TJSAMP_*).
std::string TjEncode(const cv::Mat& image,
                     int pixel_format,
                     int subsampling,
                     int quality = 90,
                     int flags = 0) {
  tjhandle tj = tjInitCompress();
  unsigned char* jpeg = nullptr;
  unsigned long size = 0;  // NOLINT(runtime/int)
  const int rc = tjCompress2(
      tj, image.data, image.cols, static_cast<int>(image.step[0]), image.rows,
      pixel_format, &jpeg, &size, subsampling, quality, flags);
  std::string out = rc == 0 ? std::string(reinterpret_cast<char*>(jpeg), size)
                            : std::string();
  tjFree(jpeg);
  tjDestroy(tj);
  EXPECT_EQ(rc, 0) << tjGetErrorStr2(nullptr);
  return out;
}

// A TIFF structure with IFD0 = the given 12-byte entries.
std::string Tiff(bool intel, const std::vector<std::string>& entries) {
  auto u16 = intel ? Le16 : Be16;
  auto u32 = intel ? Le32 : Be32;
  std::string t =
      std::string(intel ? "II" : "MM") + u16(42) + u32(8) + u16(entries.size());
  for (const std::string& e : entries) t += e;
  return t + u32(0);
}
std::string OrientationEntry(bool intel, int orientation) {
  auto u16 = intel ? Le16 : Be16;
  auto u32 = intel ? Le32 : Be32;
  return u16(0x0112) + u16(3) + u32(1) + u16(orientation) + u16(0);
}

// `jpeg` with an APP1 segment holding `payload` right after SOI.
std::string WithApp1(const std::string& jpeg, const std::string& payload) {
  return jpeg.substr(0, 2) + "\xFF\xE1" + Be16(payload.size() + 2) + payload +
         jpeg.substr(2);
}

// Offset of the first byte after the SOS header of the first scan.
size_t ScanStart(const std::string& jpeg) {
  size_t i = 2;
  while (i + 4 <= jpeg.size()) {
    const unsigned char marker = jpeg[i + 1];
    const size_t length =
        (size_t((unsigned char)jpeg[i + 2]) << 8) | (unsigned char)jpeg[i + 3];
    if (marker == 0xDA) return i + 2 + length;
    i += 2 + length;
  }
  return std::string::npos;
}

// JPEG files of the real captures: every nuscenes_n015 camera, every 8th
// keyframe of each scene-0916 camera.
std::vector<std::string> RealJpegs() {
  std::vector<std::string> files;
  for (const auto& e :
       fs::directory_iterator(test::RealDataPath("nuscenes_n015")))
    if (e.path().extension() == ".jpg") files.push_back(e.path().string());
  const fs::path samples = test::RealDataPath("nuscenes_scene0916/samples");
  for (const auto& cam : fs::directory_iterator(samples)) {
    std::vector<std::string> jpgs;
    for (const auto& e : fs::directory_iterator(cam.path()))
      if (e.path().extension() == ".jpg") jpgs.push_back(e.path().string());
    std::sort(jpgs.begin(), jpgs.end());
    for (size_t i = 0; i < jpgs.size(); i += 8) files.push_back(jpgs[i]);
  }
  std::sort(files.begin(), files.end());
  return files;
}

long MaxRssKb() {  // NOLINT(runtime/int)
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss;
}

// ---- Round trips and basic reads ----

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

TEST(ImageIo, RgbaPngRoundTripsAndOpenCvReadsOurFiles) {
  const std::string dir = test::MakeTempDir("img_rgba");
  const cv::Mat rgba = RandomImage(19, 23, CV_8UC4);
  WriteImageRgb(dir + "/rgba.png", rgba);
  cv::Mat bgra;
  cv::cvtColor(rgba, bgra, cv::COLOR_RGBA2BGRA);
  EXPECT_TRUE(Identical(ReadImageUnchanged(dir + "/rgba.png"), bgra));
  EXPECT_TRUE(
      Identical(cv::imread(dir + "/rgba.png", cv::IMREAD_UNCHANGED), bgra));
  // A sub-matrix (non-continuous rows) writes the same as its copy.
  const cv::Mat big = RandomImage(40, 50, CV_8UC3);
  const cv::Mat roi = big(cv::Rect(5, 7, 31, 17));
  WriteImageRgb(dir + "/roi.png", roi);
  EXPECT_TRUE(Identical(ReadImageRgb(dir + "/roi.png"), roi.clone()));
  const cv::Mat depth = RandomImage(9, 13, CV_16UC1);
  WriteImageRgb(dir + "/depth.png", depth);
  EXPECT_TRUE(
      Identical(cv::imread(dir + "/depth.png", cv::IMREAD_UNCHANGED), depth));
  // 16-bit RGB (geodrive-diffusion vae-decode --out-frames): BGR when read
  // unchanged, by us and by OpenCV.
  const cv::Mat rgb16 = RandomImage(11, 7, CV_16UC3);
  WriteImageRgb(dir + "/rgb16.png", rgb16);
  cv::Mat bgr16;
  cv::cvtColor(rgb16, bgr16, cv::COLOR_RGB2BGR);
  EXPECT_TRUE(Identical(ReadImageUnchanged(dir + "/rgb16.png"), bgr16));
  EXPECT_TRUE(
      Identical(cv::imread(dir + "/rgb16.png", cv::IMREAD_UNCHANGED), bgr16));
  // JPEG has no 16-bit form.
  EXPECT_THROW(WriteImageRgb(dir + "/rgb16.jpg", rgb16), InputError);
}

TEST(ImageIo, PngWritesAreDeterministic) {
  const std::string dir = test::MakeTempDir("img_determinism");
  for (int type : {CV_8UC3, CV_8UC1, CV_8UC4, CV_16UC1, CV_16UC3}) {
    const cv::Mat image = RandomImage(64, 64, type);
    WriteImageRgb(dir + "/a.png", image);
    WriteImageRgb(dir + "/b.png", image);
    EXPECT_EQ(test::ReadFile(dir + "/a.png"), test::ReadFile(dir + "/b.png"))
        << type;
  }
  const cv::Mat smooth = SmoothImage(48, 80);
  WriteImageRgb(dir + "/a.jpg", smooth);
  WriteImageRgb(dir + "/b.jpg", smooth);
  EXPECT_EQ(test::ReadFile(dir + "/a.jpg"), test::ReadFile(dir + "/b.jpg"));
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

TEST(ImageIo, JpegWritesAreByteIdenticalToOpenCvs) {
  // Quality 95, 4:2:0, same libjpeg-turbo: the same file OpenCV writes.
  const std::string dir = test::MakeTempDir("img_jpeg_bytes");
  const cv::Mat rgb = SmoothImage(45, 67);
  WriteImageRgb(dir + "/rgb.jpg", rgb);
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  std::vector<uint8_t> opencv;
  ASSERT_TRUE(
      cv::imencode(".jpg", bgr, opencv, {cv::IMWRITE_JPEG_QUALITY, 95}));
  EXPECT_EQ(test::ReadFile(dir + "/rgb.jpg"),
            std::string(opencv.begin(), opencv.end()));
  cv::Mat gray;
  cv::cvtColor(rgb, gray, cv::COLOR_RGB2GRAY);
  WriteImageRgb(dir + "/gray.jpg", gray);
  ASSERT_TRUE(
      cv::imencode(".jpg", gray, opencv, {cv::IMWRITE_JPEG_QUALITY, 95}));
  EXPECT_EQ(test::ReadFile(dir + "/gray.jpg"),
            std::string(opencv.begin(), opencv.end()));
  // RGBA: alpha dropped.
  cv::Mat rgba;
  cv::cvtColor(rgb, rgba, cv::COLOR_RGB2RGBA);
  WriteImageRgb(dir + "/rgba.jpg", rgba);
  EXPECT_EQ(test::ReadFile(dir + "/rgba.jpg"),
            test::ReadFile(dir + "/rgb.jpg"));
}

TEST(ImageIo, EncodeJpegRgbIsOpenCvsImencodeAtEveryQuality) {
  // The synthetic dataset's camera JPEGs (quality 90) were cv::imencode's;
  // EncodeJpegRgb must give the same bytes (same libjpeg-turbo, 4:2:0,
  // accurate DCT), so that `geodrive synth` output is unchanged.
  const std::string dir = test::MakeTempDir("img_jpeg_quality");
  const cv::Mat rgb = SmoothImage(90, 160);
  cv::Mat bgr, gray;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  cv::cvtColor(rgb, gray, cv::COLOR_RGB2GRAY);
  for (int quality : {1, 30, 75, 90, 95, 96, 100}) {
    std::vector<uint8_t> opencv;
    ASSERT_TRUE(
        cv::imencode(".jpg", bgr, opencv, {cv::IMWRITE_JPEG_QUALITY, quality}));
    EXPECT_EQ(EncodeJpegRgb(rgb, quality), opencv) << "quality " << quality;
    ASSERT_TRUE(cv::imencode(".jpg", gray, opencv,
                             {cv::IMWRITE_JPEG_QUALITY, quality}));
    EXPECT_EQ(EncodeJpegRgb(gray, quality), opencv) << "gray " << quality;
  }
  WriteJpeg(dir + "/q90.jpg", rgb, 90);
  const std::vector<uint8_t> q90 = EncodeJpegRgb(rgb, 90);
  EXPECT_EQ(test::ReadFile(dir + "/q90.jpg"),
            std::string(q90.begin(), q90.end()));
  EXPECT_THROW(EncodeJpegRgb(rgb, 0), InputError);
  EXPECT_THROW(EncodeJpegRgb(rgb, 101), InputError);
  EXPECT_THROW(EncodeJpegRgb(cv::Mat(), 90), InputError);
  EXPECT_THROW(EncodeJpegRgb(cv::Mat(4, 4, CV_16UC1), 90), InputError);
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
  EXPECT_EQ(ReadImageSize(dir + "/a.png"), cv::Size(29, 17));
  EXPECT_EQ(ReadImageSize(dir + "/b.jpg"), cv::Size(13, 31));
  // PNG and JPEG only (the toolkit's frame formats).
  cv::imwrite(dir + "/c.bmp", RandomImage(5, 9, CV_8UC3));
  EXPECT_EQ(ErrorOf([&] { ReadImageSize(dir + "/c.bmp"); }),
            dir +
                "/c.bmp: not a readable image (unknown format or corrupt "
                "data)");
}

// A file read once (ImageFile) gives the header and pixels of the path-based
// readers, and the same errors, naming the file.
TEST(ImageIo, ImageFileReadOnceDecodesAsThePathReaders) {
  const std::string real = test::RealDataPath(kNuscenesJpeg);
  const ImageFile file = ReadImageFile(real);
  EXPECT_EQ(file.path, real);
  EXPECT_EQ(ReadImageHeader(file).size, cv::Size(1600, 900));
  EXPECT_TRUE(ReadImageHeader(file).jpeg);
  EXPECT_EQ(MaxAbsDiff(DecodeImageRgb(file), ReadImageRgb(real)), 0.0);
  const cv::Mat half = DecodeImageRgb(file, JpegScale{1, 2});
  EXPECT_EQ(half.size(), cv::Size(800, 450));
  EXPECT_EQ(MaxAbsDiff(half, ReadImageRgbScaled(real, JpegScale{1, 2})), 0.0);
  EXPECT_EQ(ErrorOf([&] {
              DecodeImageRgb(file, JpegScale{3, 7});
            }),
            real +
                ": cannot decode a 1600x900 JPEG at scale 3/7 (not one of "
                "libjpeg-turbo's scales for that size)");

  const std::string dir = test::MakeTempDir("img_file");
  WriteImageRgb(dir + "/a.png", RandomImage(17, 29, CV_8UC3));
  const ImageFile png = ReadImageFile(dir + "/a.png");
  EXPECT_FALSE(ReadImageHeader(png).jpeg);
  EXPECT_EQ(MaxAbsDiff(DecodeImageRgb(png), ReadImageRgb(dir + "/a.png")), 0.0);
  // Bytes cut short: the same error as reading the cut file.
  ImageFile cut = file;
  cut.bytes.resize(cut.bytes.size() / 2);
  EXPECT_EQ(ErrorOf([&] { DecodeImageRgb(cut); }),
            real + ": truncated or corrupt JPEG (no end-of-image marker)");
  EXPECT_EQ(ErrorOf([&] { ReadImageHeader(cut); }),
            real + ": truncated or corrupt JPEG (no end-of-image marker)");
  // Bytes that are no image (a caller-made ImageFile) are refused, not
  // decoded.
  const ImageFile junk{"junk.bin", std::vector<uint8_t>(64, 7)};
  EXPECT_EQ(ErrorOf([&] { DecodeImageRgb(junk); }),
            "junk.bin: not a readable image (unknown format or corrupt data)");
  EXPECT_EQ(ErrorOf([&] {
              ReadImageHeader(ImageFile{"e.jpg", {}});
            }),
            "e.jpg: empty file (expected an image)");
}

// ---- Pixels identical to cv::imdecode ----

TEST(ImageIo, RealImagesDecodeExactlyAsOpenCv) {
  const std::vector<std::string> jpegs = RealJpegs();
  EXPECT_GE(jpegs.size(), 6u + 6u * 5u);
  for (const std::string& path : jpegs) ExpectSameAsOpenCv(path, path);
  for (const auto& e :
       fs::directory_iterator(test::RealDataPath("kitti_odometry_00"))) {
    if (e.path().extension() == ".png")
      ExpectSameAsOpenCv(e.path().string(), e.path().string());
  }
  ExpectSameAsOpenCv(test::RealDataPath(kKittiPng), kKittiPng);
}

TEST(ImageIo, SyntheticJpegsDecodeExactlyAsOpenCv) {
  const std::string dir = test::MakeTempDir("img_jpeg_kinds");
  const cv::Mat rgb = SmoothImage(45, 67);  // odd sizes: partial MCUs
  cv::Mat gray, cmyk(rgb.size(), CV_8UC4);
  cv::cvtColor(rgb, gray, cv::COLOR_RGB2GRAY);
  cv::randu(cmyk, 0, 256);
  cv::GaussianBlur(cmyk, cmyk, cv::Size(5, 5), 0);
  const struct {
    const char* name;
    std::string bytes;
  } cases[] = {
      {"420", TjEncode(rgb, TJPF_RGB, TJSAMP_420)},
      {"444", TjEncode(rgb, TJPF_RGB, TJSAMP_444)},
      {"422", TjEncode(rgb, TJPF_RGB, TJSAMP_422)},
      {"440", TjEncode(rgb, TJPF_RGB, TJSAMP_440)},
      {"411", TjEncode(rgb, TJPF_RGB, TJSAMP_411)},
      {"gray", TjEncode(gray, TJPF_GRAY, TJSAMP_GRAY)},
      {"gray_from_rgb", TjEncode(rgb, TJPF_RGB, TJSAMP_GRAY)},
      {"progressive_420",
       TjEncode(rgb, TJPF_RGB, TJSAMP_420, 85, TJFLAG_PROGRESSIVE)},
      {"progressive_gray",
       TjEncode(gray, TJPF_GRAY, TJSAMP_GRAY, 85, TJFLAG_PROGRESSIVE)},
      {"restart_markers_opencv",
       [&] {
         std::vector<uint8_t> b;
         cv::imencode(".jpg", rgb, b, {cv::IMWRITE_JPEG_RST_INTERVAL, 2});
         return std::string(b.begin(), b.end());
       }()},
      {"ycck", TjEncode(cmyk, TJPF_CMYK, TJSAMP_444)},
      {"ycck_420", TjEncode(cmyk, TJPF_CMYK, TJSAMP_420)},
  };
  for (const auto& c : cases) {
    ASSERT_FALSE(c.bytes.empty()) << c.name;
    const std::string path = dir + "/" + c.name + ".jpg";
    test::WriteFile(path, c.bytes);
    ExpectSameAsOpenCv(path, c.name);
  }
  WriteImageRgb(dir + "/ours.jpg", rgb);
  ExpectSameAsOpenCv(dir + "/ours.jpg", "WriteImageRgb");
}

TEST(ImageIo, SyntheticPngsDecodeExactlyAsOpenCv) {
  const std::string dir = test::MakeTempDir("img_png_kinds");
  const int w = 13, h = 7;  // odd width: packed rows end mid-byte
  struct Case {
    std::string name;
    std::string bytes;
  };
  std::vector<Case> cases;
  for (int depth : {1, 2, 4, 8, 16}) {
    cases.push_back(
        {"gray" + std::to_string(depth),
         MakePng(w, h, 0, depth, RandomSamples(w * h, (1 << depth) - 1))});
  }
  // Gray with a tRNS key: OpenCV keeps 1 channel (the key is ignored).
  std::vector<int> g8 = RandomSamples(w * h, 255);
  g8[3] = g8[10] = 77;
  cases.push_back(
      {"gray8_trns", MakePng(w, h, 0, 8, g8, PngChunk("tRNS", Be16(77)))});
  cases.push_back(
      {"gray16_trns", MakePng(w, h, 0, 16, RandomSamples(w * h, 65535),
                              PngChunk("tRNS", Be16(1000)))});
  for (int depth : {8, 16}) {
    const int max = (1 << depth) - 1;
    const std::string d = std::to_string(depth);
    cases.push_back({"gray_alpha" + d,
                     MakePng(w, h, 4, depth, RandomSamples(2 * w * h, max))});
    cases.push_back(
        {"rgb" + d, MakePng(w, h, 2, depth, RandomSamples(3 * w * h, max))});
    cases.push_back(
        {"rgba" + d, MakePng(w, h, 6, depth, RandomSamples(4 * w * h, max))});
    // RGB with a tRNS colour key that some pixels match: 4 channels unchanged.
    std::vector<int> rgb = RandomSamples(3 * w * h, max);
    for (int px : {0, 5, 50}) {
      rgb[3 * px] = max / 3;
      rgb[3 * px + 1] = max / 5;
      rgb[3 * px + 2] = max / 7;
    }
    cases.push_back({"rgb_trns" + d,
                     MakePng(w, h, 2, depth, rgb,
                             PngChunk("tRNS", Be16(max / 3) + Be16(max / 5) +
                                                  Be16(max / 7)))});
  }
  // Colour to gray: libpng's coefficients, and its linear-light path when the
  // file declares a gamma.
  const std::vector<int> rgb8 = RandomSamples(3 * w * h, 255);
  cases.push_back({"rgb8_gama045",
                   MakePng(w, h, 2, 8, rgb8, PngChunk("gAMA", Be32(45455)))});
  cases.push_back({"rgb8_gama070",
                   MakePng(w, h, 2, 8, rgb8, PngChunk("gAMA", Be32(70000)))});
  cases.push_back({"rgb8_gama1",
                   MakePng(w, h, 2, 8, rgb8, PngChunk("gAMA", Be32(100000)))});
  cases.push_back(
      {"rgb8_srgb",
       MakePng(w, h, 2, 8, rgb8, PngChunk("sRGB", std::string(1, '\0')))});
  cases.push_back({"palette8_gama045",
                   MakePng(w, h, 3, 8, RandomSamples(w * h, 255),
                           PngChunk("gAMA", Be32(45455)) + PngChunk("PLTE", [] {
                             std::string p;
                             for (int v : RandomSamples(3 * 256, 255))
                               p += char(v);
                             return p;
                           }()))});
  for (int depth : {1, 2, 4, 8}) {
    const int entries = 1 << depth;
    std::string plte, trns;
    for (int v : RandomSamples(3 * entries, 255)) plte += char(v);
    for (int v : RandomSamples(entries / 2 + 1, 255)) trns += char(v);
    const std::vector<int> idx = RandomSamples(w * h, entries - 1);
    const std::string d = std::to_string(depth);
    cases.push_back(
        {"palette" + d, MakePng(w, h, 3, depth, idx, PngChunk("PLTE", plte))});
    cases.push_back({"palette_trns" + d,
                     MakePng(w, h, 3, depth, idx,
                             PngChunk("PLTE", plte) + PngChunk("tRNS", trns))});
  }
  // Interlaced (Adam7), through libspng's encoder.
  for (int type : {CV_8UC3, CV_16UC1}) {
    const cv::Mat image = RandomImage(h + 4, w + 6, type);
    spng_ctx* enc = spng_ctx_new(SPNG_CTX_ENCODER);
    spng_set_option(enc, SPNG_ENCODE_TO_BUFFER, 1);
    spng_ihdr ihdr{};
    ihdr.width = image.cols;
    ihdr.height = image.rows;
    ihdr.bit_depth = type == CV_16UC1 ? 16 : 8;
    ihdr.color_type = type == CV_16UC1 ? 0 : 2;
    ihdr.interlace_method = 1;
    spng_set_ihdr(enc, &ihdr);
    ASSERT_EQ(
        spng_encode_image(enc, image.data, image.total() * image.elemSize(),
                          SPNG_FMT_PNG, SPNG_ENCODE_FINALIZE),
        0);
    size_t size = 0;
    int err = 0;
    void* png = spng_get_png_buffer(enc, &size, &err);
    cases.push_back({"interlaced" + std::to_string(type),
                     std::string(static_cast<char*>(png), size)});
    std::free(png);
    spng_ctx_free(enc);
  }
  for (const Case& c : cases) {
    const std::string path = dir + "/" + c.name + ".png";
    test::WriteFile(path, c.bytes);
    ExpectSameAsOpenCv(path, c.name);
  }
  // The types OpenCV gives them, for the record.
  EXPECT_EQ(ReadImageUnchanged(dir + "/gray_alpha8.png").type(), CV_8UC4);
  EXPECT_EQ(ReadImageUnchanged(dir + "/rgb_trns16.png").type(), CV_16UC4);
  EXPECT_EQ(ReadImageUnchanged(dir + "/palette_trns4.png").type(), CV_8UC4);
  EXPECT_EQ(ReadImageUnchanged(dir + "/gray8_trns.png").type(), CV_8UC1);
  EXPECT_EQ(ReadImageUnchanged(dir + "/rgba16.png").type(), CV_16UC4);
}

TEST(ImageIo, ExifOrientationIsAppliedAsOpenCvDoes) {
  const std::string dir = test::MakeTempDir("img_exif");
  const cv::Mat rgb = SmoothImage(23, 37);  // not square: 5..8 swap sides
  const std::string jpeg = TjEncode(rgb, TJPF_RGB, TJSAMP_444);
  std::vector<int> samples;
  for (int r = 0; r < rgb.rows; ++r)
    for (int c = 0; c < rgb.cols; ++c)
      for (int k = 0; k < 3; ++k) samples.push_back(rgb.at<cv::Vec3b>(r, c)[k]);
  for (bool intel : {true, false}) {
    for (int orientation = 0; orientation <= 9; ++orientation) {
      const std::string name =
          std::string(intel ? "ii" : "mm") + "_" + std::to_string(orientation);
      const std::string tiff =
          Tiff(intel, {OrientationEntry(intel, orientation)});
      test::WriteFile(dir + "/" + name + ".jpg",
                      WithApp1(jpeg, std::string("Exif\0\0", 6) + tiff));
      ExpectSameAsOpenCv(dir + "/" + name + ".jpg", name + ".jpg");
      test::WriteFile(dir + "/" + name + ".png",
                      MakePng(rgb.cols, rgb.rows, 2, 8, samples,
                              intel ? PngChunk("eXIf", tiff) : "",
                              intel ? "" : PngChunk("eXIf", tiff)));
      ExpectSameAsOpenCv(dir + "/" + name + ".png", name + ".png");
    }
  }
  const cv::Size swapped(rgb.rows, rgb.cols);
  EXPECT_EQ(ReadImageSize(dir + "/ii_6.jpg"), swapped);
  EXPECT_EQ(ReadImageRgb(dir + "/mm_8.png").size(), swapped);
  EXPECT_EQ(ReadImageUnchanged(dir + "/mm_8.jpg").size(), rgb.size());
  // ReadImageHeader: the orientation ReadImageRgb applies (0 and 9 read as
  // 1: as stored), the size it returns, the format.
  for (int orientation = 0; orientation <= 9; ++orientation) {
    for (const std::string ext : {".jpg", ".png"}) {
      const std::string path = dir + "/ii_" + std::to_string(orientation) + ext;
      const ImageHeader header = ReadImageHeader(path);
      EXPECT_EQ(header.orientation,
                orientation >= 1 && orientation <= 8 ? orientation : 1)
          << path;
      EXPECT_EQ(header.size, ReadImageRgb(path).size()) << path;
      EXPECT_EQ(header.jpeg, ext == ".jpg") << path;
    }
  }

  // Malformed or unusual EXIF: parsed as OpenCV parses it, never out of
  // bounds.
  const bool le = true;
  auto u16 = Le16;
  auto u32 = Le32;
  const std::string make_oob =  // Make string pointing past the data
      u16(0x010F) + u16(2) + u32(40) + u32(5000);
  const std::string xres_oob = u16(0x011A) + u16(5) + u32(1) + u32(5000);
  const std::string unknown = u16(0x9999) + u16(3) + u32(1) + u32(0);
  const struct {
    const char* name;
    std::string app1;
  } odd[] = {
      {"count_past_end",  // orientation read, then the entries run out
       std::string("Exif\0\0", 6) + "II" + u16(42) + u32(8) + u16(60) +
           OrientationEntry(le, 6)},
      {"ifd_past_end", std::string("Exif\0\0", 6) + "II" + u16(42) + u32(900)},
      {"bad_tag_mark", std::string("Exif\0\0", 6) + "II" + u16(43) + u32(8) +
                           u16(1) + OrientationEntry(le, 6) + u32(0)},
      {"make_oob_before", std::string("Exif\0\0", 6) +
                              Tiff(le, {make_oob, OrientationEntry(le, 6)})},
      {"xres_oob_before", std::string("Exif\0\0", 6) +
                              Tiff(le, {xres_oob, OrientationEntry(le, 6)})},
      {"orientation_twice",
       std::string("Exif\0\0", 6) +
           Tiff(le, {OrientationEntry(le, 3), OrientationEntry(le, 6)})},
      {"unknown_then_orientation",
       std::string("Exif\0\0", 6) +
           Tiff(le, {unknown, OrientationEntry(le, 5)})},
      {"orientation_cut", std::string("Exif\0\0", 6) + "II" + u16(42) + u32(8) +
                              u16(1) + u16(0x0112) + u16(3) + u32(1) + "\x06"},
      {"xmp", std::string("http://ns.adobe.com/xap/1.0/\0<x:xmpmeta/>", 41)},
      {"short", "Exi"},
  };
  for (const auto& c : odd) {
    const std::string path = dir + "/" + c.name + ".jpg";
    test::WriteFile(path, WithApp1(jpeg, c.app1));
    ExpectSameAsOpenCv(path, c.name);
  }
  // OpenCV takes the first APP1 only: XMP first hides a later EXIF.
  test::WriteFile(
      dir + "/xmp_then_exif.jpg",
      WithApp1(WithApp1(jpeg, std::string("Exif\0\0", 6) +
                                  Tiff(le, {OrientationEntry(le, 6)})),
               std::string("http://ns.adobe.com/xap/1.0/\0x", 30)));
  ExpectSameAsOpenCv(dir + "/xmp_then_exif.jpg", "xmp_then_exif");
  EXPECT_EQ(ReadImageRgb(dir + "/xmp_then_exif.jpg").size(), rgb.size());
}

TEST(ImageIo, ScaledJpegDecodeMatchesOpenCvReduced) {
  const std::string path = test::RealDataPath(kNuscenesJpeg);
  const std::string bytes = test::ReadFile(path);
  const struct {
    int min_width, min_height, flags;
    cv::Size size;
  } cases[] = {
      {200, 100, cv::IMREAD_REDUCED_COLOR_8, {200, 113}},
      {201, 100, cv::IMREAD_REDUCED_COLOR_4, {400, 225}},
      {400, 225, cv::IMREAD_REDUCED_COLOR_4, {400, 225}},
      {100, 300, cv::IMREAD_REDUCED_COLOR_2, {800, 450}},
      {800, 451, cv::IMREAD_COLOR, {1600, 900}},
      {5000, 5000, cv::IMREAD_COLOR, {1600, 900}},
  };
  for (const auto& c : cases) {
    const cv::Mat ours = ReadImageRgbScaled(path, c.min_width, c.min_height);
    EXPECT_EQ(ours.size(), c.size) << c.min_width << "x" << c.min_height;
    cv::Mat expected;
    cv::cvtColor(CvDecode(bytes, c.flags), expected, cv::COLOR_BGR2RGB);
    EXPECT_TRUE(Identical(ours, expected))
        << c.min_width << "x" << c.min_height;
  }
  // The requested size is in the displayed (EXIF-oriented) frame.
  const std::string dir = test::MakeTempDir("img_scaled");
  const std::string rotated =
      WithApp1(bytes, std::string("Exif\0\0", 6) +
                          Tiff(true, {OrientationEntry(true, 6)}));
  test::WriteFile(dir + "/rot.jpg", rotated);
  EXPECT_EQ(ReadImageRgbScaled(dir + "/rot.jpg", 225, 400).size(),
            cv::Size(225, 400));
  cv::Mat expected;
  cv::cvtColor(CvDecode(rotated, cv::IMREAD_REDUCED_COLOR_4), expected,
               cv::COLOR_BGR2RGB);
  EXPECT_TRUE(
      Identical(ReadImageRgbScaled(dir + "/rot.jpg", 225, 400), expected));
  // PNG: full size.
  EXPECT_EQ(ReadImageRgbScaled(test::RealDataPath(kKittiPng), 10, 10).size(),
            cv::Size(1242, 375));
}

// Any M/8 scale (JpegDecodeScales): ceil(side * M / 8) per side; 1/8, 1/2
// and 1/1 give the pixels of the min-size overload and of ReadImageRgb; EXIF
// orientation applies after the decode; a scale the library does not list,
// or would not pick for the image's size, is an InputError naming the file.
TEST(ImageIo, JpegDecodeAtAnyListedScale) {
  const auto names = [](const std::vector<JpegScale>& scales) {
    std::vector<std::string> out;
    for (const JpegScale& s : scales)
      out.push_back(std::to_string(s.num) + "/" + std::to_string(s.denom));
    return out;
  };
  EXPECT_THAT(names(JpegDecodeScales(1600, 900)),
              ::testing::ElementsAre("1/8", "1/4", "3/8", "1/2", "5/8", "3/4",
                                     "7/8", "1/1"));
  EXPECT_EQ(names(JpegDecodeScales(900, 1600)),
            names(JpegDecodeScales(1600, 900)));
  // 3x3: 1/8 and 1/4 both give 1x1 (TurboJPEG takes the larger, 1/4), 3/8,
  // 1/2 and 5/8 2x2, the rest 3x3.
  EXPECT_THAT(names(JpegDecodeScales(3, 3)),
              ::testing::ElementsAre("1/4", "5/8", "1/1"));
  EXPECT_THAT(names(JpegDecodeScales(1, 1)), ::testing::ElementsAre("1/1"));

  const std::string path = test::RealDataPath(kNuscenesJpeg);
  for (const JpegScale& s : JpegDecodeScales(1600, 900)) {
    const cv::Mat rgb = ReadImageRgbScaled(path, s);
    EXPECT_EQ(rgb.size(), cv::Size((1600 * s.num + s.denom - 1) / s.denom,
                                   (900 * s.num + s.denom - 1) / s.denom))
        << s.num << "/" << s.denom;
    EXPECT_EQ(rgb.type(), CV_8UC3);
  }
  EXPECT_EQ(ReadImageRgbScaled(path, JpegScale{5, 8}).size(),
            cv::Size(1000, 563));
  EXPECT_TRUE(Identical(ReadImageRgbScaled(path, JpegScale{1, 2}),
                        ReadImageRgbScaled(path, 800, 450)));
  EXPECT_TRUE(Identical(ReadImageRgbScaled(path, JpegScale{2, 4}),
                        ReadImageRgbScaled(path, 800, 450)));  // by value
  EXPECT_TRUE(Identical(ReadImageRgbScaled(path, JpegScale{1, 8}),
                        ReadImageRgbScaled(path, 200, 113)));
  EXPECT_TRUE(
      Identical(ReadImageRgbScaled(path, JpegScale{1, 1}), ReadImageRgb(path)));
  // A 5/8 decode is the image at 5/8: close to the full decode area-resized
  // to 1000x562.5 (the last, partial row left out).
  cv::Mat area;
  cv::resize(ReadImageRgb(path), area, cv::Size(), 0.625, 0.625,
             cv::INTER_AREA);
  const cv::Rect top(0, 0, 1000, 562);
  const double l2 = cv::norm(ReadImageRgbScaled(path, JpegScale{5, 8})(top),
                             area(top), cv::NORM_L2);
  EXPECT_GT(10 * std::log10(255.0 * 255.0 * top.area() * 3 / (l2 * l2)), 35.0);

  const std::string dir = test::MakeTempDir("img_any_scale");
  const std::string bytes = test::ReadFile(path);
  test::WriteFile(dir + "/rot.jpg",
                  WithApp1(bytes, std::string("Exif\0\0", 6) +
                                      Tiff(true, {OrientationEntry(true, 6)})));
  const cv::Mat rotated = ReadImageRgbScaled(dir + "/rot.jpg", JpegScale{5, 8});
  EXPECT_EQ(rotated.size(), cv::Size(563, 1000));
  cv::Mat expected;
  cv::rotate(ReadImageRgbScaled(path, JpegScale{5, 8}), expected,
             cv::ROTATE_90_CLOCKWISE);
  EXPECT_TRUE(Identical(rotated, expected));

  for (const JpegScale s : {JpegScale{2, 3}, JpegScale{3, 2}, JpegScale{0, 8},
                            JpegScale{1, 0}, JpegScale{-1, -8}}) {
    EXPECT_EQ(ErrorOf([&] { ReadImageRgbScaled(path, s); }),
              path + ": cannot decode a 1600x900 JPEG at scale " +
                  std::to_string(s.num) + "/" + std::to_string(s.denom) +
                  " (not one of libjpeg-turbo's scales for that size)");
  }
  WriteImageRgb(dir + "/tiny.jpg", RandomImage(3, 3, CV_8UC3));
  EXPECT_EQ(ReadImageRgbScaled(dir + "/tiny.jpg", JpegScale{1, 4}).size(),
            cv::Size(1, 1));
  EXPECT_THAT(ErrorOf([&] {
                ReadImageRgbScaled(dir + "/tiny.jpg", JpegScale{1, 8});
              }),
              HasSubstr("cannot decode a 3x3 JPEG at scale 1/8"));
  // PNG: full size at any scale.
  EXPECT_EQ(
      ReadImageRgbScaled(test::RealDataPath(kKittiPng), JpegScale{1, 8}).size(),
      cv::Size(1242, 375));
}

// ---- Hardening ----

TEST(ImageIo, JpegWithCorruptScanDataIsRejected) {
  // 64 bytes in the middle of the entropy-coded data overwritten with stuffed
  // 0xFF bytes (a run of 1 bits, not a Huffman code), EOI kept: libjpeg
  // decodes it "with warnings" and OpenCV returns a frame. (Flipped bits that
  // still form valid codes are not detectable at all: libjpeg resynchronizes.)
  const std::string full = test::ReadFile(test::RealDataPath(kNuscenesJpeg));
  const size_t start = ScanStart(full);
  ASSERT_NE(start, std::string::npos);
  std::string corrupt = full;
  size_t mid = start + (full.size() - start) / 2;
  while (static_cast<unsigned char>(corrupt[mid - 1]) == 0xFF) ++mid;
  for (size_t i = mid; i < mid + 64; i += 2)
    corrupt.replace(i, 2, "\xFF\x00", 2);
  ASSERT_FALSE(CvDecode(corrupt, cv::IMREAD_COLOR).empty())
      << "OpenCV no longer accepts this file: the test lost its point";
  const std::string path = test::MakeTempDir("img_corrupt") + "/corrupt.jpg";
  test::WriteFile(path, corrupt);
  EXPECT_THAT(ErrorOf([&] { ReadImageRgb(path); }),
              StartsWith(path + ": corrupt JPEG data (libjpeg warning: "));
  EXPECT_THAT(ErrorOf([&] { ReadImageGray(path); }), HasSubstr("libjpeg"));
  EXPECT_THAT(ErrorOf([&] { ReadImageUnchanged(path); }), HasSubstr("libjpeg"));
  const std::string message = ErrorOf([&] { ReadImageRgb(path); });
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
}

TEST(ImageIo, JpegWithPrematureEndOfScanIsRejected) {
  // The scan cut in half, EOI appended: structurally complete, but libjpeg
  // warns "premature end of data segment" and pads the image with grey.
  const std::string full = test::ReadFile(test::RealDataPath(kNuscenesJpeg));
  const size_t start = ScanStart(full);
  std::string cut = full.substr(0, start + (full.size() - start) / 2);
  while (!cut.empty() && static_cast<unsigned char>(cut.back()) == 0xFF)
    cut.pop_back();
  cut += "\xFF\xD9";
  ASSERT_FALSE(CvDecode(cut, cv::IMREAD_COLOR).empty());
  const std::string path = test::MakeTempDir("img_premature") + "/cut.jpg";
  test::WriteFile(path, cut);
  EXPECT_EQ(ErrorOf([&] { ReadImageRgb(path); }),
            path +
                ": corrupt JPEG data (libjpeg warning: Corrupt JPEG data: "
                "premature end of data segment)");
  // The header alone is fine: the size is still readable.
  EXPECT_EQ(ReadImageSize(path), cv::Size(1600, 900));
}

TEST(ImageIo, HugeJpegHeaderIsRejectedBeforeAllocating) {
  // A tiny JPEG whose SOF declares 20000 x 20000 (1.2 GB decoded).
  std::string jpeg = TjEncode(SmoothImage(16, 16), TJPF_RGB, TJSAMP_420);
  size_t sof = 2;
  while (static_cast<unsigned char>(jpeg[sof + 1]) != 0xC0) {
    sof += 2 + ((size_t((unsigned char)jpeg[sof + 2]) << 8) |
                (unsigned char)jpeg[sof + 3]);
  }
  jpeg.replace(sof + 5, 4, Be16(20000) + Be16(20000));
  const std::string path = test::MakeTempDir("img_huge_jpeg") + "/huge.jpg";
  test::WriteFile(path, jpeg);
  const long rss_before = MaxRssKb();  // NOLINT(runtime/int)
  const auto t0 = std::chrono::steady_clock::now();
  const std::string expected =
      path +
      ": image of 20000x20000 pixels is over the reader's limit (16384 pixels "
      "per side, 268435456 pixels)";
  EXPECT_EQ(ErrorOf([&] { ReadImageRgb(path); }), expected);
  EXPECT_EQ(ErrorOf([&] { ReadImageUnchanged(path); }), expected);
  EXPECT_EQ(ErrorOf([&] { ReadImageSize(path); }), expected);
  EXPECT_EQ(ErrorOf([&] { ReadImageRgbScaled(path, 100, 100); }), expected);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
          .count();
  EXPECT_LT(seconds, 0.5);
  EXPECT_LT(MaxRssKb() - rss_before, 100 * 1024);
  // Within the limits the same trick reaches the decoder, which fails cleanly.
  jpeg.replace(sof + 5, 4, Be16(300) + Be16(200));
  test::WriteFile(path, jpeg);
  EXPECT_THAT(ErrorOf([&] { ReadImageRgb(path); }), HasSubstr("libjpeg"));
}

TEST(ImageIo, HugePngHeaderIsRejected) {
  const std::string dir = test::MakeTempDir("img_huge_png");
  std::string png = MakePng(4, 4, 2, 8, RandomSamples(48, 255));
  // IHDR declares 100000 x 100000 (CRC fixed, so only the size is wrong).
  const std::string ihdr = Be32(100000) + Be32(100000) + png.substr(24, 5);
  png.replace(8, 25, PngChunk("IHDR", ihdr));
  test::WriteFile(dir + "/huge.png", png);
  const long rss_before = MaxRssKb();  // NOLINT(runtime/int)
  const std::string expected =
      dir +
      "/huge.png: image of 100000x100000 pixels is over the reader's limit "
      "(16384 pixels per side, 268435456 pixels)";
  EXPECT_EQ(ErrorOf([&] { ReadImageRgb(dir + "/huge.png"); }), expected);
  EXPECT_EQ(ErrorOf([&] { ReadImageSize(dir + "/huge.png"); }), expected);
  EXPECT_LT(MaxRssKb() - rss_before, 100 * 1024);
  // 16384 x 16385: one side over.
  png.replace(8, 25,
              PngChunk("IHDR", Be32(16384) + Be32(16385) + png.substr(24, 5)));
  test::WriteFile(dir + "/tall.png", png);
  EXPECT_THAT(ErrorOf([&] { ReadImageGray(dir + "/tall.png"); }),
              HasSubstr("16384x16385 pixels is over the reader's limit"));
}

TEST(ImageIo, PngWithBadCrcIsRejected) {
  const std::string dir = test::MakeTempDir("img_crc");
  const std::vector<int> samples = RandomSamples(3 * 8 * 5, 255);
  const std::string good = MakePng(8, 5, 2, 8, samples);
  ASSERT_NO_THROW(ReadImageRgb(
      (test::WriteFile(dir + "/good.png", good), dir + "/good.png")));
  // IDAT's CRC (the 4 bytes before IEND's 12).
  std::string bad = good;
  bad[bad.size() - 13] ^= 1;
  test::WriteFile(dir + "/idat_crc.png", bad);
  EXPECT_THAT(ErrorOf([&] { ReadImageRgb(dir + "/idat_crc.png"); }),
              StartsWith(dir + "/idat_crc.png: cannot decode PNG (libspng: "));
  // An ancillary chunk's CRC, before and after the image data (libpng and
  // OpenCV would drop the chunk and carry on).
  std::string text = PngChunk("tEXt", std::string("Comment\0hello", 13));
  text[text.size() - 1] ^= 1;
  test::WriteFile(dir + "/text_before.png", MakePng(8, 5, 2, 8, samples, text));
  test::WriteFile(dir + "/text_after.png",
                  MakePng(8, 5, 2, 8, samples, "", text));
  EXPECT_THAT(ErrorOf([&] { ReadImageRgb(dir + "/text_before.png"); }),
              HasSubstr("cannot decode PNG (libspng: "));
  EXPECT_THAT(ErrorOf([&] { ReadImageUnchanged(dir + "/text_after.png"); }),
              HasSubstr("cannot decode PNG (libspng: "));
  // Bad zlib checksum (the last 4 bytes of the IDAT data), CRC made valid.
  std::string adler = good;
  const size_t idat = adler.find("IDAT");
  const size_t idat_len =
      (size_t(static_cast<unsigned char>(adler[idat - 2])) << 8) |
      static_cast<unsigned char>(adler[idat - 1]);
  std::string body = adler.substr(idat + 4, idat_len);
  body[body.size() - 1] ^= 1;
  adler.replace(idat - 4, 12 + idat_len, PngChunk("IDAT", body));
  test::WriteFile(dir + "/adler.png", adler);
  EXPECT_THAT(ErrorOf([&] { ReadImageRgb(dir + "/adler.png"); }),
              HasSubstr("cannot decode PNG (libspng: "));
}

TEST(ImageIo, FailuresPrintNothing) {
  const std::string dir = test::MakeTempDir("img_quiet");
  const std::string full = test::ReadFile(test::RealDataPath(kNuscenesJpeg));
  const size_t start = ScanStart(full);
  test::WriteFile(dir + "/cut.jpg",
                  full.substr(0, start + 5000) + std::string("\xFF\xD9", 2));
  std::string png = test::ReadFile(test::RealDataPath(kKittiPng));
  png[png.size() / 2] ^= 0x40;
  test::WriteFile(dir + "/bad.png", png);
  test::WriteFile(dir + "/junk.jpg", std::string("\xFF\xD8\xFF\xE0\x00\x04"
                                                 "ab\xFF\xD9",
                                                 10));
  ::testing::internal::CaptureStderr();
  ::testing::internal::CaptureStdout();
  for (const char* name : {"/cut.jpg", "/bad.png", "/junk.jpg"}) {
    EXPECT_FALSE(ErrorOf([&] { ReadImageRgb(dir + name); }).empty()) << name;
    EXPECT_FALSE(ErrorOf([&] { ReadImageUnchanged(dir + name); }).empty());
  }
  EXPECT_EQ(::testing::internal::GetCapturedStdout(), "");
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
}

// ---- Errors ----

TEST(ImageIo, MissingFileSaysCannotOpen) {
  const std::string path = test::MakeTempDir("img_missing") + "/missing.png";
  EXPECT_EQ(ErrorOf([&] { ReadImageRgb(path); }),
            path + ": cannot open (No such file or directory)");
  EXPECT_EQ(ErrorOf([&] { ReadImageSize(path); }),
            path + ": cannot open (No such file or directory)");
}

TEST(ImageIo, NonImageFileIsRejected) {
  const std::string dir = test::MakeTempDir("img_not_image");
  test::WriteFile(dir + "/notes.png", "this is a text file, not a PNG\n");
  EXPECT_EQ(
      ErrorOf([&] { ReadImageRgb(dir + "/notes.png"); }),
      dir +
          "/notes.png: not a readable image (unknown format or corrupt data)");
  test::WriteFile(dir + "/empty.jpg", "");
  EXPECT_EQ(ErrorOf([&] { ReadImageGray(dir + "/empty.jpg"); }),
            dir + "/empty.jpg: empty file (expected an image)");
  EXPECT_THAT(ErrorOf([&] { ReadImageRgb(dir); }),
              StartsWith(dir + ": is a directory"));
}

TEST(ImageIo, TruncatedJpegIsRejected) {
  // libjpeg only warns ("Premature end of JPEG file") and returns a half-grey
  // image; the reader must refuse it instead.
  const std::string path = test::MakeTempDir("img_trunc_jpeg") + "/cut.jpg";
  const std::string full = test::ReadFile(test::RealDataPath(kNuscenesJpeg));
  for (size_t keep :
       {full.size() / 2, full.size() - 2, size_t{1000}, size_t{3}}) {
    test::WriteFile(path, full.substr(0, keep));
    EXPECT_EQ(ErrorOf([&] { ReadImageRgb(path); }),
              path + ": truncated or corrupt JPEG (no end-of-image marker)")
        << keep;
  }
  test::WriteFile(path, full.substr(0, full.size() / 2));
  EXPECT_THAT(ErrorOf([&] { ReadImageSize(path); }), HasSubstr("truncated"));
}

TEST(ImageIo, TruncatedPngIsRejected) {
  const std::string path = test::MakeTempDir("img_trunc_png") + "/cut.png";
  const std::string full = test::ReadFile(test::RealDataPath(kKittiPng));
  for (size_t keep :
       {full.size() / 2, full.size() - 1, size_t{40}, size_t{9}}) {
    test::WriteFile(path, full.substr(0, keep));
    EXPECT_EQ(ErrorOf([&] { ReadImageRgb(path); }),
              path + ": truncated or corrupt PNG (no IEND chunk)")
        << keep;
  }
  // A complete chunk structure with corrupt pixel data still fails (in the
  // decoder).
  std::string corrupt = full;
  for (size_t i = 200; i < 2000; ++i)
    corrupt[i] = static_cast<char>(corrupt[i] ^ 0x5a);
  test::WriteFile(path, corrupt);
  EXPECT_THAT(ErrorOf([&] { ReadImageRgb(path); }),
              StartsWith(path + ": cannot decode PNG (libspng: "));
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
                WriteImageRgb(dir + "/a.bmp", RandomImage(4, 4, CV_8UC3));
              }),
              StartsWith(dir + "/a.bmp: cannot encode image as .bmp"));
  EXPECT_THAT(ErrorOf([&] {
                WriteImageRgb(dir + "/d.jpg", RandomImage(4, 4, CV_16UC1));
              }),
              StartsWith(dir + "/d.jpg: JPEG needs an 8-bit image"));
  EXPECT_THAT(ErrorOf([&] {
                WriteImageRgb(dir + "/no/dir/a.png",
                              RandomImage(4, 4, CV_8UC3));
              }),
              StartsWith(dir + "/no/dir/a.png: cannot write"));
  EXPECT_TRUE(std::filesystem::is_empty(dir));
}

}  // namespace
}  // namespace image_io_test
}  // namespace geodrive

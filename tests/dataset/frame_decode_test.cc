// The builder's frame path (dataset/frame_decode.h, issue 23 "Frames"): which
// DCT scale it decodes at, that a full-size decode still gives the previous
// pixels, the PSNR of the DCT-scaled path against the full decode on the real
// scene-0916 frames, the size check, and the pair folder's PNG writer.

#include "dataset/frame_decode.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "dataset/internal/pair_png.h"
#include "geometry/image_io.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

namespace fs = std::filesystem;

double Psnr(const cv::Mat& a, const cv::Mat& b) {
  const double norm = cv::norm(a, b, cv::NORM_L2);
  const double mse = norm * norm / (static_cast<double>(a.total()) * 3);
  return mse <= 0 ? 100.0 : 10.0 * std::log10(255.0 * 255.0 / mse);
}

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

std::vector<std::string> RealFrontFrames() {
  std::vector<std::string> files;
  const std::string dir =
      test::RealDataPath("nuscenes_scene0916/samples/CAM_FRONT");
  if (!fs::is_directory(dir)) return files;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() == ".jpg") files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST(FrameDecode, DenominatorFollowsTheOutputSize) {
  const auto spec = [](int w, int h, ResizeMode mode) {
    return ComputeResizeSpec(1600, 900, w, h, mode);
  };
  // The case: 720x480 decodes at 800x450 (height x 1.067 after).
  EXPECT_EQ(
      FrameDecodeDenominator(1600, 900, spec(720, 480, ResizeMode::kResize)),
      2);
  // Centre-crop to 720x480: resized 853x480, still 1/2.
  EXPECT_EQ(FrameDecodeDenominator(1600, 900,
                                   spec(720, 480, ResizeMode::kCenterCrop)),
            2);
  EXPECT_EQ(
      FrameDecodeDenominator(1600, 900, spec(400, 225, ResizeMode::kResize)),
      4);
  EXPECT_EQ(
      FrameDecodeDenominator(1600, 900, spec(200, 112, ResizeMode::kResize)),
      8);
  // Larger outputs, and the released preset's 1024x576: full decode.
  EXPECT_EQ(
      FrameDecodeDenominator(1600, 900, spec(1024, 576, ResizeMode::kResize)),
      1);
  FrameDecodeOptions never_up;
  never_up.max_upsample = 1.0;
  EXPECT_EQ(FrameDecodeDenominator(
                1600, 900, spec(720, 480, ResizeMode::kResize), never_up),
            1);
  FrameDecodeOptions full;
  full.mode = FrameDecodeMode::kFull;
  EXPECT_EQ(FrameDecodeDenominator(1600, 900,
                                   spec(200, 112, ResizeMode::kResize), full),
            1);
}

// kFull is the builder's previous path, pixel for pixel: full decode,
// INTER_AREA whenever the width shrinks, crop.
TEST(FrameDecode, FullModeGivesThePreviousPixels) {
  const std::vector<std::string> files = RealFrontFrames();
  if (files.empty())
    FAIL() << "no real data at ../shared/data/real/nuscenes_scene0916";
  FrameDecodeOptions full;
  full.mode = FrameDecodeMode::kFull;
  for (const ResizeMode mode : {ResizeMode::kResize, ResizeMode::kCenterCrop}) {
    const ImageResizeSpec spec = ComputeResizeSpec(1600, 900, 720, 480, mode);
    const cv::Mat rgb = ReadImageRgb(files.front());
    cv::Mat resized;
    cv::resize(rgb, resized, cv::Size(spec.resized_width, spec.resized_height),
               0, 0, cv::INTER_AREA);
    const cv::Mat expected = resized(
        cv::Rect(spec.crop_left, spec.crop_top, spec.width, spec.height));
    const cv::Mat got =
        ReadFrameAtOutputSize(files.front(), 1600, 900, spec, full);
    ASSERT_EQ(got.size(), cv::Size(720, 480));
    ASSERT_TRUE(got.isContinuous());
    EXPECT_EQ(cv::norm(got, expected, cv::NORM_INF), 0.0) << ToString(mode);
  }
}

// The criterion: the DCT-scaled path (1/2, then resize) within 40 dB
// PSNR of the full decode + resize, on every real CAM_FRONT keyframe of
// scene-0916 (measured 41.2 dB worst, 42.9 dB mean; docs/PERFORMANCE.md).
TEST(FrameDecode, DctScaledIsWithin40DbOfFullDecodeOnRealFrames) {
  const std::vector<std::string> files = RealFrontFrames();
  if (files.empty())
    FAIL() << "no real data at ../shared/data/real/nuscenes_scene0916";
  ASSERT_EQ(files.size(), 41u);
  const ImageResizeSpec spec =
      ComputeResizeSpec(1600, 900, 720, 480, ResizeMode::kResize);
  FrameDecodeOptions full;
  full.mode = FrameDecodeMode::kFull;
  double worst = 100, sum = 0;
  for (const std::string& f : files) {
    const cv::Mat a = ReadFrameAtOutputSize(f, 1600, 900, spec, full);
    const cv::Mat b = ReadFrameAtOutputSize(f, 1600, 900, spec);
    ASSERT_EQ(b.size(), cv::Size(720, 480));
    ASSERT_EQ(b.type(), CV_8UC3);
    const double p = Psnr(a, b);
    worst = std::min(worst, p);
    sum += p;
  }
  EXPECT_GE(worst, 40.0);
  EXPECT_GE(sum / files.size(), 42.0);
  std::printf(
      "DCT-scaled vs full decode, 41 real frames: worst %.2f dB, "
      "mean %.2f dB\n",
      worst, sum / files.size());
}

// A scaled decode cannot tell 1599 from 1600 columns: the header is checked.
TEST(FrameDecode, SizeOtherThanTheCameraIsAnError) {
  const std::vector<std::string> files = RealFrontFrames();
  if (files.empty())
    FAIL() << "no real data at ../shared/data/real/nuscenes_scene0916";
  const ImageResizeSpec spec =
      ComputeResizeSpec(1599, 900, 720, 480, ResizeMode::kResize);
  try {
    ReadFrameAtOutputSize(files.front(), 1599, 900, spec);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(files.front()), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("1600x900"), std::string::npos);
  }
}

TEST(FrameDecode, ResizeWithoutCropReturnsAFreshImage) {
  cv::Mat rgb(450, 800, CV_8UC3, cv::Scalar(10, 20, 30));
  const ImageResizeSpec same =
      ComputeResizeSpec(800, 450, 800, 450, ResizeMode::kResize);
  const cv::Mat out = ResizeFrameToOutput(rgb, same);
  EXPECT_NE(out.data, rgb.data);  // the caller may modify either
  EXPECT_EQ(cv::norm(out, rgb, cv::NORM_INF), 0.0);
}

TEST(PairPng, LosslessAndDeterministic) {
  const std::string dir = test::MakeTempDir("pair_png");
  cv::Mat rgb(97, 131, CV_8UC3);
  cv::randu(rgb, cv::Scalar::all(0), cv::Scalar::all(256));
  rgb(cv::Rect(10, 10, 60, 40)).setTo(cv::Scalar(200, 100, 50));
  internal::WritePairPng(dir + "/a.png", rgb);
  internal::WritePairPng(dir + "/b.png", rgb);
  const cv::Mat back = ReadImageRgb(dir + "/a.png");
  ASSERT_EQ(back.size(), rgb.size());
  EXPECT_EQ(cv::norm(back, rgb, cv::NORM_INF), 0.0);
  EXPECT_EQ(ReadAll(dir + "/a.png"), ReadAll(dir + "/b.png"));
  // A view (not continuous) is written as its pixels.
  const cv::Mat view = rgb(cv::Rect(5, 7, 50, 30));
  internal::WritePairPng(dir + "/c.png", view);
  EXPECT_EQ(cv::norm(ReadImageRgb(dir + "/c.png"), view, cv::NORM_INF), 0.0);
  EXPECT_THROW(internal::WritePairPng(dir + "/d.png", cv::Mat()), InputError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace geodrive

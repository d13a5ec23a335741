// Image decoding: geometry/image_io.h (TurboJPEG, libspng) against OpenCV's
// imgcodecs on a real 1600x900 nuScenes CAM_FRONT JPEG and a real 1242x375
// KITTI PNG, single thread. Figures: docs/PERFORMANCE.md "Images".

#include <benchmark/benchmark.h>

#include <algorithm>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "geometry/image_io.h"
#include "geometry/util/files.h"

namespace {

// The first CAM_FRONT keyframe of the real scene-0916 extract.
std::string NuscenesJpeg() {
  static const std::string path = [] {
    std::vector<std::string> files;
    for (const auto& e : std::filesystem::directory_iterator(
             std::string(GEODRIVE_SHARED_DATA_DIR) +
             "/real/nuscenes_scene0916/samples/CAM_FRONT")) {
      if (e.path().extension() == ".jpg") files.push_back(e.path().string());
    }
    std::sort(files.begin(), files.end());
    return files.empty() ? std::string() : files.front();
  }();
  return path;
}

std::string KittiPng() {
  return std::string(GEODRIVE_SHARED_DATA_DIR) +
         "/real/kitti_000008/000008.png";
}

// geometry/image_io.h: file read + header checks + decode (RGB).
void BM_ReadImageRgbJpeg(benchmark::State& state) {
  const std::string path = NuscenesJpeg();
  for (auto _ : state) benchmark::DoNotOptimize(geodrive::ReadImageRgb(path));
}
BENCHMARK(BM_ReadImageRgbJpeg)->Unit(benchmark::kMillisecond);

// The OpenCV route: file read + cv::imdecode(IMREAD_COLOR) + BGR to RGB.
void BM_OpenCvImdecodeRgbJpeg(benchmark::State& state) {
  const std::string path = NuscenesJpeg();
  for (auto _ : state) {
    const std::vector<uint8_t> bytes = geodrive::ReadFileBytes(path, 1u << 30);
    cv::Mat bgr = cv::imdecode(bytes, cv::IMREAD_COLOR), rgb;
    cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
    benchmark::DoNotOptimize(rgb.data);
  }
}
BENCHMARK(BM_OpenCvImdecodeRgbJpeg)->Unit(benchmark::kMillisecond);

// cv::imdecode alone (BGR, no channel swap), from memory.
void BM_OpenCvImdecodeBgrJpegInMemory(benchmark::State& state) {
  const std::vector<uint8_t> bytes =
      geodrive::ReadFileBytes(NuscenesJpeg(), 1u << 30);
  for (auto _ : state)
    benchmark::DoNotOptimize(cv::imdecode(bytes, cv::IMREAD_COLOR));
}
BENCHMARK(BM_OpenCvImdecodeBgrJpegInMemory)->Unit(benchmark::kMillisecond);

// DCT-domain downscaling: 1/2 (800x450), 1/4 (400x225), 1/8 (200x113).
void BM_ReadImageRgbScaledJpeg(benchmark::State& state) {
  const std::string path = NuscenesJpeg();
  const int denom = static_cast<int>(state.range(0));
  for (auto _ : state) {
    benchmark::DoNotOptimize(
        geodrive::ReadImageRgbScaled(path, 1600 / denom, 900 / denom));
  }
}
BENCHMARK(BM_ReadImageRgbScaledJpeg)
    ->Arg(2)
    ->Arg(4)
    ->Arg(8)
    ->Unit(benchmark::kMillisecond);

// Every M/8 scale (ReadImageRgbScaled with a JpegScale): 1/8, 1/4, 1/2 and
// 1/1 have SIMD inverse DCTs in libjpeg-turbo, 3/8, 5/8, 3/4 and 7/8 run its C
// ones (docs/PERFORMANCE.md, "Dataset builder").
void BM_ReadImageRgbAtJpegScale(benchmark::State& state) {
  const std::string path = NuscenesJpeg();
  const geodrive::JpegScale scale{static_cast<int>(state.range(0)), 8};
  for (auto _ : state)
    benchmark::DoNotOptimize(geodrive::ReadImageRgbScaled(path, scale));
}
BENCHMARK(BM_ReadImageRgbAtJpegScale)
    ->DenseRange(1, 8)
    ->Unit(benchmark::kMillisecond);

// Decode at full size, then cv::resize to 1/4 (INTER_AREA): what a caller
// without ReadImageRgbScaled does.
void BM_ReadImageRgbThenResizeQuarter(benchmark::State& state) {
  const std::string path = NuscenesJpeg();
  for (auto _ : state) {
    cv::Mat small;
    cv::resize(geodrive::ReadImageRgb(path), small, cv::Size(400, 225), 0, 0,
               cv::INTER_AREA);
    benchmark::DoNotOptimize(small.data);
  }
}
BENCHMARK(BM_ReadImageRgbThenResizeQuarter)->Unit(benchmark::kMillisecond);

void BM_ReadImageSizeJpeg(benchmark::State& state) {
  const std::string path = NuscenesJpeg();
  for (auto _ : state) benchmark::DoNotOptimize(geodrive::ReadImageSize(path));
}
BENCHMARK(BM_ReadImageSizeJpeg)->Unit(benchmark::kMicrosecond);

void BM_ReadImageRgbPng(benchmark::State& state) {
  const std::string path = KittiPng();
  for (auto _ : state) benchmark::DoNotOptimize(geodrive::ReadImageRgb(path));
}
BENCHMARK(BM_ReadImageRgbPng)->Unit(benchmark::kMillisecond);

void BM_OpenCvImdecodeRgbPng(benchmark::State& state) {
  const std::string path = KittiPng();
  for (auto _ : state) {
    const std::vector<uint8_t> bytes = geodrive::ReadFileBytes(path, 1u << 30);
    cv::Mat bgr = cv::imdecode(bytes, cv::IMREAD_COLOR), rgb;
    cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
    benchmark::DoNotOptimize(rgb.data);
  }
}
BENCHMARK(BM_OpenCvImdecodeRgbPng)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
  cv::setNumThreads(1);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  if (NuscenesJpeg().empty()) return 2;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

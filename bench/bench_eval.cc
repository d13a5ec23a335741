// SSIM + PSNR of 25 frame pairs at 480x720 (RGB uint8) on one thread -- the
// target of <= 150 ms. Figures and the skimage ratio:
// docs/PERFORMANCE.md "Evaluation metrics". With GEODRIVE_BENCH_DUMP_FRAMES=DIR
// the 25 frame pairs are also written to DIR/gt.npy and DIR/pred.npy (uint8,
// 25 x 480 x 720 x 3) so that skimage can be timed on the same frames.

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "eval/frechet.h"
#include "eval/image_metrics.h"
#include "geometry/npy.h"

namespace {

void MakeFrames(std::vector<cv::Mat>* gt, std::vector<cv::Mat>* pred) {
  cv::RNG rng(20250528);
  for (int i = 0; i < 25; ++i) {
    cv::Mat g(480, 720, CV_8UC3), noise(480, 720, CV_8UC3);
    rng.fill(g, cv::RNG::UNIFORM, 0, 256);
    cv::GaussianBlur(g, g, cv::Size(0, 0), 2.0);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 20);
    gt->push_back(g);
    pred->push_back(g + noise);
  }
  const char* dump = std::getenv("GEODRIVE_BENCH_DUMP_FRAMES");
  if (dump == nullptr || *dump == '\0') return;
  for (const auto& [name, frames] :
       {std::pair{"gt", gt}, std::pair{"pred", pred}}) {
    std::vector<uint8_t> data;
    for (const cv::Mat& f : *frames)
      data.insert(data.end(), f.data, f.data + f.total() * f.elemSize());
    geodrive::WriteNpy(
        std::string(dump) + "/" + name + ".npy",
        geodrive::NpyArray::Uint8({25, 480, 720, 3}, data.data()));
  }
}

void BM_SsimPsnr25Frames480x720(benchmark::State& state) {
  std::vector<cv::Mat> gt, pred;
  MakeFrames(&gt, &pred);
  geodrive::FrameMetricsOptions options;
  options.num_threads = static_cast<int>(state.range(0));
  for (auto _ : state) {
    const geodrive::VideoScores s = geodrive::CompareVideos(pred, gt, options);
    benchmark::DoNotOptimize(s.mean.ssim_rgb);
    state.counters["ssim"] = s.mean.ssim_rgb;  // skimage: 0.793673573565
  }
  state.counters["frames"] = 25;
}
BENCHMARK(BM_SsimPsnr25Frames480x720)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The two parts of the workload above, one thread.
void BM_Ssim25Frames480x720(benchmark::State& state) {
  std::vector<cv::Mat> gt, pred;
  MakeFrames(&gt, &pred);
  for (auto _ : state) {
    double sum = 0;
    for (int i = 0; i < 25; ++i) sum += geodrive::Ssim(pred[i], gt[i]);
    benchmark::DoNotOptimize(sum);
  }
}
BENCHMARK(BM_Ssim25Frames480x720)->Unit(benchmark::kMillisecond);

void BM_Psnr25Frames480x720(benchmark::State& state) {
  std::vector<cv::Mat> gt, pred;
  MakeFrames(&gt, &pred);
  for (auto _ : state) {
    double sum = 0;
    for (int i = 0; i < 25; ++i) sum += geodrive::Psnr(pred[i], gt[i]);
    benchmark::DoNotOptimize(sum);
  }
}
BENCHMARK(BM_Psnr25Frames480x720)->Unit(benchmark::kMillisecond);

void BM_SsimOneFrameGenericPath(benchmark::State& state) {
  std::vector<cv::Mat> gt, pred;
  MakeFrames(&gt, &pred);
  geodrive::SsimOptions options;
  options.fused_kernel = false;
  for (auto _ : state)
    benchmark::DoNotOptimize(geodrive::Ssim(pred[0], gt[0], options));
}
BENCHMARK(BM_SsimOneFrameGenericPath)->Unit(benchmark::kMillisecond);

void BM_Frechet2048(benchmark::State& state) {
  const int d = static_cast<int>(state.range(0));
  geodrive::FeatureStatistics a, b;
  const Eigen::MatrixXd fa = Eigen::MatrixXd::Random(d + 100, d);
  const Eigen::MatrixXd fb = Eigen::MatrixXd::Random(d + 100, d);
  a = geodrive::ComputeFeatureStatistics(fa);
  b = geodrive::ComputeFeatureStatistics(fb);
  for (auto _ : state)
    benchmark::DoNotOptimize(geodrive::FrechetDistance(a, b).distance);
}
BENCHMARK(BM_Frechet2048)->Arg(400)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();

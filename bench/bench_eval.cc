// SSIM + PSNR of 25 frame pairs at 480x720 (RGB uint8) on one thread -- the
// issue's speed bar
// (<= 150 ms). Figures and the skimage ratio: docs/PERFORMANCE.md "Evaluation
// metrics".

#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "eval/frechet.h"
#include "eval/image_metrics.h"

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
}

void BM_SsimPsnr25Frames480x720(benchmark::State& state) {
  std::vector<cv::Mat> gt, pred;
  MakeFrames(&gt, &pred);
  geodrive::FrameMetricsOptions options;
  options.num_threads = static_cast<int>(state.range(0));
  for (auto _ : state) {
    const geodrive::VideoScores s = geodrive::CompareVideos(pred, gt, options);
    benchmark::DoNotOptimize(s.mean.ssim_rgb);
  }
  state.counters["frames"] = 25;
}
BENCHMARK(BM_SsimPsnr25Frames480x720)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

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

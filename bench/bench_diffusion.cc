// Diffusion runtime benchmarks (LibTorch CPU): the `tiny` forward (encoder +
// backbone) and one CogVideoX-5B block forward at the real token count, with
// peak RSS and the number of block forwards per sampling step.
//
// Quick (tiny + a 5B block at 1 latent frame = 1,576 tokens):
//   OMP_NUM_THREADS=2 bench_diffusion
// Full token count (13 latent frames = 17,776 tokens), in its own process since
// peak RSS is the process high-water mark (getrusage):
//   GEODRIVE_BENCH_5B_FULL=1 OMP_NUM_THREADS=2 bench_diffusion
//       --benchmark_filter=Full

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>
#include <c10/core/InferenceMode.h>
#include <sys/resource.h>

#include <cstdlib>
#include <string>

#include "diffusion/config.h"
#include "diffusion/model.h"
#include "diffusion/sampler.h"

namespace geodrive {
namespace diffusion {
namespace {

double PeakRssMb() {
  struct rusage u;
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0;  // kB on Linux
}

void BM_TinyForward(benchmark::State& state) {
  c10::InferenceMode guard;
  const DiTConfig c = ConfigPreset("tiny");
  const Weights backbone = InitWeights(BackboneParamSpecs(c), 1);
  const Weights branch = InitBranchFromBackbone(c, backbone, 2);
  const int64_t B = 2;  // CFG batch
  const at::Tensor noisy = at::randn(
      {B, c.latent_frames, c.out_channels, c.latent_height, c.latent_width});
  const at::Tensor text = at::randn({B, c.text_seq_len, c.text_embed_dim});
  const at::Tensor t = at::full({B}, 500.0);
  for (auto _ : state) {
    auto res = BranchForward(c, branch, noisy, noisy, text, t);
    at::Tensor v =
        BackboneForward(c, backbone, at::cat({noisy, noisy}, 2), text, t, res);
    benchmark::DoNotOptimize(v.data_ptr());
  }
  state.counters["threads"] = at::get_num_threads();
}

// One CogVideoXBlock of the 5B model on [226 text; frames x 1,350 video]
// tokens, batch 1.
void BM_CogVideoX5BBlock(benchmark::State& state) {
  c10::InferenceMode guard;
  DiTConfig c = ConfigPreset("cogvideox-5b-i2v");
  const int64_t frames = state.range(0);
  std::vector<ParamSpec> block;
  for (const auto& s : BackboneParamSpecs(c)) {
    if (s.name.rfind("transformer_blocks.0.", 0) == 0) block.push_back(s);
  }
  const Weights w = InitWeights(block, 3);
  const double weights_mb = NumElements(block) * 4.0 / (1 << 20);
  const int64_t nv = frames * c.tokens_per_frame(), D = c.inner_dim();
  const RotaryTables rope =
      Rotary3D(c, frames, c.latent_height / 2, c.latent_width / 2);
  const at::Tensor temb = at::randn({1, c.time_embed_dim});
  const at::Tensor video0 = at::randn({1, nv, D}),
                   text0 = at::randn({1, c.text_seq_len, D});
  const double rss_before = PeakRssMb();
  ForwardOptions
      opt;  // defaults: 256 MB attention chunks, 4,096-token FF chunks
  for (auto _ : state) {
    at::Tensor video = video0, text = text0;
    BlockForward(c, w, "transformer_blocks.0.", temb, rope, opt, &video, &text);
    benchmark::DoNotOptimize(video.data_ptr());
  }
  state.counters["tokens"] = static_cast<double>(nv + c.text_seq_len);
  state.counters["block_weights_MB"] = weights_mb;
  state.counters["peak_rss_MB"] = PeakRssMb();
  state.counters["rss_before_forward_MB"] = rss_before;
  state.counters["threads"] = at::get_num_threads();
  // One sampling step = (42 backbone + 2 encoder blocks) x CFG batch 2
  // block-forwards.
  state.counters["block_forwards_per_step"] =
      (c.num_layers + c.branch_layers) * 2.0;
}

}  // namespace
}  // namespace diffusion
}  // namespace geodrive

int main(int argc, char** argv) {
  using namespace geodrive::diffusion;
  ConfigureThreads(0);
  benchmark::RegisterBenchmark("BM_TinyForward", BM_TinyForward)
      ->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("BM_CogVideoX5BBlock/Frames1",
                               BM_CogVideoX5BBlock)
      ->Arg(1)
      ->Iterations(2)
      ->Unit(benchmark::kSecond);
  if (const char* full = std::getenv("GEODRIVE_BENCH_5B_FULL");
      full && std::string(full) == "1") {
    benchmark::RegisterBenchmark("BM_CogVideoX5BBlock/Full",
                                 BM_CogVideoX5BBlock)
        ->Arg(13)
        ->Iterations(1)
        ->Unit(benchmark::kSecond);
  }
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

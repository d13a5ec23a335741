// `geodrive-device-check`: what the diffusion runtime does on a device, for
// scripts/device_check.sh (which builds it standalone against the PyTorch
// installation it finds) and for a CPU smoke test in CI. Prints:
//   1. the LibTorch build (version, CUDA devices, attention kernel);
//   2. agreement of the tiny config on the CPU in float32 (the reference) and
//      on --device in float32 and in --dtype: max |difference| per output
//      (encoder outputs, backbone output, three sampling steps, VAE decode);
//      on the CPU, the chunked and the fused attention are compared too;
//   3. one 5B-shape DiT block forward (17,776 tokens) in --dtype: time, peak
//      memory;
//   4. one full sampling step of the 5B shape with random weights (42
//      backbone + 2 encoder blocks, classifier-free guidance batch 2): time,
//      peak memory; on CUDA also with the blocks offloaded to host memory;
//   5. a 5B-shape VAE decode of 13 latent frames (49 x 480 x 720): time, peak
//      memory.
// --shape small runs 3-5 on scaled-down shapes (a CPU can do them in
// seconds); --shape 5b is the real model's. Exit 0 when every part ran and
// the agreement is within the stated tolerances, 1 otherwise.

#include <ATen/ATen.h>
#include <ATen/CPUGeneratorImpl.h>
#include <c10/core/InferenceMode.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "diffusion/config.h"
#include "diffusion/model.h"
#include "diffusion/runtime.h"
#include "diffusion/runtime_torch.h"
#include "diffusion/schedule.h"
#include "diffusion/scheduler.h"
#include "diffusion/vae.h"
#include "diffusion/vae_config.h"
#include "geometry/util/status.h"

#ifdef GEODRIVE_CUDA_STATS
#include <c10/cuda/CUDACachingAllocator.h>
#endif

namespace geodrive {
namespace diffusion {
namespace {

struct CheckOptions {
  // Device under test.
  DeviceSpec device;
  // Dtype of the 5B-shape parts and of the second agreement run.
  ComputeDtype dtype = ComputeDtype::kBFloat16;
  // "5b" (the real shapes) or "small" (scaled down for a CPU).
  std::string shape = "small";
  // Timed repetitions after one warm-up run (the median is printed).
  int repeats = 3;
  // Parts to skip: "agreement", "block", "step", "vae".
  std::vector<std::string> skip;
  bool Skipped(const std::string& part) const {
    return std::find(skip.begin(), skip.end(), part) != skip.end();
  }
};

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since)
      .count();
}

// Waits for the device's queue (a host read of a reduction).
void Sync(const at::Tensor& t) {
  if (t.defined() && !t.is_cpu()) (void)t.sum().item<float>();
}

// Peak memory since the last Reset: the CUDA caching allocator's peak of
// allocated bytes where the build has its statistics, else the process's peak
// resident set (CPU; not resettable, so a high-water mark of the run).
struct PeakMemory {
  DeviceSpec device;
  void Reset() const {
#ifdef GEODRIVE_CUDA_STATS
    if (device.is_cuda())
      c10::cuda::CUDACachingAllocator::resetPeakStats(device.index);
#endif
  }
  std::string Report() const {
    char buf[96];
#ifdef GEODRIVE_CUDA_STATS
    if (device.is_cuda()) {
      const auto stats =
          c10::cuda::CUDACachingAllocator::getDeviceStats(device.index);
      std::snprintf(buf, sizeof(buf), "peak %.2f GB allocated on %s",
                    stats.allocated_bytes[0].peak / 1e9,
                    device.ToString().c_str());
      return buf;
    }
#endif
    if (device.is_cuda()) return "peak memory not available in this build";
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    std::snprintf(buf, sizeof(buf), "process peak RSS %.2f GB",
                  ru.ru_maxrss * 1024.0 / 1e9);
    return buf;
  }
};

// Median time of `repeats` runs of `fn` after one warm-up; fn returns a tensor
// to synchronise on.
double TimeIt(int repeats, const std::function<at::Tensor()>& fn) {
  Sync(fn());
  std::vector<double> t;
  for (int i = 0; i < repeats; ++i) {
    const auto start = std::chrono::steady_clock::now();
    Sync(fn());
    t.push_back(Seconds(start));
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

double MaxAbsDiff(const at::Tensor& a, const at::Tensor& b) {
  return (a.to(at::kFloat).cpu() - b.to(at::kFloat).cpu())
      .abs()
      .max()
      .item<double>();
}

double MaxAbs(const at::Tensor& a) {
  return a.to(at::kFloat).abs().max().item<double>();
}

// Random weights drawn on the device (N(0, 1/fan_in) matrices, small biases,
// unit LayerNorms, zero encoder projections), for timing only: drawing 5.6e9
// numbers on the host would take minutes.
Weights RandomWeightsOn(const std::vector<ParamSpec>& specs,
                        const at::TensorOptions& options) {
  Weights w;
  const at::TensorOptions f32 = options.dtype(at::kFloat);
  for (const auto& s : specs) {
    at::Tensor t;
    const bool norm =
        s.name.find("norm") != std::string::npos && s.shape.size() == 1;
    if (s.name.rfind("branch_", 0) == 0) {
      t = at::zeros(s.shape, f32);
    } else if (norm) {
      t = s.name.size() > 7 &&
                  s.name.compare(s.name.size() - 7, 7, ".weight") == 0
              ? at::ones(s.shape, f32)
              : at::zeros(s.shape, f32);
    } else if (s.shape.size() >= 2) {
      const int64_t fan_in = NumElements(s.shape) / s.shape[0];
      t = at::randn(s.shape, f32) / std::sqrt(static_cast<double>(fan_in));
    } else {
      t = at::randn(s.shape, f32) * 0.02;
    }
    w.Set(s.name, t.to(options.dtype()));
  }
  return w;
}

// The DiT's outputs for one set of inputs: encoder outputs, backbone output
// and three DPM sampling steps from seeded noise.
struct TinyOutputs {
  std::vector<at::Tensor> branch;
  at::Tensor backbone, sampled, decoded;
};

TinyOutputs RunTiny(const DeviceSpec& device,
                    ComputeDtype dtype,
                    AttentionBackend attention) {
  const DiTConfig cfg = ConfigPreset("tiny");
  WeightPlacement place;
  place.device = device;
  place.dtype = dtype;
  const Weights backbone = InitWeights(BackboneParamSpecs(cfg), 7, place);
  Weights branch = InitBranchFromBackbone(cfg, backbone, 8);
  // Non-zero encoder projections, so that the encoder's outputs matter.
  at::Generator gen = at::make_generator<at::CPUGeneratorImpl>(9);
  const at::TensorOptions opts = ComputeOptions(device, dtype);
  for (int k = 0; k < cfg.branch_layers; ++k) {
    const std::string b = "branch_blocks." + std::to_string(k);
    branch.Set(
        b + ".weight",
        (at::randn(branch.Get(b + ".weight").sizes(), gen) * 0.1).to(opts));
    branch.Set(
        b + ".bias",
        (at::randn(branch.Get(b + ".bias").sizes(), gen) * 0.02).to(opts));
  }
  ForwardOptions fwd;
  fwd.attention = attention;
  const at::TensorOptions f32 = ComputeOptions(device, ComputeDtype::kFloat32);
  const int64_t B = 2, F = cfg.latent_frames, C = cfg.out_channels;
  const int64_t H = cfg.latent_height, W = cfg.latent_width;
  at::Tensor noisy = at::randn({B, F, C, H, W}, gen).to(f32);
  at::Tensor cond = at::randn({B, F, C, H, W}, gen).to(f32);
  at::Tensor image = at::randn({B, F, C, H, W}, gen).to(f32);
  at::Tensor text =
      at::randn({B, cfg.text_seq_len, cfg.text_embed_dim}, gen).to(f32);
  at::Tensor t = at::full({B}, 499.0, f32);
  TinyOutputs out;
  out.branch = BranchForward(cfg, branch, noisy, cond, text, t, fwd);
  out.backbone = BackboneForward(cfg, backbone, at::cat({noisy, image}, 2),
                                 text, t, out.branch, fwd);
  // Three DPM steps (50-step schedule), CFG on the [negative; positive] text.
  ScheduleConfig sc;
  const std::vector<double> ab = AlphasCumprod(sc);
  const std::vector<int64_t> ts = InferenceTimesteps(sc, 50);
  at::Generator noise = at::make_generator<at::CPUGeneratorImpl>(11);
  at::Tensor x = at::randn({1, F, C, H, W}, noise).to(f32);
  at::Tensor old_x0;
  for (int i = 0; i < 3; ++i) {
    const at::Tensor x_in = at::cat({x, x}, 0);
    const at::Tensor tt = at::full({2}, static_cast<double>(ts[i]), f32);
    const auto res = BranchForward(cfg, branch, x_in, cond, text, tt, fwd);
    at::Tensor v = BackboneForward(cfg, backbone, at::cat({x_in, image}, 2),
                                   text, tt, res, fwd)
                       .to(at::kFloat);
    v = ClassifierFreeGuidance(v, 6.0);
    const int64_t prev = ts[i] - 20;
    at::Tensor x0;
    x = DpmStep(
        v, old_x0, x, AlphaBarAt(ab, sc, ts[i]), AlphaBarAt(ab, sc, prev),
        i > 0 ? AlphaBarAt(ab, sc, ts[i - 1]) : -1.0, prev >= 0, noise, &x0);
    old_x0 = x0;
  }
  out.sampled = x;
  const VaeConfig vc = VaePreset("tiny");
  const Weights vae = VaeInitWeights(vc, 13).To(opts);
  out.decoded = VaeDecode(vc, vae, x[0].permute({1, 0, 2, 3}).unsqueeze(0));
  return out;
}

// Prints the agreement of `b` with the reference `a`; true when every output
// is within `tol` relative to the output's magnitude.
bool Compare(const char* what,
             const TinyOutputs& a,
             const TinyOutputs& b,
             double tol) {
  bool ok = true;
  std::printf("  %-34s", what);
  auto one = [&](const char* name, const at::Tensor& x, const at::Tensor& y) {
    const double d = MaxAbsDiff(x, y), scale = std::max(1.0, MaxAbs(x));
    ok = ok && d <= tol * scale;
    std::printf(" %s %.2e", name, d);
  };
  for (size_t k = 0; k < a.branch.size(); ++k) {
    const std::string name = "encoder[" + std::to_string(k) + "]";
    one(name.c_str(), a.branch[k], b.branch[k]);
  }
  one("backbone", a.backbone, b.backbone);
  one("3-step-sample", a.sampled, b.sampled);
  one("vae-decode", a.decoded, b.decoded);
  std::printf("  (tolerance %.0e x max(1, |ref|)) %s\n", tol,
              ok ? "ok" : "FAIL");
  return ok;
}

bool Agreement(const CheckOptions& o) {
  std::printf(
      "agreement, tiny config, max |difference| to the CPU float32 "
      "chunked-attention reference:\n");
  const DeviceSpec cpu;
  const TinyOutputs ref =
      RunTiny(cpu, ComputeDtype::kFloat32, AttentionBackend::kChunked);
  bool ok = true;
  ok &= Compare("cpu fp32 fused attention", ref,
                RunTiny(cpu, ComputeDtype::kFloat32, AttentionBackend::kFused),
                1e-4);
  if (o.device.is_cuda()) {
    const std::string d = o.device.ToString();
    ok &= Compare(
        (d + " fp32 auto attention").c_str(), ref,
        RunTiny(o.device, ComputeDtype::kFloat32, AttentionBackend::kAuto),
        1e-3);
  }
  // Reduced precision: bf16 keeps 8 significant bits (relative step 2^-8),
  // fp16 11; through 4 blocks, 3 steps and a VAE the error grows to a few
  // steps of the format.
  const double tol = o.dtype == ComputeDtype::kFloat32   ? 1e-3
                     : o.dtype == ComputeDtype::kFloat16 ? 2e-2
                                                         : 1e-1;
  const std::string what =
      o.device.ToString() + " " + DtypeName(o.dtype) + " auto attention";
  ok &= Compare(what.c_str(), ref,
                RunTiny(o.device, o.dtype, AttentionBackend::kAuto), tol);
  return ok;
}

// The config of the timed parts: the 5B preset, or a scaled-down one.
DiTConfig TimedConfig(const CheckOptions& o) {
  DiTConfig c = ConfigPreset("cogvideox-5b-i2v");
  if (o.shape == "small") {
    c.num_layers = 4;
    c.num_heads = 4;
    c.head_dim = 64;
    c.latent_frames = 3;
    c.latent_height = 16;
    c.latent_width = 24;
    c.text_seq_len = 16;
    c.text_embed_dim = 64;
    c.time_embed_dim = 64;
    c.name = "5b-small";
  }
  return c;
}

void Block(const CheckOptions& o, const PeakMemory& peak) {
  const DiTConfig c = TimedConfig(o);
  const at::TensorOptions opts = ComputeOptions(o.device, o.dtype);
  std::vector<ParamSpec> specs;
  for (const auto& s : BackboneParamSpecs(c)) {
    if (s.name.rfind("transformer_blocks.0.", 0) == 0) specs.push_back(s);
  }
  const Weights w = RandomWeightsOn(specs, opts);
  const int64_t nv = c.video_tokens(), nt = c.text_seq_len, d = c.inner_dim();
  const at::Tensor video0 = at::randn({1, nv, d}, opts);
  const at::Tensor text0 = at::randn({1, nt, d}, opts);
  const at::Tensor temb = at::randn({1, c.time_embed_dim}, opts);
  const DiTConfig& cc = c;
  const RotaryTables cpu_rope =
      Rotary3D(cc, c.latent_frames, c.latent_height / c.patch_size,
               c.latent_width / c.patch_size);
  const RotaryTables rope = {cpu_rope.cos.to(opts.device()),
                             cpu_rope.sin.to(opts.device())};
  ForwardOptions fwd;
  peak.Reset();
  const double s = TimeIt(o.repeats, [&] {
    at::Tensor video = video0, text = text0;
    BlockForward(cc, w, "transformer_blocks.0.", temb, rope, fwd, &video,
                 &text);
    return video;
  });
  std::printf(
      "block    %s %s %lld tokens (%lld video + %lld text), attention "
      "%s: %.2f ms, %s\n",
      c.name.c_str(), DtypeName(o.dtype), static_cast<long long>(nv + nt),
      static_cast<long long>(nv), static_cast<long long>(nt),
      AttentionBackendName(ResolveAttentionBackend(fwd.attention)), s * 1e3,
      peak.Report().c_str());
}

void Step(const CheckOptions& o, const PeakMemory& peak) {
  const DiTConfig c = TimedConfig(o);
  const at::TensorOptions opts = ComputeOptions(o.device, o.dtype);
  const at::TensorOptions f32 =
      ComputeOptions(o.device, ComputeDtype::kFloat32);
  auto start = std::chrono::steady_clock::now();
  Weights backbone = RandomWeightsOn(BackboneParamSpecs(c), opts);
  const Weights branch = RandomWeightsOn(BranchParamSpecs(c), opts);
  Sync(backbone.Get("proj_out.weight"));
  std::printf("step     %s: random weights on %s in %.1f s (%.2f GB)\n",
              c.name.c_str(), o.device.ToString().c_str(), Seconds(start),
              (backbone.Bytes() + branch.Bytes()) / 1e9);
  const int64_t F = c.latent_frames, C = c.out_channels;
  const int64_t H = c.latent_height, W = c.latent_width;
  const at::Tensor x = at::randn({1, F, C, H, W}, f32);
  const at::Tensor cond = at::randn({2, F, C, H, W}, f32);
  const at::Tensor image = at::randn({2, F, C, H, W}, f32);
  const at::Tensor text = at::zeros({2, c.text_seq_len, c.text_embed_dim}, f32);
  ScheduleConfig sc;
  const std::vector<double> ab = AlphasCumprod(sc);
  at::Generator gen = at::make_generator<at::CPUGeneratorImpl>(0);
  ForwardOptions fwd;
  peak.Reset();
  const double s = TimeIt(o.repeats, [&] {
    const at::Tensor x_in = at::cat({x, x}, 0);
    const at::Tensor tt = at::full({2}, 999.0, f32);
    const auto res = BranchForward(c, branch, x_in, cond, text, tt, fwd);
    at::Tensor v = BackboneForward(c, backbone, at::cat({x_in, image}, 2), text,
                                   tt, res, fwd)
                       .to(at::kFloat);
    v = ClassifierFreeGuidance(v, 6.0);
    return DpmStep(v, at::Tensor(), x, AlphaBarAt(ab, sc, 999),
                   AlphaBarAt(ab, sc, 979), -1.0, true, gen, nullptr);
  });
  std::printf(
      "step     %s %s, %d backbone + %d encoder blocks, CFG batch 2, "
      "%lld tokens: %.3f s per sampling step, %s\n",
      c.name.c_str(), DtypeName(o.dtype), c.num_layers, c.branch_layers,
      static_cast<long long>(c.seq_len()), s, peak.Report().c_str());
  if (!o.device.is_cuda()) return;
  // The same step with the backbone's blocks in pinned host memory
  // (--offload-backbone): each block is copied to the GPU for its forward.
  Weights offloaded;
  for (const auto& name : backbone.order) {
    const at::Tensor& t = backbone.Get(name);
    offloaded.Set(name, name.rfind("transformer_blocks.", 0) == 0
                            ? t.cpu().pin_memory()
                            : t);
  }
  backbone = Weights();  // the GPU copies of the blocks are freed
  ForwardOptions off = fwd;
  off.offload_blocks = true;
  peak.Reset();
  const double so = TimeIt(o.repeats, [&] {
    const at::Tensor x_in = at::cat({x, x}, 0);
    const at::Tensor tt = at::full({2}, 999.0, f32);
    const auto res = BranchForward(c, branch, x_in, cond, text, tt, off);
    return BackboneForward(c, offloaded, at::cat({x_in, image}, 2), text, tt,
                           res, off);
  });
  std::printf(
      "step     %s %s with --offload-backbone (blocks in pinned host "
      "memory): %.3f s per sampling step, %s\n",
      c.name.c_str(), DtypeName(o.dtype), so, peak.Report().c_str());
}

void Vae(const CheckOptions& o, const PeakMemory& peak) {
  VaeConfig vc = VaePreset("cogvideox-5b-i2v");
  int64_t frames = 13, h = 60, w = 90;
  if (o.shape == "small") {
    vc = VaePreset("tiny");
    frames = 5;
    h = 8;
    w = 12;
  }
  const at::TensorOptions opts = ComputeOptions(o.device, o.dtype);
  const Weights weights = VaeInitWeights(vc, 0).To(opts);
  const at::Tensor z = at::randn({1, vc.latent_channels, frames, h, w}, opts);
  peak.Reset();
  at::Tensor out;
  const double s = TimeIt(o.repeats, [&] {
    out = VaeDecode(vc, weights, z);
    return out;
  });
  std::printf(
      "vae      %s %s decode of %lld latent frames -> %lld x %lld x "
      "%lld: %.2f s, %s\n",
      vc.name.c_str(), DtypeName(o.dtype), static_cast<long long>(frames),
      static_cast<long long>(out.size(2)), static_cast<long long>(out.size(3)),
      static_cast<long long>(out.size(4)), s, peak.Report().c_str());
}

void PrintHelp() {
  std::printf(
      "geodrive-device-check [--device cpu|cuda[:N]] [--dtype fp32|bf16|fp16]\n"
      "    [--shape small|5b] [--repeats N] [--skip agreement,block,step,vae]\n"
      "Checks the diffusion runtime on a device: tiny-config agreement with "
      "the CPU\nfloat32 reference, then a DiT block, a full sampling step "
      "and a VAE decode of\nthe 5B shape (--shape 5b) or a scaled-down one "
      "(small), timed, with peak memory.\n");
}

int Run(int argc, char** argv) {
  CheckOptions o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      GEODRIVE_CHECK_INPUT(i + 1 < argc, a, " needs a value");
      return argv[++i];
    };
    if (a == "--help" || a == "-h") {
      PrintHelp();
      return 0;
    } else if (a == "--device") {
      o.device = ParseDevice(value());
    } else if (a == "--dtype") {
      o.dtype = ParseDtype(value());
    } else if (a == "--shape") {
      o.shape = value();
      GEODRIVE_CHECK_INPUT(o.shape == "small" || o.shape == "5b",
                           "--shape must be small or 5b, got '", o.shape, "'");
    } else if (a == "--repeats") {
      const std::string v = value();
      char* end = nullptr;
      const long n = std::strtol(v.c_str(), &end, 10);
      GEODRIVE_CHECK_INPUT(!v.empty() && *end == '\0' && n >= 1 && n <= 100,
                           "--repeats must be an integer in [1, 100], got '", v,
                           "'");
      o.repeats = static_cast<int>(n);
    } else if (a == "--skip") {
      std::string v = value();
      size_t pos = 0;
      while (pos <= v.size()) {
        const size_t comma = std::min(v.find(',', pos), v.size());
        o.skip.push_back(v.substr(pos, comma - pos));
        pos = comma + 1;
      }
    } else {
      ThrowInputError(a, "unknown option (see --help)");
    }
  }
  RuntimeOptions runtime;
  runtime.device = o.device;
  runtime.Check();
  c10::InferenceMode guard;
  at::manual_seed(0);
  std::printf("runtime  %s\n", GetRuntimeInfo().BriefReport().c_str());
  const PeakMemory peak{o.device};
  bool ok = true;
  const auto start = std::chrono::steady_clock::now();
  if (!o.Skipped("agreement")) ok &= Agreement(o);
  if (!o.Skipped("block")) Block(o, peak);
  if (!o.Skipped("step")) Step(o, peak);
  if (!o.Skipped("vae")) Vae(o, peak);
  std::printf(
      "done     in %.1f s: %s\n", Seconds(start),
      ok ? "all agreement checks within tolerance" : "AGREEMENT FAILED");
  return ok ? 0 : 1;
}

}  // namespace
}  // namespace diffusion
}  // namespace geodrive

int main(int argc, char** argv) {
  try {
    return geodrive::diffusion::Run(argc, argv);
  } catch (const geodrive::InputError& e) {
    std::fprintf(stderr, "geodrive-device-check: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "geodrive-device-check: internal error: %s\n",
                 e.what());
    return 1;
  }
}

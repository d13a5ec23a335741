#include "diffusion/sampler.h"

#include <ATen/ATen.h>
#include <ATen/CPUGeneratorImpl.h>
#include <ATen/Parallel.h>
#include <c10/core/InferenceMode.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <set>
#include <sstream>

#include "diffusion/config.h"
#include "diffusion/model.h"
#include "diffusion/runtime_torch.h"
#include "diffusion/safetensors.h"
#include "diffusion/schedule.h"
#include "diffusion/scheduler.h"
#include "diffusion/vae.h"
#include "diffusion/vae_config.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace diffusion {

at::Tensor DdimStep(const at::Tensor& v,
                    const at::Tensor& x,
                    double at_,
                    double ap,
                    at::Tensor* x0_out) {
  const DdimCoefficients k = DdimStepCoefficients(at_, ap);
  at::Tensor x0 = x * k.x0_from_x - v * k.x0_from_v;
  if (x0_out != nullptr) *x0_out = x0;
  return x * k.a + x0 * k.b;
}

at::Tensor DpmStep(const at::Tensor& v,
                   const at::Tensor& old_x0,
                   const at::Tensor& x,
                   double at_,
                   double ap,
                   double aback,
                   bool prev_nonneg,
                   at::Generator gen,
                   at::Tensor* x0_out) {
  const DpmCoefficients k = DpmStepCoefficients(
      at_, ap, old_x0.defined() ? aback : -1.0, prev_nonneg);
  at::Tensor x0 = x * k.x0_from_x - v * k.x0_from_v;
  // Noise from the CPU generator, moved to x's device: the same numbers on
  // every device.
  auto draw = [&] {
    return at::randn(x.sizes(), gen, x.options().device(at::kCPU))
        .to(x.device());
  };
  at::Tensor noise = draw();
  at::Tensor prev = x * k.mult1 - x0 * k.mult2 + noise * k.noise;
  if (k.second_order) {
    at::Tensor d = x0 * k.mult3 - old_x0 * k.mult4;
    noise = draw();
    prev = x * k.mult1 - d * k.mult2 + noise * k.noise;
  }
  if (x0_out != nullptr) *x0_out = x0;
  return prev;
}

at::Tensor ClassifierFreeGuidance(const at::Tensor& doubled, double g) {
  std::vector<at::Tensor> uc = doubled.chunk(2, 0);
  return uc[0] + (uc[1] - uc[0]) * g;
}

void SampleOptions::Check() const {
  GEODRIVE_CHECK_INPUT(!weights.empty(), "--weights is required");
  GEODRIVE_CHECK_INPUT(!latents.empty(), "--latents is required");
  GEODRIVE_CHECK_INPUT(!cond_latents.empty(), "--cond-latents is required");
  GEODRIVE_CHECK_INPUT(!out.empty(), "--out is required");
  GEODRIVE_CHECK_INPUT(scheduler == "dpm" || scheduler == "ddim",
                       "--scheduler must be dpm or ddim");
  GEODRIVE_CHECK_INPUT(steps >= 1 && steps <= 1000,
                       "--steps must be in [1, 1000]");
  GEODRIVE_CHECK_INPUT(guidance >= 0, "--guidance must be >= 0");
  GEODRIVE_CHECK_INPUT(attention_chunk_mb >= 1 && ff_token_chunk >= 1,
                       "chunk sizes must be positive");
}

std::string SampleResult::BriefReport() const {
  std::ostringstream os;
  os << "sampled " << steps << " steps in " << seconds << " s"
     << (guidance_used ? " with classifier-free guidance" : " without guidance")
     << " on " << runtime << ", " << weight_bytes / 1e6 << " MB of weights -> "
     << out;
  return os.str();
}

void InitWeightsOptions::Check() const {
  GEODRIVE_CHECK_INPUT(!out.empty(), "--out is required");
}

void ConfigureThreads(int threads) {
  if (threads <= 0) {
    const char* env = std::getenv("OMP_NUM_THREADS");
    if (env != nullptr) threads = std::atoi(env);
  }
  if (threads > 0) at::set_num_threads(threads);
}

namespace {

// The tensor `preferred` of `path`, or its only tensor.
at::Tensor LoadOne(const std::string& path, const std::string& preferred) {
  SafetensorsCheckpoint ckpt(path);
  if (ckpt.Has(preferred)) return ckpt.Load(preferred).to(at::kFloat);
  if (ckpt.entries().size() == 1)
    return ckpt.Load(ckpt.entries()[0].name).to(at::kFloat);
  ThrowInputError(path, "expected a tensor named '", preferred,
                  "' or exactly one tensor, found ", ckpt.entries().size());
}

void CheckFinite(const at::Tensor& t, const std::string& path) {
  GEODRIVE_CHECK_INPUT(at::isfinite(t).all().item<bool>(), path,
                       ": contains NaN or Inf");
}

bool HasPrefix(const std::string& path, const std::string& prefix) {
  SafetensorsCheckpoint ckpt(path);
  for (const auto& e : ckpt.entries()) {
    if (e.name.rfind(prefix, 0) == 0) return true;
  }
  return false;
}

void DrawProgress(int done, int total, int64_t t, double elapsed) {
  const int width = 30;
  const int filled = total > 0 ? done * width / total : width;
  std::string bar(filled, '#');
  bar += std::string(width - filled, '.');
  const double per = done > 0 ? elapsed / done : 0.0;
  std::fprintf(stderr, "\rsample [%s] %d/%d t=%lld %.2f s/step, eta %.0f s   ",
               bar.c_str(), done, total, static_cast<long long>(t), per,
               per * (total - done));
  if (done == total) std::fprintf(stderr, "\n");
  std::fflush(stderr);
}

// The prompt embeddings of --prompt-embeds expanded to batch B (float32, CPU):
// *pos always (zeros without the file), *neg when the file has them.
void LoadPromptEmbeds(const SampleOptions& o,
                      const DiTConfig& cfg,
                      int64_t B,
                      at::Tensor* pos_out,
                      at::Tensor* neg_out) {
  at::Tensor pos, neg;
  if (!o.prompt_embeds.empty()) {
    SafetensorsCheckpoint pe(o.prompt_embeds);
    GEODRIVE_CHECK_INPUT(pe.Has("prompt_embeds"), o.prompt_embeds,
                         ": needs a tensor 'prompt_embeds' [1|B, L, ",
                         cfg.text_embed_dim, "]");
    pos = pe.Load("prompt_embeds").to(at::kFloat);
    if (pe.Has("negative_prompt_embeds")) {
      neg = pe.Load("negative_prompt_embeds").to(at::kFloat);
    } else {
      GEODRIVE_CHECK_INPUT(
          o.guidance == 1.0, o.prompt_embeds,
          ": needs 'negative_prompt_embeds' (T5 of the empty prompt) for "
          "guidance ",
          o.guidance, " (or pass --guidance 1)");
    }
    for (at::Tensor* t : {&pos, &neg}) {
      if (!t->defined()) continue;
      GEODRIVE_CHECK_INPUT(
          t->dim() == 3 && (t->size(0) == 1 || t->size(0) == B) &&
              t->size(2) == cfg.text_embed_dim,
          o.prompt_embeds, ": prompt embeddings must be [1|", B, ", L, ",
          cfg.text_embed_dim, "], got ", ShapeToString(t->sizes().vec()));
      CheckFinite(*t, o.prompt_embeds);
      *t = t->expand({B, t->size(1), t->size(2)}).contiguous();
    }
  } else {
    pos = at::zeros({B, cfg.text_seq_len, cfg.text_embed_dim});
  }
  *pos_out = pos;
  *neg_out = neg;
}

}  // namespace

SampleResult Sample(const SampleOptions& o) {
  o.Check();
  o.runtime.Check();
  const auto start = std::chrono::steady_clock::now();
  c10::InferenceMode guard;
  DiTConfig cfg = ConfigPreset(o.config);
  cfg.conditioning_scale = o.conditioning_scale;
  ForwardOptions fwd;
  fwd.attention_chunk_bytes = o.attention_chunk_mb << 20;
  fwd.ff_token_chunk = o.ff_token_chunk;
  fwd.attention = o.attention;
  fwd.offload_blocks = o.runtime.offload_backbone;
  WeightPlacement placement;
  placement.device = o.runtime.device;
  placement.dtype = o.runtime.dtype;
  placement.host_blocks = o.runtime.offload_backbone;
  WeightPlacement branch_placement = placement;
  branch_placement.host_blocks = false;
  // Scheduler state, noise and latents: float32 on the compute device.
  const at::TensorOptions f32 =
      ComputeOptions(o.runtime.device, ComputeDtype::kFloat32);

  LoadReport report;
  Weights backbone = LoadWeights(o.weights, BackboneParamSpecs(cfg), "", true,
                                 &report, placement);
  Weights branch;
  if (!o.branch_weights.empty()) {
    branch = LoadWeights(o.branch_weights, BranchParamSpecs(cfg), "", false,
                         &report, branch_placement);
  } else if (HasPrefix(o.weights, "branch.")) {
    branch = LoadWeights(o.weights, BranchParamSpecs(cfg), "branch.", false,
                         &report, branch_placement);
  } else {
    branch = InitBranchFromBackbone(cfg, backbone, o.seed);
  }
  if (!o.branch_weights.empty() || HasPrefix(o.weights, "branch.")) {
    // The heads of the branch checkpoint are unused: only the used tensors must
    // be present.
    CheckBranchLoadReport(report);
  }

  at::Tensor cond = LoadOne(o.cond_latents, "latents");
  at::Tensor image = LoadOne(o.latents, "latents");
  CheckFinite(cond, o.cond_latents);
  CheckFinite(image, o.latents);
  GEODRIVE_CHECK_INPUT(cond.dim() == 5, o.cond_latents,
                       ": condition latents must be [B, F, C, H, W]");
  GEODRIVE_CHECK_INPUT(image.dim() == 5, o.latents,
                       ": image latents must be [B, F, C, H, W]");
  const int64_t B = cond.size(0), F = cond.size(1), C = cond.size(2),
                H = cond.size(3), W = cond.size(4);
  GEODRIVE_CHECK_INPUT(C == cfg.out_channels, o.cond_latents, ": has ", C,
                       " channels, '", cfg.name, "' uses ", cfg.out_channels);
  GEODRIVE_CHECK_INPUT(
      cfg.in_channels == 2 * C && cfg.branch_in_channels == 2 * C, "config '",
      cfg.name, "' does not take [latent, image] channel pairs");
  GEODRIVE_CHECK_INPUT(
      image.size(0) == B && image.size(1) <= F && image.size(2) == C &&
          image.size(3) == H && image.size(4) == W,
      o.latents, ": image latents ", ShapeToString(image.sizes().vec()),
      " do not fit the condition latents ", ShapeToString(cond.sizes().vec()));
  if (image.size(1) < F) {
    image = at::cat(
        {image, at::zeros({B, F - image.size(1), C, H, W}, image.options())},
        1);
  }
  cond = cond.to(f32);
  image = image.to(f32);

  // Text: [negative; positive] for classifier-free guidance.
  at::Tensor pos, neg;
  LoadPromptEmbeds(o, cfg, B, &pos, &neg);
  pos = pos.to(f32);
  if (neg.defined()) neg = neg.to(f32);
  const bool use_cfg = neg.defined() && o.guidance != 1.0;
  at::Tensor text = use_cfg ? at::cat({neg, pos}, 0) : pos;
  at::Tensor image_in = use_cfg ? at::cat({image, image}, 0) : image;
  at::Tensor cond_in = use_cfg ? at::cat({cond, cond}, 0) : cond;

  ScheduleConfig sc;
  const std::vector<double> ab = AlphasCumprod(sc);
  const std::vector<int64_t> ts = InferenceTimesteps(sc, o.steps);
  const int64_t stride = sc.num_train_timesteps / o.steps;
  at::Generator gen = at::make_generator<at::CPUGeneratorImpl>(o.seed);
  // init_noise_sigma = 1; drawn on the CPU (same numbers on every device).
  at::Tensor x = at::randn({B, F, C, H, W}, gen, at::kFloat).to(f32);
  at::Tensor old_x0;
  for (size_t i = 0; i < ts.size(); ++i) {
    const int64_t t = ts[i];
    at::Tensor x_in = use_cfg ? at::cat({x, x}, 0) : x;
    at::Tensor tt = at::full({x_in.size(0)}, static_cast<double>(t), f32);
    std::vector<at::Tensor> res =
        BranchForward(cfg, branch, x_in, cond_in, text, tt, fwd);
    at::Tensor v = BackboneForward(cfg, backbone, at::cat({x_in, image_in}, 2),
                                   text, tt, res, fwd)
                       .to(at::kFloat);
    if (use_cfg) {
      const double g = o.dynamic_cfg
                           ? DynamicGuidanceScale(o.guidance, o.steps, t)
                           : o.guidance;
      v = ClassifierFreeGuidance(v, g);
    }
    const int64_t prev_t = t - stride;
    const double at_ = AlphaBarAt(ab, sc, t), ap = AlphaBarAt(ab, sc, prev_t);
    if (o.scheduler == "ddim") {
      x = DdimStep(v, x, at_, ap);
    } else {
      const double aback = i > 0 ? AlphaBarAt(ab, sc, ts[i - 1]) : -1.0;
      at::Tensor x0;
      x = DpmStep(v, old_x0, x, at_, ap, aback, prev_t >= 0, gen, &x0);
      old_x0 = x0;
    }
    if (o.progress) {
      const double el = std::chrono::duration<double>(
                            std::chrono::steady_clock::now() - start)
                            .count();
      DrawProgress(static_cast<int>(i + 1), static_cast<int>(ts.size()), t, el);
    }
  }
  CheckFinite(x, "sampled latents");
  SaveSafetensors(o.out, {{"latents", x.cpu()}},
                  {{"config", cfg.name},
                   {"device", o.runtime.device.ToString()},
                   {"dtype", DtypeName(o.runtime.dtype)},
                   {"attention",
                    AttentionBackendName(ResolveAttentionBackend(o.attention))},
                   {"seed", std::to_string(o.seed)},
                   {"steps", std::to_string(o.steps)},
                   {"scheduler", o.scheduler},
                   {"guidance", std::to_string(use_cfg ? o.guidance : 1.0)}});
  SampleResult r;
  r.out = o.out;
  r.steps = o.steps;
  r.guidance_used = use_cfg;
  r.runtime = o.runtime.BriefReport();
  r.weight_bytes = backbone.Bytes() + branch.Bytes();
  r.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  return r;
}

std::string InitWeightsFile(const InitWeightsOptions& o) {
  o.Check();
  c10::InferenceMode guard;
  if (o.vae) {
    const VaeConfig vc = VaePreset(o.config);
    const Weights w = VaeInitWeights(vc, o.seed);
    std::vector<std::pair<std::string, at::Tensor>> all;
    AppendForSave(w, "", &all);
    SaveSafetensors(o.out, all,
                    {{"config", vc.name}, {"seed", std::to_string(o.seed)}});
    std::ostringstream os;
    os << "wrote " << all.size() << " tensors ("
       << NumElements(VaeParamSpecs(vc)) << " parameters, VAE " << vc.name
       << ") to " << o.out;
    return os.str();
  }
  const DiTConfig cfg = ConfigPreset(o.config);
  const std::vector<ParamSpec> specs = BackboneParamSpecs(cfg);
  const int64_t n = NumElements(specs) +
                    (o.with_branch ? NumElements(BranchParamSpecs(cfg)) : 0);
  GEODRIVE_CHECK_INPUT(
      o.allow_large || n <= 1000000000, "init-weights: '", cfg.name, "' has ",
      n, " parameters (", n * 4 / 1e9,
      " GB in float32); pass --allow-large to write it anyway");
  Weights backbone = InitWeights(specs, o.seed);
  std::vector<std::pair<std::string, at::Tensor>> all;
  AppendForSave(backbone, "", &all);
  if (o.with_branch) {
    Weights branch = InitBranchFromBackbone(cfg, backbone, o.seed + 1);
    if (o.nonzero_branch) {
      at::Generator gen = at::make_generator<at::CPUGeneratorImpl>(o.seed + 2);
      for (int k = 0; k < cfg.branch_layers; ++k) {
        const std::string b = "branch_blocks." + std::to_string(k);
        branch.Set(b + ".weight",
                   at::randn(branch.Get(b + ".weight").sizes(), gen) * 0.1);
        branch.Set(b + ".bias",
                   at::randn(branch.Get(b + ".bias").sizes(), gen) * 0.02);
      }
    }
    AppendForSave(branch, "branch.", &all);
  }
  SaveSafetensors(o.out, all,
                  {{"config", cfg.name}, {"seed", std::to_string(o.seed)}});
  std::ostringstream os;
  os << "wrote " << all.size() << " tensors (" << n << " parameters, config "
     << cfg.name << ") to " << o.out;
  return os.str();
}

std::string CheckWeights(const std::string& config,
                         const std::string& weights,
                         const std::string& branch_weights,
                         bool* ok,
                         const RuntimeOptions& runtime) {
  runtime.Check();
  const DiTConfig cfg = ConfigPreset(config);
  std::set<std::string> stored_dtypes;
  auto compare = [&](const std::string& path,
                     const std::vector<ParamSpec>& specs,
                     const std::string& prefix) {
    SafetensorsCheckpoint ckpt(path);
    std::vector<ParamSpec> in_file;
    for (const auto& e : ckpt.entries()) {
      if (e.name.rfind(prefix, 0) != 0) continue;
      if (prefix.empty() && e.name.rfind("branch.", 0) == 0) continue;
      in_file.push_back({e.name.substr(prefix.size()), e.shape});
      stored_dtypes.insert(e.dtype);
    }
    return CompareStateDict(path + (prefix.empty() ? "" : " [" + prefix + "*]"),
                            specs, in_file);
  };
  std::ostringstream os;
  LoadReport r = compare(weights, BackboneParamSpecs(cfg), "");
  *ok = r.ok();
  os << "backbone " << r.BriefReport();
  std::string bpath = branch_weights, prefix;
  if (bpath.empty() && HasPrefix(weights, "branch.")) {
    bpath = weights;
    prefix = "branch.";
  }
  int64_t params = NumElements(BackboneParamSpecs(cfg));
  if (!bpath.empty()) {
    LoadReport b = compare(bpath, BranchParamSpecs(cfg), prefix);
    *ok = *ok && b.ok();
    os << "\nencoder " << b.BriefReport();
    params += NumElements(BranchParamSpecs(cfg));
  }
  // What loading would take: stored dtypes, and the weights' size in the
  // compute dtype on the device (a checkpoint in that dtype is not converted).
  os << "\nstored as";
  for (const auto& d : stored_dtypes) os << " " << d;
  os << "; " << params << " parameters = "
     << static_cast<double>(params) * DtypeBytes(runtime.dtype) / 1e9
     << " GB in " << DtypeName(runtime.dtype) << " on "
     << runtime.device.ToString();
  if (runtime.offload_backbone && runtime.device.is_cuda()) {
    int64_t per_block = 0;
    for (const auto& spec : BackboneParamSpecs(cfg)) {
      if (spec.name.rfind("transformer_blocks.0.", 0) == 0)
        per_block += NumElements(spec.shape);
    }
    os << " (offload: "
       << static_cast<double>(per_block) * DtypeBytes(runtime.dtype) / 1e9
       << " GB per block on the device at a time)";
  }
  return os.str();
}

}  // namespace diffusion
}  // namespace geodrive

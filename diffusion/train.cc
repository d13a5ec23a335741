#include "diffusion/train.h"

#include <ATen/ATen.h>
#include <ATen/CPUGeneratorImpl.h>
#include <torch/csrc/autograd/autograd.h>
#include <torch/csrc/autograd/custom_function.h>
#include <torch/optim/adamw.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "diffusion/config.h"
#include "diffusion/pairs_loader.h"
#include "diffusion/runtime_torch.h"
#include "diffusion/safetensors.h"
#include "diffusion/schedule.h"
#include "diffusion/vae.h"
#include "diffusion/vae_config.h"
#include "geometry/util/files.h"
#include "geometry/util/output_file.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace diffusion {

namespace fs = std::filesystem;

namespace {

constexpr const char* kStateFormat = "geodrive-branch-train-state-v1";
constexpr const char* kBranchFile =
    "branch/diffusion_pytorch_model.safetensors";
constexpr const char* kStateFile = "training_state.safetensors";

bool IsTinyPreset(const std::string& name) {
  return name.rfind("tiny", 0) == 0;
}

bool HasPrefixedTensors(const std::string& path, const std::string& prefix) {
  SafetensorsCheckpoint ckpt(path);
  for (const auto& e : ckpt.entries()) {
    if (e.name.rfind(prefix, 0) == 0) return true;
  }
  return false;
}

// RGB CV_32FC3 frames -> [1, 3, F, H, W] float32.
at::Tensor FramesToTensor(const std::vector<cv::Mat>& frames) {
  const int64_t F = static_cast<int64_t>(frames.size());
  const int64_t H = frames[0].rows, W = frames[0].cols;
  at::Tensor t = at::empty({F, H, W, 3}, at::kFloat);
  for (int64_t f = 0; f < F; ++f) {
    const cv::Mat& m = frames[static_cast<size_t>(f)];
    TORCH_CHECK(m.isContinuous() && m.type() == CV_32FC3);
    std::memcpy(t[f].data_ptr<float>(), m.ptr<float>(),
                static_cast<size_t>(H * W * 3) * sizeof(float));
  }
  return t.permute({3, 0, 1, 2}).unsqueeze(0).contiguous();
}

// One pair's model inputs: scaled latents [F', C, h, w] and the first frame
// [3, 1, H, W] in pixels (for image-noise augmentation).
struct PairLatents {
  at::Tensor gt, cond, image, first_frame;
};

// The backward of a checkpointed function (the encoder, a backbone block):
// recomputes `run` with grad enabled from detached copies of the saved inputs
// and returns the gradients of the inputs that required them, at index 1 + i
// (index 0 is the Function's spec pointer, which has none).
torch::autograd::variable_list RecomputeInputGrads(
    const torch::autograd::variable_list& saved,
    const torch::autograd::variable_list& grad_outputs,
    const std::function<
        std::vector<at::Tensor>(const std::vector<at::Tensor>&)>& run) {
  std::vector<at::Tensor> leaves, wrt;
  std::vector<size_t> wrt_index;
  for (size_t i = 0; i < saved.size(); ++i) {
    at::Tensor leaf = saved[i].detach();
    if (saved[i].requires_grad()) {
      leaf.requires_grad_(true);
      wrt.push_back(leaf);
      wrt_index.push_back(i);
    }
    leaves.push_back(leaf);
  }
  std::vector<at::Tensor> outputs;
  {
    at::AutoGradMode enable(true);
    outputs = run(leaves);
  }
  std::vector<at::Tensor> used_out, used_grad;
  for (size_t k = 0; k < outputs.size(); ++k) {
    if (!grad_outputs[k].defined() || !outputs[k].requires_grad()) continue;
    used_out.push_back(outputs[k]);
    used_grad.push_back(grad_outputs[k]);
  }
  torch::autograd::variable_list grads(saved.size() + 1);
  if (wrt.empty() || used_out.empty()) return grads;
  const torch::autograd::variable_list g =
      torch::autograd::grad(used_out, wrt, used_grad, /*retain_graph=*/false,
                            /*create_graph=*/false, /*allow_unused=*/true);
  for (size_t j = 0; j < wrt_index.size(); ++j) grads[1 + wrt_index[j]] = g[j];
  return grads;
}

// The encoder's custom autograd Function (gradient checkpointing).
struct BranchCheckpointSpec {
  const DiTConfig* config;
  const ForwardOptions* options;
  std::vector<std::string> names;  // branch parameter names (inputs 4..)
  std::vector<at::Tensor> extra;   // tensors of the branch not passed as inputs
  std::vector<std::string> extra_names;
};

std::vector<at::Tensor> RunBranch(const BranchCheckpointSpec& spec,
                                  at::TensorList inputs) {
  Weights w;
  for (size_t i = 0; i < spec.names.size(); ++i)
    w.tensors[spec.names[i]] = inputs[4 + i];
  for (size_t i = 0; i < spec.extra_names.size(); ++i)
    w.tensors[spec.extra_names[i]] = spec.extra[i];
  return BranchForward(*spec.config, w, inputs[0], inputs[1], inputs[2],
                       inputs[3], *spec.options);
}

struct BranchCheckpointFunction
    : public torch::autograd::Function<BranchCheckpointFunction> {
  // inputs: noisy, cond, text, timesteps, then the branch parameters.
  static torch::autograd::variable_list forward(
      torch::autograd::AutogradContext* ctx,
      const BranchCheckpointSpec* spec,
      at::TensorList inputs) {
    // Runs with grad mode off (Function::apply): no activations are kept.
    ctx->saved_data["spec"] = reinterpret_cast<int64_t>(spec);
    ctx->save_for_backward(inputs.vec());
    return RunBranch(*spec, inputs);
  }

  static torch::autograd::variable_list backward(
      torch::autograd::AutogradContext* ctx,
      torch::autograd::variable_list grad_outputs) {
    const auto* spec = reinterpret_cast<const BranchCheckpointSpec*>(
        ctx->saved_data["spec"].toInt());
    return RecomputeInputGrads(ctx->get_saved_variables(), grad_outputs,
                               [spec](const std::vector<at::Tensor>& in) {
                                 return RunBranch(*spec, in);
                               });
  }
};

// Gradient checkpointing of one backbone block (ForwardOptions::
// block_forward): the forward keeps only the block's inputs; backward
// recomputes the block with grad enabled and differentiates it. The backbone's
// weights are frozen, so the gradients are those of the activations.
struct BlockCheckpointSpec {
  DiTConfig config;
  const Weights* weights;  // the block's weights (outlive the step)
  Weights owned;           // ... or a copy made by the offload path
  std::string prefix;
  RotaryTables rope;
  ForwardOptions options;  // without block_forward
};

struct BlockCheckpointFunction
    : public torch::autograd::Function<BlockCheckpointFunction> {
  static torch::autograd::variable_list forward(
      torch::autograd::AutogradContext* ctx,
      const BlockCheckpointSpec* spec,
      const at::Tensor& video,
      const at::Tensor& text,
      const at::Tensor& temb) {
    ctx->saved_data["spec"] = reinterpret_cast<int64_t>(spec);
    ctx->save_for_backward({video, text, temb});
    at::Tensor v = video, t = text;
    BlockForward(spec->config, *spec->weights, spec->prefix, temb, spec->rope,
                 spec->options, &v, &t);
    return {v, t};
  }

  static torch::autograd::variable_list backward(
      torch::autograd::AutogradContext* ctx,
      torch::autograd::variable_list grad_outputs) {
    const auto* spec = reinterpret_cast<const BlockCheckpointSpec*>(
        ctx->saved_data["spec"].toInt());
    // saved: video, text, temb.
    return RecomputeInputGrads(ctx->get_saved_variables(), grad_outputs,
                               [spec](const std::vector<at::Tensor>& in) {
                                 at::Tensor v = in[0], t = in[1];
                                 BlockForward(spec->config, *spec->weights,
                                              spec->prefix, in[2], spec->rope,
                                              spec->options, &v, &t);
                                 return std::vector<at::Tensor>{v, t};
                               });
  }
};

}  // namespace

void CheckpointedBlockForward(const DiTConfig& config,
                              const Weights& w,
                              const std::string& prefix,
                              const at::Tensor& temb,
                              const RotaryTables& rope,
                              const ForwardOptions& options,
                              at::Tensor* video,
                              at::Tensor* text) {
  if (!at::GradMode::is_enabled() ||
      !(video->requires_grad() || text->requires_grad() ||
        temb.requires_grad())) {
    BlockForward(config, w, prefix, temb, rope, options, video, text);
    return;
  }
  auto spec = std::make_shared<BlockCheckpointSpec>();
  spec->config = config;
  spec->owned = w.Subset(prefix);  // shares the tensors; outlives the step
  spec->weights = &spec->owned;
  spec->prefix = prefix;
  spec->rope = rope;
  spec->options = options;
  spec->options.block_forward = nullptr;
  torch::autograd::variable_list out =
      BlockCheckpointFunction::apply(spec.get(), *video, *text, temb);
  // The autograd node holds a raw pointer: tie the spec's lifetime to the
  // outputs' graph with a no-op hook that owns it.
  for (auto& o : out) {
    if (o.requires_grad()) o.register_hook([spec](at::Tensor g) { return g; });
  }
  *video = out[0];
  *text = out[1];
}

namespace {

std::string FormatDouble(double v) {
  if (!std::isfinite(v)) return "";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.9g", v);
  return buf;
}

}  // namespace

double ClipGradNorm(const std::vector<at::Tensor>& params, double max_norm) {
  std::vector<at::Tensor> norms;
  for (const auto& p : params) {
    if (p.grad().defined()) norms.push_back(p.grad().norm(2));
  }
  if (norms.empty()) return 0.0;
  const double total = at::stack(norms).norm(2).item<double>();
  const double coef = max_norm / (total + 1e-6);
  if (max_norm > 0 && coef < 1) {
    for (const auto& p : params) {
      if (p.grad().defined()) p.grad().mul_(coef);
    }
  }
  return total;
}

std::vector<at::Tensor> CheckpointedBranchForward(
    const DiTConfig& config,
    const Weights& branch,
    const at::Tensor& noisy,
    const at::Tensor& cond,
    const at::Tensor& text,
    const at::Tensor& timesteps,
    const ForwardOptions& options) {
  BranchCheckpointSpec spec;
  spec.config = &config;
  spec.options = &options;
  std::vector<at::Tensor> inputs = {noisy, cond, text, timesteps};
  for (const auto& name : branch.order) {
    const at::Tensor& t = branch.Get(name);
    if (t.requires_grad()) {
      spec.names.push_back(name);
      inputs.push_back(t);
    } else {
      spec.extra_names.push_back(name);
      spec.extra.push_back(t);
    }
  }
  // `spec` lives on this stack frame, but backward runs later: keep it alive
  // with the graph by moving it to the heap, owned by a shared_ptr captured in
  // the returned tensors' lifetime via the context (see below).
  auto owned = std::make_shared<BranchCheckpointSpec>(std::move(spec));
  std::vector<at::Tensor> out =
      BranchCheckpointFunction::apply(owned.get(), at::TensorList(inputs));
  // The autograd node holds only a raw pointer; tie the spec's lifetime to the
  // outputs' grad_fn with a no-op hook holding the shared_ptr.
  for (auto& o : out) {
    if (o.requires_grad()) {
      o.register_hook([owned](at::Tensor g) { return g; });
    }
  }
  return out;
}

void TrainOptions::Check() const {
  GEODRIVE_CHECK_INPUT(!pairs.empty(), "--pairs is required");
  GEODRIVE_CHECK_INPUT(!out.empty(), "--out is required");
  GEODRIVE_CHECK_INPUT(steps >= 0 && steps <= 100000000,
                       "--steps must be in [0, 1e8], got ", steps);
  GEODRIVE_CHECK_INPUT(batch >= 1 && batch <= 1024,
                       "--batch must be in [1, 1024], got ", batch);
  GEODRIVE_CHECK_INPUT(std::isfinite(lr) && lr > 0 && lr < 1,
                       "--lr must be in (0, 1), got ", lr);
  GEODRIVE_CHECK_INPUT(std::isfinite(weight_decay) && weight_decay >= 0,
                       "--weight-decay must be >= 0");
  GEODRIVE_CHECK_INPUT(
      beta1 >= 0 && beta1 < 1 && beta2 >= 0 && beta2 < 1 && adam_eps > 0,
      "AdamW betas must be in [0, 1) and eps > 0");
  GEODRIVE_CHECK_INPUT(std::isfinite(max_grad_norm),
                       "--max-grad-norm must be finite");
  GEODRIVE_CHECK_INPUT(warmup_steps >= 0, "--warmup-steps must be >= 0");
  GEODRIVE_CHECK_INPUT(val_every >= 1, "--val-every must be >= 1");
  GEODRIVE_CHECK_INPUT(val_timesteps >= 1 && val_timesteps <= 1000,
                       "--val-timesteps must be in [1, 1000]");
  GEODRIVE_CHECK_INPUT(checkpoint_every >= 0,
                       "--checkpoint-every must be >= 0");
  GEODRIVE_CHECK_INPUT(prefetch >= 1 && prefetch <= 1024,
                       "--prefetch must be in [1, 1024]");
  GEODRIVE_CHECK_INPUT(
      image_dropout >= 0 && image_dropout <= 1 && image_noise_log_std >= 0,
      "image dropout must be in [0, 1], noise std >= 0");
  GEODRIVE_CHECK_INPUT(attention_chunk_mb >= 1 && ff_token_chunk >= 1,
                       "chunk sizes must be positive");
}

std::string TrainResult::BriefReport() const {
  std::ostringstream os;
  os << "trained steps " << start_step << " -> " << end_step << " in "
     << seconds << " s";
  if (first_val_loss && last_val_loss) {
    os << "; validation loss " << *first_val_loss << " -> " << *last_val_loss;
  }
  if (!last_checkpoint.empty()) os << "; checkpoint " << last_checkpoint;
  return os.str();
}

struct Trainer::Impl {
  TrainOptions o;
  DiTConfig cfg;
  VaeConfig vae_cfg;
  ForwardOptions fwd;
  Weights backbone, branch, vae;
  std::vector<std::string> trained;  // branch names that train
  std::vector<at::Tensor> params;
  std::unique_ptr<torch::optim::AdamW> opt;
  at::Generator gen;
  std::vector<double> alphas_cumprod;
  at::Tensor text;  // [1, L, D]
  int64_t step = 0;
  double last_grad_norm = 0;
  int pixel_frames = 0, pixel_height = 0, pixel_width = 0;
  // Data.
  std::vector<PairLatents> train_cache;  // cache_latents
  int64_t num_train = 0;
  std::unique_ptr<PairsLoader> stream;  // !cache_latents
  std::vector<PairLatents> val;

  PairsLoaderOptions LoaderOptions(const std::string& manifest) const {
    PairsLoaderOptions lo;
    lo.manifest = manifest;
    lo.frames = pixel_frames;
    lo.width = pixel_width;
    lo.height = pixel_height;
    lo.seed = o.seed;
    lo.prefetch = o.prefetch;
    return lo;
  }

  at::Tensor EncodeVideo(const at::Tensor& video) const {
    // [B, 3, F, H, W] -> scaled latents [B, F', C, h, w], float32 on the CPU
    // (the VAE runs on the device in its dtype).
    at::NoGradGuard no_grad;
    return (VaeEncode(vae_cfg, vae, video).to(at::kFloat).cpu() *
            vae_cfg.scaling_factor)
        .permute({0, 2, 1, 3, 4})
        .contiguous();
  }

  // Float32 on the compute device (the step's data, drawn on the CPU).
  at::Tensor OnDevice(const at::Tensor& t) const {
    return t.to(ComputeOptions(o.runtime.device, ComputeDtype::kFloat32));
  }

  PairLatents Encode(const PairSample& s) const {
    PairLatents p;
    const at::Tensor gt = FramesToTensor(s.gt);
    p.gt = EncodeVideo(gt)[0];
    p.cond = EncodeVideo(FramesToTensor(s.cond))[0];
    p.first_frame = gt[0].narrow(1, 0, 1).contiguous();    // [3, 1, H, W]
    p.image = EncodeVideo(p.first_frame.unsqueeze(0))[0];  // [1, C, h, w]
    return p;
  }

  std::vector<PairLatents> EncodeAll(const std::string& manifest) {
    PairsLoaderOptions lo = LoaderOptions(manifest);
    lo.shuffle = false;
    lo.num_samples = static_cast<int64_t>(ReadManifest(manifest).size());
    PairsLoader loader(lo);
    std::vector<PairLatents> out;
    PairSample s;
    while (static_cast<int64_t>(out.size()) < loader.size() &&
           loader.Next(&s)) {
      out.push_back(Encode(s));
    }
    return out;
  }

  double LrAt(int64_t s) const {
    if (o.warmup_steps <= 0 || s >= o.warmup_steps) return o.lr;
    return o.lr * static_cast<double>(s + 1) /
           static_cast<double>(o.warmup_steps);
  }

  at::Tensor AlphaBar(const at::Tensor& t) const {
    at::Tensor table = at::tensor(alphas_cumprod, at::kDouble);
    return OnDevice(table.index_select(0, t.cpu()));
  }

  // v-prediction MSE of the model at (x0, eps, t); latents [B, F', C, h, w].
  at::Tensor Loss(const at::Tensor& x0,
                  const at::Tensor& cond,
                  const at::Tensor& image,
                  const at::Tensor& eps,
                  const at::Tensor& t,
                  bool checkpointing) const {
    // Inputs and the loss in float32 on the device; the networks in their
    // dtypes. The encoder's float32 master weights are cast to the compute
    // dtype differentiably (shared, not copied, in float32).
    const int64_t B = x0.size(0);
    const at::Tensor ab = AlphaBar(t).view({B, 1, 1, 1, 1});
    const at::Tensor sa = ab.sqrt(), sb = (1 - ab).sqrt();
    const at::Tensor x0d = OnDevice(x0), epsd = OnDevice(eps);
    const at::Tensor xt = sa * x0d + sb * epsd;
    const at::Tensor v = sa * epsd - sb * x0d;
    const at::Tensor tf = OnDevice(t);
    const at::Tensor td = OnDevice(text);
    const at::Tensor txt = td.expand({B, td.size(1), td.size(2)});
    const at::Tensor condd = OnDevice(cond);
    const Weights enc =
        branch.To(ComputeOptions(o.runtime.device, o.runtime.dtype));
    ForwardOptions backbone_fwd = fwd;
    if (checkpointing) backbone_fwd.block_forward = CheckpointedBlockForward;
    const std::vector<at::Tensor> res =
        checkpointing
            ? CheckpointedBranchForward(cfg, enc, xt, condd, txt, tf, fwd)
            : BranchForward(cfg, enc, xt, condd, txt, tf, fwd);
    const at::Tensor pred =
        BackboneForward(cfg, backbone, at::cat({xt, OnDevice(image)}, 2), txt,
                        tf, res, backbone_fwd);
    return (pred.to(at::kFloat) - v).pow(2).mean();
  }

  // Restores the optimiser moments, the step and the generator's state of a
  // checkpoint-<step>/ folder (its training_state.safetensors).
  void RestoreState(const std::string& dir) {
    const std::string path = dir + "/" + kStateFile;
    SafetensorsFile st(path);
    const auto fmt = st.metadata().find("format");
    GEODRIVE_CHECK_INPUT(
        fmt != st.metadata().end() && fmt->second == kStateFormat, path,
        ": not a ", kStateFormat, " file");
    const auto cfg_it = st.metadata().find("config");
    GEODRIVE_CHECK_INPUT(
        cfg_it != st.metadata().end() && cfg_it->second == cfg.name, path,
        ": written for config '",
        cfg_it == st.metadata().end() ? "" : cfg_it->second, "', not '",
        cfg.name, "'");
    GEODRIVE_CHECK_INPUT(st.Has("global_step") && st.Has("rng_state"), path,
                         ": lacks global_step or rng_state");
    step = st.Load("global_step").item<int64_t>();
    GEODRIVE_CHECK_INPUT(step >= 0, path, ": negative global_step");
    gen.set_state(st.Load("rng_state"));
    for (size_t i = 0; i < trained.size(); ++i) {
      const std::string& name = trained[i];
      if (!st.Has("exp_avg." + name)) continue;  // never stepped
      GEODRIVE_CHECK_INPUT(
          st.Has("exp_avg_sq." + name) && st.Has("adam_step." + name), path,
          ": incomplete optimizer state for '", name, "'");
      at::Tensor ea = OnDevice(st.Load("exp_avg." + name));
      at::Tensor eas = OnDevice(st.Load("exp_avg_sq." + name));
      GEODRIVE_CHECK_INPUT(
          ea.sizes() == params[i].sizes() && eas.sizes() == params[i].sizes(),
          path, ": optimizer state of '", name, "' has the wrong shape");
      auto state = std::make_unique<torch::optim::AdamWParamState>();
      state->step(st.Load("adam_step." + name).item<int64_t>());
      state->exp_avg(ea);
      state->exp_avg_sq(eas);
      opt->state()[c10::guts::to_string(params[i].unsafeGetTensorImpl())] =
          std::move(state);
    }
  }

  // Image latent padded with zeros to F' frames: [B, F', C, h, w].
  at::Tensor PadImage(const at::Tensor& image, int64_t frames) const {
    const int64_t B = image.size(0);
    return at::cat({image, at::zeros({B, frames - image.size(1), image.size(2),
                                      image.size(3), image.size(4)})},
                   1);
  }
};

Trainer::Trainer(const TrainOptions& options) : impl_(new Impl) {
  Impl& m = *impl_;
  m.o = options;
  m.o.Check();
  m.cfg = ConfigPreset(m.o.config);
  m.cfg.Check();
  m.vae_cfg = VaePreset(VaePresetNameForConfig(m.cfg.name));
  GEODRIVE_CHECK_INPUT(m.vae_cfg.latent_channels == m.cfg.out_channels,
                       "config '", m.cfg.name, "': VAE '", m.vae_cfg.name,
                       "' has ", m.vae_cfg.latent_channels,
                       " latent channels, the DiT ", m.cfg.out_channels);
  GEODRIVE_CHECK_INPUT(m.cfg.in_channels == 2 * m.cfg.out_channels &&
                           m.cfg.branch_in_channels == 2 * m.cfg.out_channels,
                       "config '", m.cfg.name,
                       "' does not take [latent, image] channel pairs");
  m.fwd.attention_chunk_bytes = m.o.attention_chunk_mb << 20;
  m.fwd.ff_token_chunk = m.o.ff_token_chunk;
  m.fwd.attention = m.o.attention;
  m.o.runtime.Check();
  // Frozen networks in their compute dtypes on the device; the trained
  // encoder's master weights in float32 there.
  WeightPlacement backbone_place, vae_place, branch_place;
  backbone_place.device = vae_place.device = branch_place.device =
      m.o.runtime.device;
  backbone_place.dtype = m.o.runtime.dtype;
  vae_place.dtype = m.o.runtime.vae_dtype;
  m.pixel_frames = static_cast<int>(m.vae_cfg.PixelFrames(m.cfg.latent_frames));
  m.pixel_height = m.cfg.latent_height * m.vae_cfg.spatial_compression;
  m.pixel_width = m.cfg.latent_width * m.vae_cfg.spatial_compression;

  // Weights. Random ones only for the tiny presets (tests, demos).
  const bool tiny = IsTinyPreset(m.cfg.name);
  GEODRIVE_CHECK_INPUT(tiny || !m.o.weights.empty(),
                       "--weights is required for config '", m.cfg.name, "'");
  GEODRIVE_CHECK_INPUT(tiny || !m.o.vae_weights.empty(),
                       "--vae-weights is required for config '", m.cfg.name,
                       "'");
  LoadReport report;
  if (m.o.weights.empty()) {
    m.backbone =
        InitWeights(BackboneParamSpecs(m.cfg), m.o.seed, backbone_place);
  } else {
    m.backbone = LoadWeights(m.o.weights, BackboneParamSpecs(m.cfg), "", true,
                             &report, backbone_place);
  }
  m.vae = m.o.vae_weights.empty()
              ? InitWeights(VaeParamSpecs(m.vae_cfg), m.o.seed + 2, vae_place)
              : LoadWeights(m.o.vae_weights, VaeParamSpecs(m.vae_cfg), "", true,
                            &report, vae_place);
  std::string branch_path, branch_prefix;
  if (!m.o.resume.empty()) {
    branch_path = m.o.resume + "/" + kBranchFile;
  } else if (!m.o.branch_weights.empty()) {
    branch_path = m.o.branch_weights;
  } else if (!m.o.weights.empty() &&
             HasPrefixedTensors(m.o.weights, "branch.")) {
    branch_path = m.o.weights;
    branch_prefix = "branch.";
  }
  if (branch_path.empty()) {
    m.branch =
        InitBranchFromBackbone(m.cfg, m.backbone, m.o.seed + 1)
            .To(ComputeOptions(m.o.runtime.device, ComputeDtype::kFloat32));
  } else {
    m.branch = LoadWeights(branch_path, BranchParamSpecs(m.cfg), branch_prefix,
                           false, &report, branch_place);
    CheckBranchLoadReport(report);
  }
  // Frozen: backbone and VAE. Trained: the encoder's used tensors.
  m.backbone.SetRequiresGrad(false);
  m.vae.SetRequiresGrad(false);
  m.branch.SetRequiresGrad(false);
  for (const auto& name : m.branch.order) {
    if (IsUnusedBranchParam(name)) continue;
    m.branch.tensors[name].requires_grad_(true);
    m.trained.push_back(name);
    m.params.push_back(m.branch.Get(name));
  }
  m.opt = std::make_unique<torch::optim::AdamW>(
      m.params, torch::optim::AdamWOptions(m.o.lr)
                    .betas({m.o.beta1, m.o.beta2})
                    .eps(m.o.adam_eps)
                    .weight_decay(m.o.weight_decay));
  m.gen = at::make_generator<at::CPUGeneratorImpl>(m.o.seed);
  m.alphas_cumprod = AlphasCumprod(ScheduleConfig{});

  if (!m.o.prompt_embeds.empty()) {
    SafetensorsCheckpoint pe(m.o.prompt_embeds);
    GEODRIVE_CHECK_INPUT(pe.Has("prompt_embeds"), m.o.prompt_embeds,
                         ": needs a tensor 'prompt_embeds' [1, L, ",
                         m.cfg.text_embed_dim, "]");
    m.text = pe.Load("prompt_embeds").to(at::kFloat);
    GEODRIVE_CHECK_INPUT(m.text.dim() == 3 && m.text.size(0) == 1 &&
                             m.text.size(2) == m.cfg.text_embed_dim &&
                             at::isfinite(m.text).all().item<bool>(),
                         m.o.prompt_embeds,
                         ": prompt_embeds must be finite [1, L, ",
                         m.cfg.text_embed_dim, "]");
  } else {
    m.text = at::zeros({1, m.cfg.text_seq_len, m.cfg.text_embed_dim});
  }

  // Resume: optimizer moments, step, RNG.
  if (!m.o.resume.empty()) m.RestoreState(m.o.resume);

  // Data.
  if (m.o.cache_latents) {
    m.train_cache = m.EncodeAll(m.o.pairs);
    m.num_train = static_cast<int64_t>(m.train_cache.size());
  } else {
    PairsLoaderOptions lo = m.LoaderOptions(m.o.pairs);
    lo.start_sample = m.step * m.o.batch;
    m.stream = std::make_unique<PairsLoader>(lo);
    m.num_train = m.stream->size();
  }
  if (!m.o.val_pairs.empty()) m.val = m.EncodeAll(m.o.val_pairs);
}

Trainer::~Trainer() = default;

double Trainer::Step() {
  Impl& m = *impl_;
  const int64_t B = m.o.batch;
  std::vector<at::Tensor> x0s, conds, images, firsts;
  for (int64_t j = 0; j < B; ++j) {
    if (m.o.cache_latents) {
      const int64_t k = m.step * B + j;
      const std::vector<int64_t> order =
          EpochOrder(m.num_train, m.o.seed, k / m.num_train, true);
      const PairLatents& p =
          m.train_cache[static_cast<size_t>(order[k % m.num_train])];
      x0s.push_back(p.gt);
      conds.push_back(p.cond);
      images.push_back(p.image);
      firsts.push_back(p.first_frame);
    } else {
      PairSample s;
      TORCH_CHECK(m.stream->Next(&s), "pairs stream ended");
      TORCH_CHECK(s.sample == m.step * B + j, "pairs stream out of order");
      PairLatents p = m.Encode(s);
      x0s.push_back(p.gt);
      conds.push_back(p.cond);
      images.push_back(p.image);
      firsts.push_back(p.first_frame);
    }
  }
  const at::Tensor x0 = at::stack(x0s), cond = at::stack(conds);
  at::Tensor image = at::stack(images);  // [B, 1, C, h, w]
  // Random draws, in a fixed order from the one generator.
  if (m.o.image_noise) {
    const at::Tensor sigma = (at::randn({B}, m.gen) * m.o.image_noise_log_std +
                              m.o.image_noise_log_mean)
                                 .exp();
    const at::Tensor frames = at::stack(firsts);  // [B, 3, 1, H, W]
    const at::Tensor noisy =
        frames + sigma.view({B, 1, 1, 1, 1}) * at::randn(frames.sizes(), m.gen);
    image = m.EncodeVideo(noisy);
    const at::Tensor keep =
        (at::rand({B}, m.gen) >= m.o.image_dropout).to(at::kFloat);
    image = image * keep.view({B, 1, 1, 1, 1});
  }
  const at::Tensor t = at::randint(0, 1000, {B}, m.gen, at::kLong);
  const at::Tensor eps = at::randn(x0.sizes(), m.gen);
  const double lr = m.LrAt(m.step);
  for (auto& group : m.opt->param_groups()) {
    static_cast<torch::optim::AdamWOptions&>(group.options()).lr(lr);
  }
  m.opt->zero_grad();
  const at::Tensor loss = m.Loss(x0, cond, m.PadImage(image, x0.size(1)), eps,
                                 t, m.o.grad_checkpointing);
  loss.backward();
  m.last_grad_norm = ClipGradNorm(m.params, m.o.max_grad_norm);
  m.opt->step();
  ++m.step;
  return loss.item<double>();
}

bool Trainer::has_validation() const { return !impl_->val.empty(); }

double Trainer::Validate() {
  Impl& m = *impl_;
  GEODRIVE_CHECK_INPUT(!m.val.empty(), "no validation pairs (--val-pairs)");
  at::NoGradGuard no_grad;
  const int64_t K = m.o.val_timesteps;
  // Timesteps at the centres of K equal bins of [0, 1000).
  std::vector<int64_t> ts;
  for (int64_t i = 0; i < K; ++i) ts.push_back((2 * i + 1) * 1000 / (2 * K));
  const at::Tensor t = at::tensor(ts, at::kLong);
  double total = 0;
  for (size_t i = 0; i < m.val.size(); ++i) {
    const PairLatents& p = m.val[i];
    at::Generator g = at::make_generator<at::CPUGeneratorImpl>(
        0x76616C00ull + static_cast<uint64_t>(i));  // fixed per pair
    const at::Tensor x0 = p.gt.unsqueeze(0).expand({K, -1, -1, -1, -1});
    const at::Tensor cond = p.cond.unsqueeze(0).expand({K, -1, -1, -1, -1});
    const at::Tensor image = m.PadImage(
        p.image.unsqueeze(0).expand({K, -1, -1, -1, -1}), x0.size(1));
    const at::Tensor eps = at::randn(x0.sizes(), g);
    total += m.Loss(x0, cond, image, eps, t, false).item<double>();
  }
  return total / static_cast<double>(m.val.size());
}

void Trainer::SaveCheckpoint(const std::string& final_dir) const {
  const Impl& m = *impl_;
  // Written under a temporary name (removed if the run is interrupted) and
  // renamed when complete: a checkpoint folder is whole or absent.
  const fs::path final_path(final_dir);
  const std::string dir = TemporaryPathFor(final_dir);
  std::error_code ec;
  fs::create_directories(dir + "/branch", ec);
  GEODRIVE_CHECK_INPUT(!ec, dir, ": cannot create (", ec.message(), ")");
  const std::map<std::string, std::string> meta = {
      {"config", m.cfg.name},
      {"global_step", std::to_string(m.step)},
      {"format", kStateFormat}};
  NamedTensors branch;
  {
    at::NoGradGuard no_grad;
    Weights detached;
    detached.order = m.branch.order;
    for (const auto& name : m.branch.order)
      detached.tensors[name] = m.branch.Get(name).detach();
    AppendForSave(detached, "", &branch);
  }
  SaveSafetensors(
      dir + "/" + kBranchFile, branch,
      {{"config", m.cfg.name}, {"global_step", std::to_string(m.step)}});
  NamedTensors state;
  state.emplace_back("global_step", at::scalar_tensor(m.step, at::kLong));
  state.emplace_back("rng_state", m.gen.get_state());
  const auto& st = m.opt->state();
  for (size_t i = 0; i < m.trained.size(); ++i) {
    const auto it =
        st.find(c10::guts::to_string(m.params[i].unsafeGetTensorImpl()));
    if (it == st.end()) continue;
    const auto& s =
        static_cast<const torch::optim::AdamWParamState&>(*it->second);
    const std::string& name = m.trained[i];
    state.emplace_back("adam_step." + name,
                       at::scalar_tensor(s.step(), at::kLong));
    state.emplace_back("exp_avg." + name, s.exp_avg().detach());
    state.emplace_back("exp_avg_sq." + name, s.exp_avg_sq().detach());
  }
  std::map<std::string, std::string> state_meta = meta;
  state_meta["seed"] = std::to_string(m.o.seed);
  state_meta["batch"] = std::to_string(m.o.batch);
  state_meta["weights"] = m.o.weights;
  state_meta["pairs"] = m.o.pairs;
  SaveSafetensors(dir + "/" + kStateFile, state, state_meta);
  // An existing folder of that name is moved aside first and removed once the
  // new one is in place.
  const std::string aside =
      (final_path.parent_path() /
       ("." + final_path.filename().string() + ".replaced"))
          .string();
  const bool replacing = fs::exists(final_dir, ec);
  if (replacing) {
    fs::remove_all(aside, ec);
    fs::rename(final_dir, aside, ec);
    GEODRIVE_CHECK_INPUT(!ec, final_dir, ": cannot move it aside (",
                         ec.message(), ")");
  }
  CommitDirectory(dir, final_dir);
  if (replacing) fs::remove_all(aside, ec);
}

int64_t Trainer::step() const { return impl_->step; }
double Trainer::last_grad_norm() const { return impl_->last_grad_norm; }
double Trainer::CurrentLr() const { return impl_->LrAt(impl_->step); }
const DiTConfig& Trainer::config() const { return impl_->cfg; }
const Weights& Trainer::backbone() const { return impl_->backbone; }
const Weights& Trainer::branch() const { return impl_->branch; }

namespace {

const char* kCsvHeader = "step,loss,val_loss,lr,grad_norm,seconds";

std::string CsvLine(const TrainLogRow& r) {
  std::ostringstream os;
  os << r.step << "," << FormatDouble(r.loss) << ","
     << (r.val_loss ? FormatDouble(*r.val_loss) : "") << ","
     << FormatDouble(r.lr) << "," << FormatDouble(r.grad_norm) << ","
     << FormatDouble(r.seconds);
  return os.str();
}

// Rows of an earlier run's CSV with step <= max_step (resume).
std::vector<TrainLogRow> ReadCsvRows(const std::string& path,
                                     int64_t max_step) {
  std::vector<TrainLogRow> rows;
  std::ifstream in(path);
  std::string line;
  bool header = true;
  while (std::getline(in, line)) {
    if (header) {
      header = false;
      continue;
    }
    std::vector<std::string> f;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) f.push_back(cell);
    while (f.size() < 6) f.emplace_back();
    auto num = [](const std::string& s, double dflt) {
      return s.empty() ? dflt : std::strtod(s.c_str(), nullptr);
    };
    auto optional_num = [](const std::string& s) -> std::optional<double> {
      if (s.empty()) return std::nullopt;
      return std::strtod(s.c_str(), nullptr);
    };
    TrainLogRow r;
    r.step = std::strtoll(f[0].c_str(), nullptr, 10);
    if (r.step > max_step) continue;
    r.loss = num(f[1], std::nan(""));
    r.val_loss = optional_num(f[2]);
    r.lr = num(f[3], 0);
    r.grad_norm = num(f[4], 0);
    r.seconds = num(f[5], 0);
    rows.push_back(r);
  }
  return rows;
}

void WriteLogs(const std::string& out,
               const TrainOptions& o,
               const std::vector<TrainLogRow>& rows) {
  {
    std::ostringstream csv;
    csv << kCsvHeader << "\n";
    for (const auto& r : rows) csv << CsvLine(r) << "\n";
    WriteFileAtomic(out + "/train_log.csv", csv.str());
  }
  nlohmann::json j;
  j["config"] = o.config;
  j["pairs"] = o.pairs;
  j["val_pairs"] = o.val_pairs;
  j["batch"] = o.batch;
  j["lr"] = o.lr;
  j["seed"] = o.seed;
  j["steps"] = o.steps;
  nlohmann::json arr = nlohmann::json::array();
  for (const auto& r : rows) {
    nlohmann::json e;
    e["step"] = r.step;
    e["loss"] = std::isfinite(r.loss) ? nlohmann::json(r.loss) : nullptr;
    e["val_loss"] = r.val_loss ? nlohmann::json(*r.val_loss) : nullptr;
    e["lr"] = r.lr;
    e["grad_norm"] = r.grad_norm;
    e["seconds"] = r.seconds;
    arr.push_back(e);
  }
  j["log"] = arr;
  WriteFileAtomic(out + "/train_log.json", j.dump(1) + "\n");
}

// The progress line. `has_validation`: a validation set was given (then "val"
// shows the latest measured loss, "n/a" before the first); without one the
// line has no "val" field.
void DrawTrainProgress(const TrainLogRow& r,
                       int64_t start,
                       int64_t total,
                       bool has_validation,
                       const std::optional<double>& last_val) {
  const int width = 24;
  const int filled =
      total > 0 ? static_cast<int>(r.step * width / total) : width;
  std::string bar(static_cast<size_t>(filled), '#');
  bar += std::string(static_cast<size_t>(width - filled), '.');
  const int64_t done = r.step - start;
  const double per = done > 0 ? r.seconds / done : 0.0;
  char val[32] = "";
  if (has_validation && last_val) {
    std::snprintf(val, sizeof(val), " val %.4f", *last_val);
  } else if (has_validation) {
    std::snprintf(val, sizeof(val), " val n/a");
  }
  std::fprintf(stderr,
               "\rtrain [%s] %lld/%lld loss %.4f%s lr %.2e %.3f s/step "
               "eta %.0f s   ",
               bar.c_str(), static_cast<long long>(r.step),
               static_cast<long long>(total), r.loss, val, r.lr, per,
               per * static_cast<double>(total - r.step));
  if (r.step == total) std::fprintf(stderr, "\n");
  std::fflush(stderr);
}

// The step of the newest OUT/checkpoint-<step> folder, -1 when there is none.
int64_t LatestCheckpointStep(const std::string& out) {
  int64_t latest = -1;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(out, ec)) {
    const std::string name = e.path().filename().string();
    const std::string prefix = "checkpoint-";
    if (name.rfind(prefix, 0) != 0 || name.size() == prefix.size() ||
        name.size() > prefix.size() + 18 ||
        name.find_first_not_of("0123456789", prefix.size()) !=
            std::string::npos ||
        !e.is_directory(ec)) {
      continue;
    }
    latest = std::max<int64_t>(latest, std::stoll(name.substr(prefix.size())));
  }
  return latest;
}

// The global step a checkpoint folder holds (its state file's metadata), -1
// when it cannot be read (the trainer then reports why).
int64_t CheckpointStep(const std::string& dir) {
  try {
    const SafetensorsFile st(dir + "/" + kStateFile);
    const auto it = st.metadata().find("global_step");
    if (it != st.metadata().end()) return std::stoll(it->second);
  } catch (const std::exception&) {
  }
  return -1;
}

// A run continues the newest checkpoint of its --out, or starts in an --out
// without checkpoints: resuming an earlier one would rewrite the log from its
// step while the later checkpoints stay, and a new run would mix its
// checkpoints with an earlier run's. `step`: the resumed step (-1: new run).
void CheckResumePoint(const TrainOptions& o, int64_t step) {
  const int64_t latest = LatestCheckpointStep(o.out);
  if (latest < 0) return;
  const std::string newest = o.out + "/checkpoint-" + std::to_string(latest);
  GEODRIVE_CHECK_INPUT(!o.resume.empty(), o.out, ": holds ", newest,
                       " of an earlier run: continue it with --resume ", newest,
                       ", or train into another --out");
  GEODRIVE_CHECK_INPUT(step < 0 || latest <= step, "--resume ", o.resume,
                       ": step ", step, ", but ", newest,
                       " is later (resuming would rewrite the log from step ",
                       step, " while the later checkpoints stay): resume from ",
                       newest, ", or remove the later checkpoints");
}

}  // namespace

TrainResult Train(const TrainOptions& o) {
  o.Check();
  const auto start = std::chrono::steady_clock::now();
  auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() -
                                         start)
        .count();
  };
  std::error_code ec;
  fs::create_directories(o.out, ec);
  GEODRIVE_CHECK_INPUT(!ec, o.out, ": cannot create (", ec.message(), ")");
  // One run per output folder: a second one says which pid holds it.
  const ExclusiveLock lock(o.out + "/.lock", o.out + ": output folder");
  CheckResumePoint(o, o.resume.empty() ? -1 : CheckpointStep(o.resume));
  Trainer trainer(o);
  if (!o.resume.empty()) CheckResumePoint(o, trainer.step());
  TrainResult result;
  result.start_step = trainer.step();
  std::vector<TrainLogRow> rows;
  if (!o.resume.empty())
    rows = ReadCsvRows(o.out + "/train_log.csv", trainer.step());
  std::optional<double> last_val;
  if (trainer.has_validation() && o.resume.empty()) {
    TrainLogRow r;
    r.step = trainer.step();
    r.loss = std::nan("");
    r.val_loss = last_val = trainer.Validate();
    r.lr = trainer.CurrentLr();
    r.seconds = elapsed();
    result.first_val_loss = r.val_loss;
    rows.push_back(r);
  } else if (trainer.has_validation()) {
    for (const auto& r : rows) {
      if (r.val_loss && !result.first_val_loss)
        result.first_val_loss = r.val_loss;
      if (r.val_loss) last_val = r.val_loss;
    }
  }
  WriteLogs(o.out, o, rows);
  while (trainer.step() < o.steps) {
    TrainLogRow r;
    r.lr = trainer.CurrentLr();
    r.loss = trainer.Step();
    r.step = trainer.step();
    r.grad_norm = trainer.last_grad_norm();
    GEODRIVE_CHECK_INPUT(std::isfinite(r.loss), "training diverged at step ",
                         r.step, " (loss ", r.loss, ")");
    const bool last = r.step == o.steps;
    if (trainer.has_validation() && (r.step % o.val_every == 0 || last)) {
      r.val_loss = last_val = trainer.Validate();
      if (!result.first_val_loss) result.first_val_loss = r.val_loss;
    }
    r.seconds = elapsed();
    rows.push_back(r);
    const bool ckpt =
        last || (o.checkpoint_every > 0 && r.step % o.checkpoint_every == 0);
    if (ckpt) {
      result.last_checkpoint = o.out + "/checkpoint-" + std::to_string(r.step);
      trainer.SaveCheckpoint(result.last_checkpoint);
    }
    if (ckpt || r.val_loss || r.step % 50 == 0) WriteLogs(o.out, o, rows);
    if (o.progress) {
      DrawTrainProgress(r, result.start_step, o.steps, trainer.has_validation(),
                        last_val);
    }
  }
  WriteLogs(o.out, o, rows);
  result.end_step = trainer.step();
  result.last_val_loss = last_val;
  result.log = rows;
  result.seconds = elapsed();
  return result;
}

}  // namespace diffusion
}  // namespace geodrive

#pragma once
// Training of GeoDrive's condition encoder ("branch") on build-dataset pairs,
// as the upstream recipe (train.py): frozen backbone and VAE, v-prediction MSE
// at uniformly random timesteps, AdamW (betas 0.9/0.95, weight decay 1e-4,
// lr 1e-5), gradient-norm clipping at 1.0, optional gradient checkpointing of
// the encoder. Checkpoints hold the encoder in the released branch naming plus
// the optimizer state, step and RNG state, so a resumed run continues the same
// loss curve. See docs/DIFFUSION.md "Training".

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "diffusion/model.h"
#include "diffusion/runtime.h"

namespace CLI {
class App;
}

namespace geodrive {
namespace diffusion {

struct TrainOptions {
  std::string pairs;            // train manifest.jsonl (geodrive build-dataset)
  std::string val_pairs;        // validation manifest ("" = no validation)
  std::string config = "tiny";  // DiT preset (ConfigPreset)
  // Backbone checkpoint (file or index; a file from init-weights may also hold
  // "branch." tensors, used as the starting encoder). "" = random weights from
  // `seed` (tiny presets only).
  std::string weights;
  std::string branch_weights;  // starting encoder ("" = see `weights`)
  // VAE checkpoint (diffusers vae/ names). "" = random weights from `seed`
  // (tiny presets only: a fixed random projection, enough for tests).
  std::string vae_weights;
  // "prompt_embeds" [1, L, text_dim] (T5 of the training prompt); "" = zeros.
  std::string prompt_embeds;
  std::string out;       // output folder: logs and checkpoint-<step>/
  std::string resume;    // a checkpoint-<step>/ folder to continue from
  int64_t steps = 1000;  // total optimiser steps (a resumed run ends here too)
  int batch = 1;
  double lr = 1e-5;
  double weight_decay = 1e-4;
  double beta1 = 0.9, beta2 = 0.95, adam_eps = 1e-8;
  double max_grad_norm = 1.0;  // <= 0: no clipping
  int64_t warmup_steps = 0;    // linear warm-up, then constant (upstream 1000)
  uint64_t seed = 0;           // data order, noise, timesteps, random weights
  int64_t val_every = 100;     // validation every N steps (and at 0 and end)
  int val_timesteps = 8;       // fixed timesteps per validation pair
  int64_t checkpoint_every = 500;   // 0 = only the final checkpoint
  // Recompute the encoder and every backbone block in backward (each block
  // keeps only its inputs for backward).
  bool grad_checkpointing = false;
  // VAE latents of each pair computed once and kept in memory (exact: the VAE
  // is frozen and the latent mean is used). false = decode and encode the
  // pairs every step, streaming through the prefetch queue.
  bool cache_latents = true;
  int prefetch = 4;
  // Upstream image conditioning noise: the first frame gets Gaussian noise of
  // sigma = exp(N(mean, std)) before encoding; the image latent is dropped
  // (zeroed) with probability image_dropout.
  bool image_noise = true;
  double image_noise_log_mean = -3.0, image_noise_log_std = 0.5;
  double image_dropout = 0.05;
  bool progress = true;  // progress line on stderr
  int64_t attention_chunk_mb = 256;
  int64_t ff_token_chunk = 4096;
  // Attention kernel (ForwardOptions::attention).
  AttentionBackend attention = AttentionBackend::kAuto;
  // Device and dtypes: the frozen backbone in runtime.dtype, the VAE in
  // runtime.vae_dtype, the trained encoder's master weights, its optimiser
  // state and the loss in float32 (the encoder computes in runtime.dtype
  // through a differentiable cast, as mixed-precision training does).
  RuntimeOptions runtime;
  void Check() const;
};

// One row of the loss log.
struct TrainLogRow {
  int64_t step = 0;                // optimiser steps done
  double loss = 0;                 // train loss of this step (NaN for step 0)
  std::optional<double> val_loss;  // empty: not measured at this step
  double lr = 0;
  double grad_norm = 0;  // before clipping
  double seconds = 0;    // since the start of this run
};

struct TrainResult {
  int64_t start_step = 0, end_step = 0;
  // Validation losses of the run (first and last measured); empty without
  // --val-pairs.
  std::optional<double> first_val_loss, last_val_loss;
  std::vector<TrainLogRow> log;
  std::string last_checkpoint;
  double seconds = 0;
  std::string BriefReport() const;
};

// The trainer state; the loop (Train) and the tests drive it step by step.
class Trainer {
 public:
  // Loads the config, weights, VAE and pairs (encoding the latents when
  // cache_latents), or resumes from options.resume. Throws InputError.
  explicit Trainer(const TrainOptions& options);
  ~Trainer();
  Trainer(const Trainer&) = delete;
  Trainer& operator=(const Trainer&) = delete;

  // One optimiser step over `batch` pairs; returns the loss.
  double Step();
  // Validation loss: mean v-MSE over every validation pair at
  // val_timesteps fixed timesteps with fixed noise (deterministic).
  double Validate();
  bool has_validation() const;
  // Writes <dir>/branch/diffusion_pytorch_model.safetensors and
  // <dir>/training_state.safetensors.
  void SaveCheckpoint(const std::string& dir) const;

  int64_t step() const;
  double last_grad_norm() const;
  double CurrentLr() const;
  const DiTConfig& config() const;
  const Weights& backbone() const;
  const Weights& branch() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The whole run: validation at 0 / every val_every / end, checkpoints every
// checkpoint_every and at the end, progress on stderr, <out>/train_log.csv and
// <out>/train_log.json (rewritten after every logged step).
TrainResult Train(const TrainOptions& options);

// The `train` subcommand of geodrive-diffusion (diffusion/train_command.cc):
// registers its options on `app`; when it is chosen, *run is set to the action.
void AddTrainCommand(CLI::App* app, std::function<int()>* run);

// Gradient-norm clipping as torch.nn.utils.clip_grad_norm_ (norm 2): total =
// ||(||g_i||_2)_i||_2 over the defined gradients; when max_norm > 0 and
// max_norm / (total + 1e-6) < 1, every gradient is scaled by that factor.
// Returns the total norm before clipping. (LibTorch's clip_grad.h does not
// compile standalone in 1.13.)
double ClipGradNorm(const std::vector<at::Tensor>& params, double max_norm);

// Gradient checkpointing of the encoder: BranchForward run without keeping
// activations, recomputed in backward (a custom autograd Function; LibTorch
// 1.13's C++ API has no torch.utils.checkpoint). Same values and gradients as
// BranchForward.
std::vector<at::Tensor> CheckpointedBranchForward(
    const DiTConfig& config,
    const Weights& branch,
    const at::Tensor& noisy,
    const at::Tensor& cond,
    const at::Tensor& text,
    const at::Tensor& timesteps,
    const ForwardOptions& options = {});

// BlockForward with gradient checkpointing (ForwardOptions::block_forward):
// keeps only the block's inputs and recomputes it in backward; a plain
// BlockForward when no input needs a gradient.
void CheckpointedBlockForward(const DiTConfig& config,
                              const Weights& w,
                              const std::string& prefix,
                              const at::Tensor& temb,
                              const RotaryTables& rope,
                              const ForwardOptions& options,
                              at::Tensor* video,
                              at::Tensor* text);

}  // namespace diffusion
}  // namespace geodrive

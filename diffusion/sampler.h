#pragma once
// Offline sampling with the frozen backbone + GeoDrive condition encoder,
// test-weight creation and checkpoint checking: the operations behind the
// `geodrive-diffusion` binary. Torch-free header.

#include <cstdint>
#include <string>
#include <vector>

#include "diffusion/runtime.h"

namespace geodrive {
namespace diffusion {

struct SampleOptions {
  std::string config = "tiny";  // preset name (ConfigPreset)
  // Backbone checkpoint: .safetensors or sharded .index.json. A file written by
  // init-weights also holds the encoder under "branch.".
  std::string weights;
  // Encoder checkpoint (diffusers branch/ folder file or index); "" = the
  // "branch." tensors of `weights` if present, else the encoder is initialised
  // from the backbone (zero projections).
  std::string branch_weights;
  std::string latents;       // first-frame image latents [B, 1..F, C, H, W]
                             // (zero-padded to F)
  std::string cond_latents;  // condition-render latents [B, F, C, H, W]
  // "prompt_embeds" [1|B, L, text_dim] and "negative_prompt_embeds" (T5 of "");
  // "" = zero text tokens for both branches and guidance off.
  std::string prompt_embeds;
  std::string out;                // output: "latents" [B, F, C, H, W] float32
  std::string scheduler = "dpm";  // "dpm" (CogVideoXDPMScheduler) | "ddim"
  int steps = 50;
  uint64_t seed = 0;
  double guidance = 6.0;
  bool dynamic_cfg = false;
  double conditioning_scale = 1.0;
  bool progress = true;  // progress bar on stderr
  int64_t attention_chunk_mb = 256;
  int64_t ff_token_chunk = 4096;
  // Attention kernel (ForwardOptions::attention).
  AttentionBackend attention = AttentionBackend::kAuto;
  // Device, dtypes and offload. The noise is drawn on the CPU (the same
  // numbers on every device), the scheduler runs in float32 on the device and
  // the output latents are float32.
  RuntimeOptions runtime;
  void Check() const;
};

struct SampleResult {
  std::string out;
  int steps = 0;
  bool guidance_used = false;
  double seconds = 0;
  // Device and dtypes the sampling ran in (RuntimeOptions::BriefReport).
  std::string runtime;
  // Bytes of DiT weights (backbone + encoder) in the compute dtype.
  int64_t weight_bytes = 0;
  std::string BriefReport() const;
};

// Runs the sampler and writes `out`. Deterministic for a seed and thread count.
SampleResult Sample(const SampleOptions& options);

struct InitWeightsOptions {
  std::string config = "tiny";
  std::string out;
  uint64_t seed = 0;
  bool with_branch = true;  // also store the encoder under "branch."
  bool nonzero_branch =
      false;                 // random (not zero) encoder projections, for tests
  bool allow_large = false;  // permit > 1e9 parameters (5B in float32 is 22 GB)
  // Write the VAE that `config` pairs with (VaeInitWeights: random test
  // weights, diffusers names) instead of the DiT.
  bool vae = false;
  void Check() const;
};

// Writes random test weights (backbone + encoder cloned from it); returns a
// one-line summary.
std::string InitWeightsFile(const InitWeightsOptions& options);

// Checks names and shapes of a backbone (and optional encoder) checkpoint
// against a preset without reading tensor data; returns the loader report text
// (with the checkpoint's stored dtypes and the memory its weights take in
// `runtime.dtype` on `runtime.device`) and sets *ok.
std::string CheckWeights(const std::string& config,
                         const std::string& weights,
                         const std::string& branch_weights,
                         bool* ok,
                         const RuntimeOptions& runtime = {});

// Parses the OMP_NUM_THREADS environment variable (0 when unset/invalid) and
// sets LibTorch's intra-op thread count to `threads` (> 0) or to that value.
void ConfigureThreads(int threads);

}  // namespace diffusion
}  // namespace geodrive

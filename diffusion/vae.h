#pragma once
// CogVideoX's 3D causal VAE forward (diffusers AutoencoderKLCogVideoX),
// written functionally over named tensors (diffusion/model.h Weights) so the
// state-dict names are exactly diffusers'. float32 on CPU.
//
// Chunking follows diffusers exactly: the encoder runs over frame batches
// (first batch 1 + encode_frame_batch frames, then encode_frame_batch), the
// decoder over latent batches (first 1 + decode_frame_batch, then
// decode_frame_batch), with causal-conv caches carried across batches. The
// convolutions are therefore exact across batches, but GroupNorm statistics
// are per batch, so the result differs from a single whole-video pass; set
// VaeOptions::frame_batching = false for that (not what diffusers computes).

#include <ATen/core/Tensor.h>

#include "diffusion/model.h"
#include "diffusion/vae_config.h"

namespace geodrive {
namespace diffusion {

struct VaeOptions {
  // Diffusers' frame batching (see above). false = one pass over all frames.
  bool frame_batching = true;
  void Check() const;
};

// Random weights for tests (deterministic for `seed`): InitWeights of
// diffusion/model.h (convs N(0, 1/fan_in), biases N(0, 0.02)) with every
// GroupNorm weight 1 and bias 0.
Weights VaeInitWeights(const VaeConfig& config, uint64_t seed);

// video [B, 3, F, H, W] float32 in [-1, 1], F = 1 + 4k, H and W multiples of 8
// -> latent mean [B, C_lat, 1 + k, H/8, W/8]. NOT multiplied by
// scaling_factor (callers multiply, as diffusers does).
at::Tensor VaeEncode(const VaeConfig& config,
                     const Weights& w,
                     const at::Tensor& video,
                     const VaeOptions& options = {});

// As VaeEncode, also returning the log-variance (clamped to [-30, 20]) in
// *logvar; sample = mean + exp(logvar / 2) * eps.
at::Tensor VaeEncodeMoments(const VaeConfig& config,
                            const Weights& w,
                            const at::Tensor& video,
                            at::Tensor* logvar,
                            const VaeOptions& options = {});

// latents [B, C_lat, F', h, w] (unscaled) -> video [B, 3, 1 + 4(F' - 1), 8h,
// 8w] in about [-1, 1] (not clamped). F' odd as in CogVideoX (13 -> 49); an
// even F' gives 4F' frames, as in diffusers (config.PixelFrames).
at::Tensor VaeDecode(const VaeConfig& config,
                     const Weights& w,
                     const at::Tensor& latents,
                     const VaeOptions& options = {});

}  // namespace diffusion
}  // namespace geodrive

#pragma once
// Configuration and state-dict table of CogVideoX's 3D causal VAE (diffusers
// AutoencoderKLCogVideoX). Torch-free: shapes are computed symbolically.

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "diffusion/config.h"

namespace geodrive {
namespace diffusion {

// VAE configuration (diffusers config.json names in comments).
struct VaeConfig {
  std::string name = "tiny";
  int in_channels = 3;      // in_channels (= out_channels)
  int latent_channels = 4;  // latent_channels
  // block_out_channels: one encoder down block / decoder up block per entry.
  std::vector<int> block_out_channels = {8, 16, 16, 16};
  int layers_per_block = 1;      // layers_per_block (decoder: + 1 resnets)
  int norm_num_groups = 4;       // norm_num_groups
  double norm_eps = 1e-6;        // norm_eps
  double scaling_factor = 0.7;   // scaling_factor (callers multiply)
  int temporal_compression = 4;  // temporal_compression_ratio
  int spatial_compression = 8;   // 2^(len(block_out_channels) - 1)
  // Encoder frame batching (diffusers num_sample_frames_batch_size): chunks of
  // this many pixel frames, the first chunk takes the odd extra frame.
  int encode_frame_batch = 8;
  // Decoder frame batching (num_latent_frames_batch_size): chunks of this many
  // latent frames, the first chunk takes the odd extra frame.
  int decode_frame_batch = 2;

  // Number of down blocks that also halve time: log2(temporal_compression).
  int TimeCompressBlocks() const;
  // Latent frames for `frames` pixel frames (1 + 4k -> 1 + k).
  int64_t LatentFrames(int64_t frames) const;
  // Pixel frames decoded from `latent_frames` (1 + k -> 1 + 4k).
  int64_t PixelFrames(int64_t latent_frames) const;
  // Throws InputError naming the preset when a field is out of range.
  void Check() const;
};

// Diffusers' frame batches [start, end) of `frames` frames in batches of
// `batch`: max(frames / batch, 1) batches, the first also taking the remainder
// frames % batch (49 pixel frames, batch 8: [0, 9), [9, 17), ..., [41, 49)).
std::vector<std::pair<int64_t, int64_t>> VaeFrameBatches(int64_t frames,
                                                         int64_t batch);

// Presets: "tiny" (4 latent channels = tiny DiTConfig out_channels; CPU tests)
// and "cogvideox-5b-i2v" (THUDM/CogVideoX-5b-I2V vae/config.json). A DiT
// config preset name (ConfigPresetNames, e.g. "tiny-49") gives the VAE that
// config pairs with (VaePresetNameForConfig), so one --config names both
// models. Throws InputError for any other name.
VaeConfig VaePreset(const std::string& name);
std::vector<std::string> VaePresetNames();

// The VAE preset a DiT config preset pairs with: "tiny" and "tiny-49" -> "tiny"
// (same latent channels and spatial compression; tiny-49 only has more latent
// frames), "cogvideox-5b-i2v" -> "cogvideox-5b-i2v". Throws InputError naming
// --config for an unknown preset.
std::string VaePresetNameForConfig(const std::string& config);

// State dict (diffusers names and shapes, module order): encoder.*, decoder.*.
// Works with Weights / LoadWeights / InitWeights of diffusion/model.h.
std::vector<ParamSpec> VaeParamSpecs(const VaeConfig& config);

}  // namespace diffusion
}  // namespace geodrive

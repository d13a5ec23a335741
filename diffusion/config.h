#pragma once
// Model configuration of the CogVideoX-style DiT and GeoDrive's condition
// encoder ("branch"), parameter name/shape tables identical to diffusers'
// CogVideoXTransformer3DModel and the released branch checkpoint, and the
// loader report. Torch-free: shapes are computed symbolically.

#include <cstdint>
#include <string>
#include <vector>

namespace geodrive {
namespace diffusion {

// Transformer configuration (diffusers config.json names in comments).
struct DiTConfig {
  std::string name = "tiny";
  int num_layers = 4;    // num_layers
  int num_heads = 2;     // num_attention_heads
  int head_dim = 16;     // attention_head_dim
  int in_channels = 8;   // in_channels: [noisy latent, image latent]
  int out_channels = 4;  // out_channels = latent channels
  int patch_size =
      2;  // patch_size (spatial; no temporal patching, CogVideoX 1.0)
  int time_embed_dim = 16;      // time_embed_dim
  int text_embed_dim = 24;      // text_embed_dim
  int text_seq_len = 8;         // max_text_seq_length
  int latent_frames = 3;        // (sample_frames - 1) / 4 + 1
  int latent_height = 4;        // sample_height
  int latent_width = 6;         // sample_width
  int ff_mult = 4;              // FF inner dim = ff_mult * inner_dim
  bool use_rotary = true;       // use_rotary_positional_embeddings
  bool use_learned_pos = true;  // use_learned_positional_embeddings (I2V only)
  bool attention_bias = true;   // attention_bias
  bool flip_sin_to_cos = true;  // flip_sin_to_cos
  int freq_shift = 0;           // freq_shift
  double norm_eps = 1e-5;       // norm_eps
  double qk_norm_eps = 1e-6;    // per-head q/k LayerNorm eps
  double rope_theta = 10000.0;
  // GeoDrive condition encoder (branch).
  int branch_layers =
      2;  // branch_layer_num: clones of blocks 0..branch_layers-1
  int branch_in_channels = 8;  // [noisy latent, condition-render latent]
  double conditioning_scale = 1.0;

  int64_t inner_dim() const { return int64_t{num_heads} * head_dim; }
  int64_t tokens_per_frame() const {
    return int64_t{latent_height / patch_size} * (latent_width / patch_size);
  }
  int64_t video_tokens() const { return tokens_per_frame() * latent_frames; }
  int64_t seq_len() const { return text_seq_len + video_tokens(); }
  // RoPE split of the head dim into t/h/w parts (diffusers: d/4, d/8*3, d/8*3).
  int rope_dim_t() const { return head_dim / 4; }
  int rope_dim_h() const { return head_dim / 8 * 3; }
  int rope_dim_w() const { return head_dim / 8 * 3; }
  // Backbone block i receives branch output i / BranchInterval() (= ceil(layers
  // / branch)).
  int BranchInterval() const {
    return (num_layers + branch_layers - 1) / branch_layers;
  }
  // Throws InputError naming the preset when a field is out of range.
  void Check() const;
};

// Presets: "cogvideox-5b-i2v" (THUDM/CogVideoX-5b-I2V + GeoDrive branch) and
// "tiny" (tests).
DiTConfig ConfigPreset(const std::string& name);
std::vector<std::string> ConfigPresetNames();

// One parameter (or persistent buffer) of a state dict.
struct ParamSpec {
  std::string name;
  std::vector<int64_t> shape;
};

int64_t NumElements(const std::vector<int64_t>& shape);
int64_t NumElements(const std::vector<ParamSpec>& specs);
std::string ShapeToString(const std::vector<int64_t>& shape);

// Backbone state dict (diffusers CogVideoXTransformer3DModel), in module order.
std::vector<ParamSpec> BackboneParamSpecs(const DiTConfig& config);
// Branch (CogvideoXBranchModel) state dict: the backbone layout with
// branch_layers blocks and branch_in_channels patch input, plus
// branch_blocks.{k} and the unused branch_x_embedder.
std::vector<ParamSpec> BranchParamSpecs(const DiTConfig& config);
// Names present in the branch checkpoint but unused by the forward pass (heads,
// x_embedder).
bool IsUnusedBranchParam(const std::string& name);

// Result of matching a checkpoint against a state-dict table.
struct LoadReport {
  std::string source;                   // checkpoint path
  int64_t matched = 0;                  // names present with the right shape
  std::vector<std::string> missing;     // expected, absent from the file
  std::vector<std::string> unexpected;  // in the file, not expected
  std::vector<std::string> mismatched;  // "name: file [..] vs model [..]"
  bool ok() const { return missing.empty() && mismatched.empty(); }
  // One line, plus up to `max_list` names per category.
  std::string BriefReport(size_t max_list = 10) const;
};

// Throws InputError naming the checkpoint when an encoder (branch) checkpoint
// lacks a tensor the forward pass uses (unused heads may be missing) or has a
// shape mismatch.
void CheckBranchLoadReport(const LoadReport& report);

// Compares names/shapes (`file` = name+shape of each stored tensor) against
// `expected`.
LoadReport CompareStateDict(const std::string& source,
                            const std::vector<ParamSpec>& expected,
                            const std::vector<ParamSpec>& file);

}  // namespace diffusion
}  // namespace geodrive

#pragma once
// CogVideoX-style DiT (diffusers CogVideoXTransformer3DModel) and GeoDrive's
// condition encoder (CogvideoXBranchModel), written functionally over named
// tensors so the state-dict names are exactly diffusers'. The forward runs on
// the device and in the dtype of the weights (diffusion/runtime.h): inputs are
// cast to them, the timestep sinusoid and RoPE are computed in float32 as
// diffusers does, and the outputs are in the weights' dtype.

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <functional>
#include <string>
#include <unordered_map>
#include <vector>

#include "diffusion/config.h"
#include "diffusion/runtime.h"

namespace geodrive {
namespace diffusion {

// A state dict: tensors by diffusers name, plus the module order for saving.
struct Weights {
  std::vector<std::string> order;
  std::unordered_map<std::string, at::Tensor> tensors;

  bool Has(const std::string& name) const { return tensors.count(name) > 0; }
  // The tensor called `name` (CHECK-fails when absent: names come from the spec
  // tables).
  const at::Tensor& Get(const std::string& name) const;
  void Set(const std::string& name, at::Tensor t);
  // Sets requires_grad on every tensor (backbone frozen: false; encoder
  // trained: true).
  void SetRequiresGrad(bool requires_grad);
  // A deep copy (clones every tensor).
  Weights Clone() const;
  // The tensors whose names start with `prefix` (same names, not copied).
  Weights Subset(const std::string& prefix) const;
  // Every tensor converted to `options` (device and dtype); tensors already
  // there are shared, not copied.
  Weights To(const at::TensorOptions& options) const;
  // Total bytes of the tensors' data.
  int64_t Bytes() const;
};

// Where loaded or initialised weights are put.
struct WeightPlacement {
  // Device of the computation.
  DeviceSpec device;
  // Dtype the weights are converted to (a checkpoint already in this dtype is
  // not converted: a BF16 file loads into bf16 without a float32 copy).
  ComputeDtype dtype = ComputeDtype::kFloat32;
  // Keep `transformer_blocks.*` in host memory (pinned when the device is
  // CUDA), in `dtype`; the forward moves one block at a time (ForwardOptions::
  // offload_blocks).
  bool host_blocks = false;
};

struct RotaryTables;
struct ForwardOptions;

// The signature of BlockForward (ForwardOptions::block_forward).
using BlockForwardFn = std::function<void(const DiTConfig& config,
                                          const Weights& w,
                                          const std::string& prefix,
                                          const at::Tensor& temb,
                                          const RotaryTables& rope,
                                          const ForwardOptions& options,
                                          at::Tensor* video,
                                          at::Tensor* text)>;

// Memory bounds and kernels of the forward pass.
struct ForwardOptions {
  // Attention scores are materialised for at most this many bytes per chunk
  // (heads x queries x keys x 4). 5B at 17,776 tokens: one head x 2,048 queries
  // is 146 MB.
  int64_t attention_chunk_bytes = int64_t{256} << 20;
  // The feed-forward runs over at most this many tokens at a time (5B: 4,096 x
  // 12,288 x 4 B).
  int64_t ff_token_chunk = 4096;
  // Attention kernel.
  AttentionBackend attention = AttentionBackend::kAuto;
  // The backbone's blocks are in host memory (WeightPlacement::host_blocks):
  // copy each block's weights to the compute device (that of
  // `patch_embed.proj.weight`) for its forward, then drop the copy.
  bool offload_blocks = false;
  // Runs one block in place of BlockForward when set (train: gradient
  // checkpointing of the backbone's blocks).
  BlockForwardFn block_forward;
  void Check() const;
};

// Random initialisation from the spec table (deterministic for `seed`):
// Linear/Conv weights N(0, 1/fan_in), biases N(0, 0.02), LayerNorm weight 1 /
// bias 0, pos_embedding N(0, 0.02).
// Each tensor is drawn in float32 on the CPU and then converted to
// `placement` (the same numbers on every device, rounded to its dtype).
Weights InitWeights(const std::vector<ParamSpec>& specs,
                    uint64_t seed,
                    const WeightPlacement& placement = {});

// The encoder as `CogvideoXBranchModel.from_transformer`: blocks
// 0..branch_layers-1 and the time embedding copied from the backbone; the patch
// conv's two latent-channel halves both copied from the backbone's noisy-latent
// slice, bias copied; text_proj, pos_embedding and the unused heads freshly
// initialised from `seed` (as upstream, not copied); branch_blocks zero.
Weights InitBranchFromBackbone(const DiTConfig& config,
                               const Weights& backbone,
                               uint64_t seed);

// Loads `specs` from a safetensors file or sharded index (names may carry
// `prefix`, e.g. "branch."), one tensor at a time: each is read from the
// mapping, converted to `placement`'s dtype and moved to its device before the
// next is read (peak host memory: one tensor, plus the blocks kept on the host
// with host_blocks). Fills `report`; throws InputError when the checkpoint
// cannot be read, or when `strict` and names are missing or shapes mismatch.
Weights LoadWeights(const std::string& path,
                    const std::vector<ParamSpec>& specs,
                    const std::string& prefix,
                    bool strict,
                    LoadReport* report,
                    const WeightPlacement& placement = {});
// Appends weights (in module order, names prefixed) to a list for
// SaveSafetensors.
void AppendForSave(const Weights& weights,
                   const std::string& prefix,
                   std::vector<std::pair<std::string, at::Tensor>>* out);

// 3D RoPE tables (cos, sin), each [video_tokens, head_dim] float32 on the CPU,
// frame-major token order (the forward moves them to the compute device).
struct RotaryTables {
  at::Tensor cos, sin;
};
RotaryTables Rotary3D(const DiTConfig& config,
                      int64_t frames,
                      int64_t grid_h,
                      int64_t grid_w);

// Timestep embedding: sinusoid (dim = inner_dim, [cos, sin]) -> linear_1 ->
// SiLU -> linear_2.
at::Tensor TimeEmbedding(const DiTConfig& config,
                         const Weights& w,
                         const at::Tensor& timesteps);

// One CogVideoXBlock in place on video [B, Nv, D] and text [B, Nt, D] tokens.
void BlockForward(const DiTConfig& config,
                  const Weights& w,
                  const std::string& prefix,
                  const at::Tensor& temb,
                  const RotaryTables& rope,
                  const ForwardOptions& options,
                  at::Tensor* video,
                  at::Tensor* text);

// Backbone forward. latents [B, F, in_channels, H, W], text [B, L,
// text_embed_dim], timesteps [B] (float), branch_outputs: per-branch-block
// video residuals [B, Nv, D] (empty = no encoder). Returns the model output [B,
// F, out_channels, H, W] (v-prediction).
at::Tensor BackboneForward(const DiTConfig& config,
                           const Weights& w,
                           const at::Tensor& latents,
                           const at::Tensor& text,
                           const at::Tensor& timesteps,
                           const std::vector<at::Tensor>& branch_outputs,
                           const ForwardOptions& options = {});

// Condition-encoder forward: noisy [B, F, C, H, W] and condition latents [B, F,
// C', H, W] with C + C' = branch_in_channels. Returns branch_layers tensors [B,
// Nv, D], already scaled by config.conditioning_scale.
std::vector<at::Tensor> BranchForward(const DiTConfig& config,
                                      const Weights& w,
                                      const at::Tensor& noisy,
                                      const at::Tensor& cond,
                                      const at::Tensor& text,
                                      const at::Tensor& timesteps,
                                      const ForwardOptions& options = {});

}  // namespace diffusion
}  // namespace geodrive

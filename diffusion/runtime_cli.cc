#include "diffusion/runtime_cli.h"

namespace geodrive {
namespace diffusion {

RuntimeOptions RuntimeArgs::Parse() const {
  RuntimeOptions r;
  r.device = ParseDevice(device);
  r.dtype = ParseDtype(dtype);
  r.vae_dtype = ParseDtype(vae_dtype, "--vae-dtype");
  r.offload_backbone = offload_backbone;
  r.Check();
  return r;
}

AttentionBackend RuntimeArgs::Attention() const {
  return ParseAttentionBackend(attention);
}

void AddRuntimeOptions(CLI::App& cmd, RuntimeArgs* a, int flags) {
  cmd.add_option("--device", a->device,
                 "compute device: cpu, cuda or cuda:N (a CUDA LibTorch build)")
      ->capture_default_str();
  if (!(flags & kRuntimeNoDitDtype)) {
    cmd.add_option("--dtype", a->dtype,
                   "dtype of the DiT's weights and activations: fp32, bf16 or "
                   "fp16 (a checkpoint stored in it loads without conversion; "
                   "scheduler, noise and output latents stay float32)")
        ->capture_default_str();
  }
  if (flags & kRuntimeVae) {
    cmd.add_option("--vae-dtype", a->vae_dtype,
                   "dtype of the VAE: fp32, bf16 or fp16")
        ->capture_default_str();
  }
  if (flags & kRuntimeAttention) {
    cmd.add_option("--attention", a->attention,
                   "attention kernel: auto (fused scaled_dot_product_attention "
                   "with LibTorch >= 2.0, else chunked), chunked, or fused "
                   "(LibTorch 1.13: its private kernel, whole score matrix)")
        ->capture_default_str();
  }
  if (flags & kRuntimeOffload) {
    cmd.add_flag("--offload-backbone", a->offload_backbone,
                 "keep the frozen backbone's blocks in host memory and move "
                 "one block at a time to the device");
  }
}

}  // namespace diffusion
}  // namespace geodrive

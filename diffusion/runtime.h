#pragma once
// Where and in which precision the diffusion runtime computes: the device
// (`--device cpu|cuda[:N]`) and the dtypes of the DiT and of the VAE
// (`--dtype`, `--vae-dtype`: fp32|bf16|fp16). Torch-free header; the LibTorch
// conversions are in diffusion/runtime_torch.h.
//
// Policy (as diffusers): weights and activations of the networks are in the
// chosen dtype; the timestep embedding's sinusoid, the scheduler's arithmetic,
// the noise and the final latents stay float32.

#include <string>

namespace geodrive {
namespace diffusion {

enum class DeviceKind { kCpu, kCuda };

// A compute device: the CPU or one CUDA device.
struct DeviceSpec {
  DeviceKind kind = DeviceKind::kCpu;
  // CUDA device ordinal (0 for "cuda"); unused for the CPU.
  int index = 0;
  bool is_cuda() const { return kind == DeviceKind::kCuda; }
  // "cpu" or "cuda:N".
  std::string ToString() const;
};

enum class ComputeDtype { kFloat32, kBFloat16, kFloat16 };

// "cpu", "cuda", "cuda:N" (the whole string; N a non-negative integer).
// Throws InputError naming the option otherwise.
DeviceSpec ParseDevice(const std::string& text);
// "fp32" | "bf16" | "fp16" (also "float32", "bfloat16", "float16").
ComputeDtype ParseDtype(const std::string& text,
                        const std::string& option = "--dtype");
// "fp32", "bf16" or "fp16".
const char* DtypeName(ComputeDtype dtype);
// Bytes per element: 4 or 2.
int DtypeBytes(ComputeDtype dtype);

// Attention kernels.
enum class AttentionBackend {
  // The fused kernel where the LibTorch is >= 2.0 (public
  // scaled_dot_product_attention: flash / memory-efficient on CUDA), else
  // kChunked.
  kAuto,
  // Scores materialised per chunk of heads x queries (ForwardOptions::
  // attention_chunk_bytes); any LibTorch.
  kChunked,
  // The fused kernel; on LibTorch 1.13 its private predecessor
  // `_scaled_dot_product_attention` (one whole score matrix: tests only).
  kFused,
};
// "auto" | "chunked" | "fused" (InputError naming --attention otherwise).
AttentionBackend ParseAttentionBackend(const std::string& text);
// The backend kAuto resolves to in this build.
AttentionBackend ResolveAttentionBackend(AttentionBackend backend);
const char* AttentionBackendName(AttentionBackend backend);

// The runtime options every diffusion command takes.
struct RuntimeOptions {
  // Device of the computation.
  DeviceSpec device;
  // Dtype of the DiT's (backbone and encoder) weights and activations.
  ComputeDtype dtype = ComputeDtype::kFloat32;
  // Dtype of the VAE's weights and activations.
  ComputeDtype vae_dtype = ComputeDtype::kFloat32;
  // Keep the frozen backbone's blocks in host memory and move each to the
  // device only for its forward (for GPUs smaller than the weights). No
  // effect on the CPU.
  bool offload_backbone = false;
  // Throws InputError when the device does not exist in this LibTorch build
  // (a CPU-only LibTorch and "cuda", an ordinal beyond the device count).
  void Check() const;
  // "cpu fp32 (VAE fp32)" etc.
  std::string BriefReport() const;
};

// What the installed LibTorch offers: its version, whether CUDA is compiled in
// and how many devices it sees, and whether the fused attention kernel
// (scaled_dot_product_attention, public from LibTorch 2.0) is available.
struct RuntimeInfo {
  std::string torch_version;
  bool cuda_available = false;
  int cuda_devices = 0;
  bool public_sdpa = false;
  std::string BriefReport() const;
};
RuntimeInfo GetRuntimeInfo();

}  // namespace diffusion
}  // namespace geodrive

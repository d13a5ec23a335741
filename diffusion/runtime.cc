#include "diffusion/runtime.h"

#include <ATen/ATen.h>
#include <ATen/Context.h>
#include <ATen/detail/CUDAHooksInterface.h>
#include <torch/version.h>

#include <cctype>
#include <sstream>

#include "diffusion/runtime_torch.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace diffusion {

std::string DeviceSpec::ToString() const {
  return is_cuda() ? "cuda:" + std::to_string(index) : std::string("cpu");
}

DeviceSpec ParseDevice(const std::string& text) {
  DeviceSpec d;
  if (text == "cpu") return d;
  d.kind = DeviceKind::kCuda;
  if (text == "cuda") return d;
  const std::string prefix = "cuda:";
  bool ok = text.rfind(prefix, 0) == 0 && text.size() > prefix.size() &&
            text.size() <= prefix.size() + 3;
  for (size_t i = prefix.size(); ok && i < text.size(); ++i)
    ok = std::isdigit(static_cast<unsigned char>(text[i])) != 0;
  GEODRIVE_CHECK_INPUT(ok, "--device: '", text,
                       "' is not a device (expected cpu, cuda or cuda:N)");
  d.index = std::stoi(text.substr(prefix.size()));
  return d;
}

ComputeDtype ParseDtype(const std::string& text, const std::string& option) {
  if (text == "fp32" || text == "float32") return ComputeDtype::kFloat32;
  if (text == "bf16" || text == "bfloat16") return ComputeDtype::kBFloat16;
  if (text == "fp16" || text == "float16") return ComputeDtype::kFloat16;
  ThrowInputError(option, "'", text,
                  "' is not a dtype (expected fp32, bf16 or fp16)");
}

const char* DtypeName(ComputeDtype dtype) {
  switch (dtype) {
    case ComputeDtype::kBFloat16:
      return "bf16";
    case ComputeDtype::kFloat16:
      return "fp16";
    case ComputeDtype::kFloat32:
      break;
  }
  return "fp32";
}

int DtypeBytes(ComputeDtype dtype) {
  return dtype == ComputeDtype::kFloat32 ? 4 : 2;
}

AttentionBackend ResolveAttentionBackend(AttentionBackend backend) {
  if (backend != AttentionBackend::kAuto) return backend;
  return TORCH_VERSION_MAJOR >= 2 ? AttentionBackend::kFused
                                  : AttentionBackend::kChunked;
}

const char* AttentionBackendName(AttentionBackend backend) {
  switch (backend) {
    case AttentionBackend::kChunked:
      return "chunked";
    case AttentionBackend::kFused:
      return "fused";
    case AttentionBackend::kAuto:
      break;
  }
  return "auto";
}

AttentionBackend ParseAttentionBackend(const std::string& text) {
  if (text == "auto") return AttentionBackend::kAuto;
  if (text == "chunked") return AttentionBackend::kChunked;
  if (text == "fused") return AttentionBackend::kFused;
  ThrowInputError("--attention", "'", text,
                  "' is not an attention kernel (expected auto, chunked or "
                  "fused)");
}

RuntimeInfo GetRuntimeInfo() {
  RuntimeInfo info;
  info.torch_version = TORCH_VERSION;
  info.cuda_available = at::hasCUDA();
  info.cuda_devices =
      info.cuda_available ? at::detail::getCUDAHooks().getNumGPUs() : 0;
  info.public_sdpa = TORCH_VERSION_MAJOR >= 2;
  return info;
}

std::string RuntimeInfo::BriefReport() const {
  std::ostringstream os;
  os << "LibTorch " << torch_version << ", "
     << (cuda_available ? std::to_string(cuda_devices) + " CUDA device(s)"
                        : std::string("CPU only"))
     << ", attention "
     << (public_sdpa ? "fused (scaled_dot_product_attention)" : "chunked");
  return os.str();
}

void RuntimeOptions::Check() const {
  if (!device.is_cuda()) {
    // LibTorch 1.13's CPU kernels have no half-precision matmul (addmm).
    const bool half =
        dtype == ComputeDtype::kFloat16 || vae_dtype == ComputeDtype::kFloat16;
    GEODRIVE_CHECK_INPUT(!half || TORCH_VERSION_MAJOR >= 2,
                         "--dtype fp16: LibTorch ", TORCH_VERSION,
                         " has no half-precision matmul on the CPU; use bf16 "
                         "or fp32 on the CPU (fp16 on CUDA)");
    return;
  }
  const RuntimeInfo info = GetRuntimeInfo();
  GEODRIVE_CHECK_INPUT(info.cuda_available, "--device ", device.ToString(),
                       ": this LibTorch (", info.torch_version,
                       ") has no CUDA support; use --device cpu or build "
                       "against a CUDA LibTorch (scripts/device_check.sh)");
  GEODRIVE_CHECK_INPUT(device.index < info.cuda_devices, "--device ",
                       device.ToString(), ": only ", info.cuda_devices,
                       " CUDA device(s) visible");
}

std::string RuntimeOptions::BriefReport() const {
  std::ostringstream os;
  os << device.ToString() << " " << DtypeName(dtype) << " (VAE "
     << DtypeName(vae_dtype) << ")" << (offload_backbone ? ", offload" : "");
  return os.str();
}

c10::Device ToTorchDevice(const DeviceSpec& device) {
  return device.is_cuda()
             ? c10::Device(c10::DeviceType::CUDA,
                           static_cast<c10::DeviceIndex>(device.index))
             : c10::Device(c10::DeviceType::CPU);
}

at::ScalarType ToScalarType(ComputeDtype dtype) {
  switch (dtype) {
    case ComputeDtype::kBFloat16:
      return at::kBFloat16;
    case ComputeDtype::kFloat16:
      return at::kHalf;
    case ComputeDtype::kFloat32:
      break;
  }
  return at::kFloat;
}

at::TensorOptions ComputeOptions(const DeviceSpec& device, ComputeDtype dtype) {
  return at::TensorOptions()
      .device(ToTorchDevice(device))
      .dtype(ToScalarType(dtype));
}

}  // namespace diffusion
}  // namespace geodrive

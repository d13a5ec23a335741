#pragma once
// LibTorch side of diffusion/runtime.h: device and dtype conversions.

#include <ATen/core/Tensor.h>
#include <c10/core/Device.h>
#include <c10/core/ScalarType.h>

#include "diffusion/runtime.h"

namespace geodrive {
namespace diffusion {

c10::Device ToTorchDevice(const DeviceSpec& device);
at::ScalarType ToScalarType(ComputeDtype dtype);
// Tensor options of that device and dtype.
at::TensorOptions ComputeOptions(const DeviceSpec& device, ComputeDtype dtype);

}  // namespace diffusion
}  // namespace geodrive

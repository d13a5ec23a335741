#pragma once
// Helpers shared by the diffusion test files.

#include <ATen/ATen.h>

#include <string>

namespace geodrive {
namespace test {

// The command prefix that runs the built geodrive-diffusion with one OpenMP
// thread (ctest runs the tests in parallel).
inline std::string DiffusionCommand() {
  return std::string("OMP_NUM_THREADS=1 ") + GEODRIVE_DIFFUSION_BINARY;
}

// max |t| as a double.
inline double MaxAbs(const at::Tensor& t) {
  return t.abs().max().item<double>();
}

}  // namespace test
}  // namespace geodrive

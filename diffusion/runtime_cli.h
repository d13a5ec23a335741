#pragma once
// The runtime options of the geodrive-diffusion commands (--device, --dtype,
// --vae-dtype, --attention, --offload-backbone), added to a CLI11 command and
// parsed into diffusion/runtime.h's RuntimeOptions. Not installed (CLI11).

#include <CLI/CLI.hpp>
#include <string>

#include "diffusion/runtime.h"

namespace geodrive {
namespace diffusion {

// Which of the options a command takes.
enum RuntimeFlag : int {
  kRuntimeVae = 1,         // --vae-dtype
  kRuntimeAttention = 2,   // --attention
  kRuntimeOffload = 4,     // --offload-backbone
  kRuntimeNoDitDtype = 8,  // no --dtype (the VAE commands)
};

// The option strings as CLI11 parses them.
struct RuntimeArgs {
  std::string device = "cpu";
  std::string dtype = "fp32";
  std::string vae_dtype = "fp32";
  std::string attention = "auto";
  bool offload_backbone = false;
  // Throws InputError naming the option whose value is not valid, or a device
  // this LibTorch cannot use.
  RuntimeOptions Parse() const;
  AttentionBackend Attention() const;
};

// Adds --device and --dtype (unless kRuntimeNoDitDtype), plus the options
// `flags` selects.
void AddRuntimeOptions(CLI::App& cmd, RuntimeArgs* args, int flags);

}  // namespace diffusion
}  // namespace geodrive

# The diffusion runtime's core (model, VAE, scheduler, safetensors, sampling, device and dtype):
# what needs only LibTorch and the header-only nlohmann_json. Included by diffusion/CMakeLists.txt
# (the full build) and by diffusion/standalone/CMakeLists.txt (the standalone build against any
# LibTorch, scripts/device_check.sh). Paths are relative to the repository root.
set(GEODRIVE_DIFFUSION_CORE_SOURCES
  diffusion/config.cc
  diffusion/schedule.cc
  diffusion/safetensors.cc
  diffusion/model.cc
  diffusion/sampler.cc
  diffusion/vae_config.cc
  diffusion/vae.cc
  diffusion/runtime.cc)
# The torch-free pieces the core uses (safetensors header parser, atomic file writes, the
# regular-file check of every reader).
set(GEODRIVE_DIFFUSION_CORE_DEPENDENCY_SOURCES
  diffusion/format/safetensors_header.cc
  geometry/util/files.cc
  geometry/util/input_file.cc)

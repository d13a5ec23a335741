// libFuzzer target: safetensors headers
// (diffusion/format/safetensors_header.h): length prefix, JSON, dtypes, shapes,
// offsets tiling the data buffer.
#include "diffusion/format/safetensors_header.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  fuzz::ExpectReturnOrInputError([&] {
    diffusion::ParseSafetensorsHeader("model.safetensors", data, size);
  });
  return 0;
}

// libFuzzer target: NumPy .npy (geometry/npy.h), header and data.
#include "fuzz/fuzz_util.h"
#include "geometry/npy.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  static const std::string path = fuzz::InputPath("array.npy");
  fuzz::WriteInput(path, data, size);
  NpyReadOptions options;
  options.max_bytes = 64ull << 20;  // within libFuzzer's malloc limit
  fuzz::ExpectReturnOrInputError([&] { ReadNpyHeader(path); });
  fuzz::ExpectReturnOrInputError([&] { ReadNpy(path, options); });
  fuzz::ExpectReturnOrInputError([&] { ReadNpyAsFloat32(path, options); });
  return 0;
}

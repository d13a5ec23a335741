// libFuzzer target: NumPy .npz archives (geometry/npz.h): the zip container
// (libzip), each member's .npy header and data.
#include "fuzz/fuzz_util.h"
#include "geometry/npz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  static const std::string path = fuzz::InputPath("arrays.npz");
  fuzz::WriteInput(path, data, size);
  NpyReadOptions options;
  options.max_bytes = 64ull << 20;  // within libFuzzer's malloc limit
  fuzz::ExpectReturnOrInputError([&] {
    const NpzReader npz(path);
    for (const std::string& key : npz.Keys()) {
      fuzz::ExpectReturnOrInputError([&] { npz.Header(key); });
      fuzz::ExpectReturnOrInputError([&] { npz.ReadAsFloat32(key, options); });
    }
  });
  return 0;
}

// libFuzzer target: .npz archives at the zip level (geometry/npz.h): member
// counts, declared compressed and uncompressed sizes, compression ratios and
// methods, entries that share data, duplicate names. The archive is opened,
// every member listed and looked up, its header and its array read; every
// declared size must be checked (geometry/util/size_limits.h) before
// anything is inflated, so no input may allocate past libFuzzer's
// -malloc_limit_mb.
#include "fuzz/fuzz_util.h"
#include "geometry/npz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  static const std::string path = fuzz::InputPath("archive.npz");
  fuzz::WriteInput(path, data, size);
  NpyReadOptions options;
  options.max_bytes = 64ull << 20;  // within libFuzzer's malloc limit
  fuzz::ExpectReturnOrInputError([&] {
    const NpzReader npz(path);
    for (const std::string& key : npz.Keys()) {
      if (!npz.Has(key)) std::abort();  // every listed key is found
      fuzz::ExpectReturnOrInputError([&] { npz.Read(key, options); });
      fuzz::ExpectReturnOrInputError([&] { npz.ReadString(key); });
    }
    fuzz::ExpectReturnOrInputError([&] { npz.Read("missing", options); });
  });
  return 0;
}

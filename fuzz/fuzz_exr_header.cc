// libFuzzer target: EXR files (geometry/exr.h), the header above all: data
// and display windows, channel lists, compression, tiles, multi-part headers,
// chunk counts and offset tables. The header's sizes are checked
// (geometry/util/size_limits.h) before OpenEXR or the reader allocates, so no
// input may allocate past libFuzzer's -malloc_limit_mb.
#include "fuzz/fuzz_util.h"
#include "geometry/exr.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  static const std::string path = fuzz::InputPath("depth.exr");
  fuzz::WriteInput(path, data, size);
  fuzz::ExpectReturnOrInputError([&] { ExrChannels(path); });
  fuzz::ExpectReturnOrInputError([&] { ReadExr(path, {"Z"}); });
  fuzz::ExpectReturnOrInputError([&] { ReadExr(path, {"X", "Y", "Z"}); });
  return 0;
}

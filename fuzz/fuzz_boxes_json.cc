// libFuzzer target: box sequences JSON of dynamic editing (render/boxes.h).
#include "fuzz/fuzz_util.h"
#include "render/boxes.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  static const std::string path = fuzz::InputPath("boxes.json");
  fuzz::WriteInput(path, data, size);
  fuzz::ExpectReturnOrInputError([&] { ReadBoxesJson(path); });
  return 0;
}

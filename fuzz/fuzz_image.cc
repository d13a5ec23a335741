// libFuzzer target: the image readers (geometry/image_io.h): JPEG and PNG by
// content, every read mode and the header-only size.
#include "fuzz/fuzz_util.h"
#include "geometry/image_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  static const std::string path = fuzz::InputPath("image.png");
  fuzz::WriteInput(path, data, size);
  fuzz::ExpectReturnOrInputError([&] { ReadImageSize(path); });
  fuzz::ExpectReturnOrInputError([&] { ReadImageRgb(path); });
  fuzz::ExpectReturnOrInputError([&] { ReadImageGray(path); });
  fuzz::ExpectReturnOrInputError([&] { ReadImageUnchanged(path); });
  return 0;
}

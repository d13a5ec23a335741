// libFuzzer target: the image readers (geometry/image_io.h): JPEG and PNG by
// content, every read mode, the DCT-scaled decode and the header-only reads.
#include "fuzz/fuzz_util.h"
#include "geometry/image_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  static const std::string path = fuzz::InputPath("image.png");
  fuzz::WriteInput(path, data, size);
  fuzz::ExpectReturnOrInputError([&] { ReadImageSize(path); });
  fuzz::ExpectReturnOrInputError([&] { ReadImageHeader(path); });
  // One M/8 scale, M from the last byte (an unlisted one is an InputError).
  const int m = size > 0 ? 1 + data[size - 1] % 8 : 8;
  fuzz::ExpectReturnOrInputError([&] {
    ReadImageRgbScaled(path, JpegScale{m, 8});
  });
  fuzz::ExpectReturnOrInputError([&] { ReadImageRgb(path); });
  fuzz::ExpectReturnOrInputError([&] { ReadImageGray(path); });
  fuzz::ExpectReturnOrInputError([&] { ReadImageUnchanged(path); });
  return 0;
}

// libFuzzer target: one serialized Waymo v1 Frame
// (dataset/waymo/waymo_frame.h): protobuf parsing, unknown fields at any
// depth, transforms, intrinsics, image sizes, the camera checks.
#include <string_view>

#include "dataset/waymo/waymo_frame.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  fuzz::ExpectReturnOrInputError([&] {
    ParseWaymoFrame(
        std::string_view(reinterpret_cast<const char*>(data), size),
        "frame.pb", 0);
  });
  return 0;
}

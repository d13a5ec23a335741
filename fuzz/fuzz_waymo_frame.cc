// libFuzzer target: one serialized Waymo v1 Frame
// (dataset/waymo/waymo_frame.h): protobuf parsing, unknown fields at any
// depth, transforms, intrinsics, image sizes, the camera checks; then each
// laser's range images (dataset/waymo/waymo_range_image.h) decoded and, with
// its calibration, turned into points.
#include <string_view>

#include "dataset/waymo/waymo_frame.h"
#include "dataset/waymo/waymo_range_image.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  fuzz::ExpectReturnOrInputError([&] {
    const WaymoFrame frame = ParseWaymoFrame(
        std::string_view(reinterpret_cast<const char*>(data), size), "frame.pb",
        0);
    for (const WaymoLaser& laser : frame.lasers) {
      for (const std::string* bytes : {&laser.return1, &laser.return2}) {
        if (bytes->empty()) continue;
        fuzz::ExpectReturnOrInputError([&] {
          const WaymoRangeImage image =
              DecodeWaymoRangeImage(*bytes, 4, "frame.pb", 0, "return");
          for (const WaymoLaserCalibration& c : frame.laser_calibrations)
            if (c.name == laser.name) WaymoRangeImagePoints(image, c);
        });
      }
    }
  });
  return 0;
}

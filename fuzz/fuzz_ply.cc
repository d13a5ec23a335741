// libFuzzer target: PLY point clouds (geometry/point_cloud_io.h).
#include "fuzz/fuzz_util.h"
#include "geometry/point_cloud_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  static const std::string path = fuzz::InputPath("cloud.ply");
  fuzz::WriteInput(path, data, size);
  fuzz::ExpectReturnOrInputError([&] { ReadPly(path); });
  return 0;
}

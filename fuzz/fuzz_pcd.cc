// libFuzzer target: PCD point clouds, ascii / binary / binary_compressed
// (geometry/point_cloud_io.h).
#include "fuzz/fuzz_util.h"
#include "geometry/point_cloud_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  static const std::string path = fuzz::InputPath("cloud.pcd");
  fuzz::WriteInput(path, data, size);
  fuzz::ExpectReturnOrInputError([&] { ReadPcd(path); });
  return 0;
}

// libFuzzer target: nuScenes `.pcd.bin` and KITTI velodyne `.bin` sweeps
// (geometry/point_cloud_io.h).
#include "fuzz/fuzz_util.h"
#include "geometry/point_cloud_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  static const std::string path = fuzz::InputPath("sweep.pcd.bin");
  fuzz::WriteInput(path, data, size);
  fuzz::ExpectReturnOrInputError([&] { ReadNuscenesLidarBin(path); });
  fuzz::ExpectReturnOrInputError([&] { ReadKittiVelodyneBin(path); });
  return 0;
}

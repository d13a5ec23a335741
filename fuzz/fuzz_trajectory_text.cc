// libFuzzer target: the text trajectory formats -- MonST3R pred_traj.txt
// (t x y z qw qx qy qz), pred_intrinsics.txt, TUM (t x y z qx qy qz qw),
// KITTI odometry poses (12 numbers a line) and COLMAP images.txt
// (geometry/trajectory_io.h).
#include "fuzz/fuzz_util.h"
#include "geometry/trajectory_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  static const std::string path = fuzz::InputPath("pred_traj.txt");
  fuzz::WriteInput(path, data, size);
  fuzz::ExpectReturnOrInputError([&] { ReadMonst3rTrajectory(path); });
  fuzz::ExpectReturnOrInputError([&] { ReadTumTrajectory(path); });
  fuzz::ExpectReturnOrInputError(
      [&] { ReadMonst3rIntrinsics(path, 512, 288); });
  fuzz::ExpectReturnOrInputError([&] { ReadKittiTrajectory(path); });
  fuzz::ExpectReturnOrInputError([&] { ReadColmapTrajectory(path); });
  return 0;
}

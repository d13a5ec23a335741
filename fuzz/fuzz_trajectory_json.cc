// libFuzzer target: geodrive trajectory JSON (geometry/trajectory_json.h).
#include "fuzz/fuzz_util.h"
#include "geometry/trajectory_json.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  static const std::string path = fuzz::InputPath("trajectory.json");
  fuzz::WriteInput(path, data, size);
  fuzz::ExpectReturnOrInputError([&] {
    TrajectoryFileInfo info;
    ReadTrajectoryJson(path, &info);
  });
  return 0;
}

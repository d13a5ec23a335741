// libFuzzer target: the npz-based reconstruction readers
// (geometry/reconstruction.h): VGGT predictions.npz, Depth Anything 3
// results.npz, MegaSaM *_sgd_cvd_hr.npz and the generic npz -- keys, shapes,
// dtypes, poses, intrinsics, confidence scales, string members -- on top of
// the zip and .npy layers that fuzz_npz covers; and the GEN3C export's clip
// folder with the input as both depth.npz and camera.npz (its header checks:
// this target links no video decoder, so the read ends at rgb.mp4).
#include <filesystem>

#include "fuzz/fuzz_util.h"
#include "geometry/reconstruction.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  static const std::string path = fuzz::InputPath("scene_sgd_cvd_hr.npz");
  fuzz::WriteInput(path, data, size);
  ReconstructionReadOptions options;
  options.max_bytes = 16ull << 20;  // within libFuzzer's malloc limit
  fuzz::ExpectReturnOrInputError([&] { DetectReconstructionFormat(path); });
  for (ReconstructionFormat format :
       {ReconstructionFormat::kVggt, ReconstructionFormat::kDepthAnything3,
        ReconstructionFormat::kMegaSam, ReconstructionFormat::kGenericNpz}) {
    fuzz::ExpectReturnOrInputError([&] {
      const Monst3rFolder r = ReadReconstruction(format, path, options);
      r.LoadFrame(0);
    });
  }
  static const std::string gen3c = [] {
    const std::string dir = fuzz::InputPath("gen3c");
    std::filesystem::create_directories(dir);
    fuzz::WriteInput(dir + "/rgb.mp4", nullptr, 0);
    return dir;
  }();
  fuzz::WriteInput(gen3c + "/depth.npz", data, size);
  fuzz::WriteInput(gen3c + "/camera.npz", data, size);
  fuzz::ExpectReturnOrInputError([&] { DetectReconstructionFormat(gen3c); });
  fuzz::ExpectReturnOrInputError([&] {
    ReadReconstruction(ReconstructionFormat::kGenericNpz, gen3c, options);
  });
  return 0;
}

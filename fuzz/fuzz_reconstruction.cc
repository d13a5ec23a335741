// libFuzzer target: the npz-based reconstruction readers
// (geometry/reconstruction.h): VGGT predictions.npz, Depth Anything 3
// results.npz, MegaSaM *_sgd_cvd_hr.npz and the generic npz -- keys, shapes,
// dtypes, poses, intrinsics, confidence scales, string members -- on top of
// the zip and .npy layers that fuzz_npz covers.
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
  return 0;
}

// MegaSaM (mega-sam/mega-sam) outputs:
//   outputs/<scene>_sgd_cvd_hr.npz  (consistent video depth, final)
//   outputs/<scene>_droid.npz       (the camera-tracking stage)
// both with images (N, H, W, 3) uint8, depths (N, H, W) (float16 in the cvd
// file, clipped to [1e-3, 100]; float32 in the droid file), intrinsic (3, 3)
// one K for all frames, in pixels of the saved images, cam_c2w (N, 4, 4)
// camera-to-world (OpenCV). No confidence. Up to scale. The saved images are
// the whole source frame resized (GridResize::kStretch). The cvd file is
// preferred when a folder holds both.

#include "geometry/reconstruction/common.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace reconstruction {
namespace {

class MegaSamReader : public ReconstructionReader {
 public:
  ReconstructionFormat format() const override {
    return ReconstructionFormat::kMegaSam;
  }
  std::string ToolName() const override { return "MegaSaM"; }
  ReconstructionConventions Conventions() const override {
    return {"cam_c2w (N,4,4) camera_to_world, as is",
            "none (every pixel confidence 1)",
            "intrinsic (3,3), one for all frames, pixels of the saved images "
            "(the whole source frame resized)",
            "up to scale; float16 depths read exactly, overflow (inf) "
            "rejected"};
  }
  std::optional<std::string> Locate(const std::string& path) const override {
    std::optional<std::string> file = FindFile(path, {"_sgd_cvd_hr.npz"});
    if (!file) file = FindFile(path, {"_droid.npz"});
    if (!file) file = FindFile(path, {".npz"});
    if (file && NpzHasKeys(*file, {"depths", "intrinsic", "cam_c2w"}))
      return file;
    return std::nullopt;
  }
  Monst3rFolder Read(const std::string& path,
                     const ReconstructionReadOptions& options) const override {
    const std::optional<std::string> file = Locate(path);
    GEODRIVE_CHECK_INPUT(file, path,
                         ": no MegaSaM npz (*_sgd_cvd_hr.npz or *_droid.npz "
                         "with depths, intrinsic and cam_c2w)");
    const NpzReader npz(*file);
    const std::string at = *file + ": ";
    Arrays a;
    a.depth =
        FloatMaps(*ReadArray(npz, "depths", options), at + "depths", true);
    const int n = static_cast<int>(a.depth.size());
    const int h = a.depth[0].rows, w = a.depth[0].cols;
    a.world_from_cam =
        Poses(*ReadArray(npz, "cam_c2w", options), at + "cam_c2w", false);
    a.cameras = Cameras(*ReadArray(npz, "intrinsic", options), at + "intrinsic",
                        n, w, h);
    if (auto images = ReadArray(npz, "images", options, false))
      a.rgb = Images(*images, at + "images");
    if (options.check_motion_direction) {
      CheckMotionDirection(a.world_from_cam, at + "cam_c2w",
                           "MegaSaM's cam_c2w is camera-to-world; was it "
                           "replaced by world-to-camera poses?");
    }
    return Assemble(*file, ToolName(), std::move(a), GridResize::kStretch, "");
  }
};

}  // namespace

std::unique_ptr<ReconstructionReader> CreateMegaSamReader() {
  return std::make_unique<MegaSamReader>();
}

}  // namespace reconstruction
}  // namespace geodrive

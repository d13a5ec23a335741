// VGGT (facebookresearch/vggt) demo output, predictions.npz, as
// demo_gradio.py / demo_viser.py write it with np.savez(**predictions):
//   extrinsic (S, 3, 4)  cam_from_world (OpenCV axes; "camera from world" in
//                        VGGT's README), from pose_encoding_to_extri_intri
//   intrinsic (S, 3, 3)  pixels of the network grid, principal point at the
//                        grid centre
//   depth (S, H, W, 1)   z-depth, up to scale (world = first camera)
//   depth_conf (S, H, W) 1 + exp(x) ("expp1", heads/head_act.py)
//   images (S, 3, H, W)  float in [0, 1] (the model input)
// plus world_points*, pose_enc and pose_enc_list (a pickled None: never read).
// The grid is load_and_preprocess_images' "crop" mode: width 518, height
// round(h * 518 / w / 14) * 14 (GridResize::kVggt).

#include "geometry/reconstruction/common.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace reconstruction {
namespace {

class VggtReader : public ReconstructionReader {
 public:
  ReconstructionFormat format() const override {
    return ReconstructionFormat::kVggt;
  }
  std::string ToolName() const override { return "VGGT"; }
  ReconstructionConventions Conventions() const override {
    return {"extrinsic (S,3,4) or (S,4,4) cam_from_world, inverted",
            "depth_conf = 1 + exp(x) -> 1 - 1/c",
            "intrinsic (S,3,3) on the 518-wide network grid (integer-index "
            "pixels); source image: width 518, height round(h*518/w/14)*14, "
            "centre crop to 518",
            "up to scale (LiDAR fit makes it metric)"};
  }
  std::optional<std::string> Locate(const std::string& path) const override {
    std::optional<std::string> file = FindFile(path, {"predictions.npz"});
    if (!file) file = FindFile(path, {".npz"});
    if (file && NpzHasKeys(*file, {"extrinsic", "intrinsic", "depth"}))
      return file;
    return std::nullopt;
  }
  Monst3rFolder Read(const std::string& path,
                     const ReconstructionReadOptions& options) const override {
    const std::optional<std::string> file = Locate(path);
    GEODRIVE_CHECK_INPUT(file, path,
                         ": no VGGT predictions.npz (an npz with extrinsic, "
                         "intrinsic and depth)");
    const NpzReader npz(*file);
    const std::string at = *file + ": ";
    Arrays a;
    a.depth = FloatMaps(*ReadArray(npz, "depth", options), at + "depth", true);
    const int n = static_cast<int>(a.depth.size());
    const int h = a.depth[0].rows, w = a.depth[0].cols;
    a.world_from_cam =
        Poses(*ReadArray(npz, "extrinsic", options), at + "extrinsic", true);
    a.cameras = Cameras(*ReadArray(npz, "intrinsic", options), at + "intrinsic",
                        n, w, h);
    if (auto conf = ReadArray(npz, "depth_conf", options, false))
      a.confidence01 =
          ConfidenceMaps(*conf, at + "depth_conf", ConfidenceScale::kOnePlus);
    if (auto images = ReadArray(npz, "images", options, false))
      a.rgb = Images(*images, at + "images");
    if (options.check_motion_direction) {
      CheckMotionDirection(a.world_from_cam, at + "extrinsic",
                           "VGGT's extrinsic is cam_from_world; was it "
                           "replaced by camera-to-world poses?");
    }
    return Assemble(*file, ToolName(), std::move(a), GridResize::kVggt, "");
  }
};

}  // namespace

std::unique_ptr<ReconstructionReader> CreateVggtReader() {
  return std::make_unique<VggtReader>();
}

}  // namespace reconstruction
}  // namespace geodrive

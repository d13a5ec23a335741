// Depth Anything 3 (ByteDance-Seed/Depth-Anything-3) exports, written by
// utils/export/npz.py with np.savez_compressed:
//   exports/npz/results.npz       image (N,H,W,3) uint8, depth, conf,
//                                 extrinsics, intrinsics
//   exports/mini_npz/results.npz  the same without image
// depth (N, H, W) z-depth (rounded to 6 or 8 decimals); conf (N, H, W)
// rounded to 2 decimals; extrinsics cam_from_world (OpenCV), (N, 3, 4) in the
// README, (N, 4, 4) in a spec comment: both accepted; intrinsics (N, 3, 3) on
// the processed grid (long side 504 by default, sides multiples of 14, the
// whole image resized: GridResize::kStretch). Depth is metres for the metric
// and nested models, up to scale otherwise: the file does not say, so it is
// read as up to scale and the LiDAR fit sets (or confirms) the scale.
// Confidence: values >= 1 are DA3's 1 + exp(x) (1 - 1/c); a map already in
// [0, 1] is taken as is.

#include <cmath>

#include "geometry/reconstruction/common.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace reconstruction {
namespace {

class DepthAnything3Reader : public ReconstructionReader {
 public:
  ReconstructionFormat format() const override {
    return ReconstructionFormat::kDepthAnything3;
  }
  std::string ToolName() const override { return "Depth Anything 3"; }
  ReconstructionConventions Conventions() const override {
    return {"extrinsics (N,3,4) or (N,4,4) cam_from_world, inverted",
            "conf >= 1: 1 + exp(x) -> 1 - 1/c; a map within [0, 1] as is",
            "intrinsics (N,3,3) on the processed grid (the whole source image "
            "resized, long side 504)",
            "up to scale as read (metric models: the LiDAR fit gives ~1)"};
  }
  std::optional<std::string> Locate(const std::string& path) const override {
    std::optional<std::string> file = FindFile(path, {"results.npz"});
    for (const char* sub : {"/exports/npz", "/exports/mini_npz"})
      if (!file) file = FindFile(path + sub, {"results.npz"});
    if (!file) file = FindFile(path, {".npz"});
    if (file && NpzHasKeys(*file, {"depth", "extrinsics", "intrinsics"}))
      return file;
    return std::nullopt;
  }
  Monst3rFolder Read(const std::string& path,
                     const ReconstructionReadOptions& options) const override {
    const std::optional<std::string> file = Locate(path);
    GEODRIVE_CHECK_INPUT(file, path,
                         ": no Depth Anything 3 results.npz (an npz with "
                         "depth, extrinsics and intrinsics; looked in "
                         "exports/npz and exports/mini_npz too)");
    const NpzReader npz(*file);
    const std::string at = *file + ": ";
    Arrays a;
    a.depth = FloatMaps(*ReadArray(npz, "depth", options), at + "depth", true);
    const int n = static_cast<int>(a.depth.size());
    const int h = a.depth[0].rows, w = a.depth[0].cols;
    a.world_from_cam =
        Poses(*ReadArray(npz, "extrinsics", options), at + "extrinsics", true);
    a.cameras = Cameras(*ReadArray(npz, "intrinsics", options),
                        at + "intrinsics", n, w, h);
    if (auto conf = ReadArray(npz, "conf", options, false)) {
      std::vector<cv::Mat> maps = FloatMaps(*conf, at + "conf", false);
      double lo = INFINITY, hi = -INFINITY;
      for (const cv::Mat& m : maps) {
        double mn = 0, mx = 0;
        cv::minMaxLoc(m, &mn, &mx);
        lo = std::min(lo, mn);
        hi = std::max(hi, mx);
      }
      GEODRIVE_CHECK_INPUT(
          lo >= 1 || (lo >= 0 && hi <= 1), at, "conf spans [", lo, ", ", hi,
          "]: neither DA3's 1 + exp(x) (>= 1) nor a [0, 1] confidence");
      const ConfidenceScale scale =
          lo >= 1 ? ConfidenceScale::kOnePlus : ConfidenceScale::kUnit;
      for (cv::Mat& m : maps) m = ConfidenceToUnit(m, scale);
      a.confidence01 = std::move(maps);
    }
    if (auto images = ReadArray(npz, "image", options, false))
      a.rgb = Images(*images, at + "image");
    if (options.check_motion_direction) {
      CheckMotionDirection(a.world_from_cam, at + "extrinsics",
                           "DA3's extrinsics are cam_from_world; was the file "
                           "rewritten with camera-to-world poses?");
    }
    return Assemble(*file, ToolName(), std::move(a), GridResize::kStretch, "");
  }
};

}  // namespace

std::unique_ptr<ReconstructionReader> CreateDepthAnything3Reader() {
  return std::make_unique<DepthAnything3Reader>();
}

}  // namespace reconstruction
}  // namespace geodrive

// Our generic npz: the escape hatch for any tool (docs/RECONSTRUCTIONS.md has
// the writer). Keys:
//   depth (N, H, W)               z-depth (float16/32/64); <= 0 or NaN =
//                                 no depth
//   intrinsics (N, 3, 3) | (3, 3) pixels of the depth grid, integer-index
//                                 (OpenCV) principal point
//   cam_c2w | cam_w2c (N, 4, 4)   exactly one: camera-to-world or
//                                 world-to-camera, OpenCV axes
//   conf (N, H, W)                optional; its scale in conf_scale
//   conf_scale                    optional str: "unit" (default, [0, 1]),
//                                 "1+exp" (1 - 1/c), "log" (1 - exp(-v)),
//                                 "logit" (sigmoid)
//   images (N, H, W, 3) uint8     optional colours
//   dynamic_mask (N, H, W)        optional, nonzero = moving object
//   units                         optional str: "metres" or "relative"
//                                 (default)
// The depth grid is the whole source image resized (GridResize::kStretch).
// A GEN3C export clip folder (depth.npz, camera.npz, rgb.mp4) goes to its own
// reader (gen3c_export.cc) under this format's name.

#include "geometry/reconstruction/common.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace reconstruction {
namespace {

class GenericNpzReader : public ReconstructionReader {
 public:
  ReconstructionFormat format() const override {
    return ReconstructionFormat::kGenericNpz;
  }
  std::string ToolName() const override { return "generic npz"; }
  ReconstructionConventions Conventions() const override {
    return {"cam_c2w (as is) or cam_w2c (inverted), (N,4,4) or (N,3,4)",
            "conf with conf_scale: unit (default), 1+exp, log or logit",
            "intrinsics (N,3,3) or (3,3) in pixels of the depth grid (the "
            "whole source image resized)",
            "units: \"metres\" or \"relative\" (default)"};
  }
  std::optional<std::string> Locate(const std::string& path) const override {
    if (auto gen3c = CreateGen3cExportReader()->Locate(path)) return gen3c;
    std::optional<std::string> file = FindFile(path, {".npz"});
    if (!file) return std::nullopt;
    if (NpzHasKeys(*file, {"depth", "intrinsics", "cam_c2w"}) ||
        NpzHasKeys(*file, {"depth", "intrinsics", "cam_w2c"}))
      return file;
    return std::nullopt;
  }
  Monst3rFolder Read(const std::string& path,
                     const ReconstructionReadOptions& options) const override {
    if (HasGen3cExportFiles(path))
      return CreateGen3cExportReader()->Read(path, options);
    const std::optional<std::string> file =
        FindFile(path, {".npz"}).value_or(path);
    const NpzReader npz(*file);
    const std::string at = *file + ": ";
    const bool c2w = npz.Has("cam_c2w"), w2c = npz.Has("cam_w2c");
    GEODRIVE_CHECK_INPUT(c2w != w2c, *file,
                         c2w ? ": both cam_c2w and cam_w2c: keep one"
                             : ": no poses (cam_c2w or cam_w2c)");
    Arrays a;
    a.depth = FloatMaps(*ReadArray(npz, "depth", options), at + "depth", true);
    const int n = static_cast<int>(a.depth.size());
    const int h = a.depth[0].rows, w = a.depth[0].cols;
    const std::string pose_key = c2w ? "cam_c2w" : "cam_w2c";
    a.world_from_cam =
        Poses(*ReadArray(npz, pose_key, options), at + pose_key, w2c);
    a.cameras = Cameras(*ReadArray(npz, "intrinsics", options),
                        at + "intrinsics", n, w, h);
    ConfidenceScale scale = ConfidenceScale::kUnit;
    if (npz.Has("conf_scale"))
      scale =
          ParseConfidenceScale(npz.ReadString("conf_scale"), at + "conf_scale");
    if (auto conf = ReadArray(npz, "conf", options, false)) {
      if (scale == ConfidenceScale::kUnit) {
        for (const cv::Mat& m : FloatMaps(*conf, at + "conf", false)) {
          double lo = 0, hi = 0;
          cv::minMaxLoc(m, &lo, &hi);
          GEODRIVE_CHECK_INPUT(lo >= 0 && hi <= 1, at, "conf spans [", lo, ", ",
                               hi,
                               "] but conf_scale is \"unit\" ([0, 1]); set "
                               "conf_scale to 1+exp, log or logit");
        }
      }
      a.confidence01 = ConfidenceMaps(*conf, at + "conf", scale);
    }
    if (auto images = ReadArray(npz, "images", options, false))
      a.rgb = Images(*images, at + "images");
    if (auto mask = ReadArray(npz, "dynamic_mask", options, false)) {
      for (cv::Mat& m : FloatMaps(*mask, at + "dynamic_mask", false)) {
        cv::Mat u8;
        cv::compare(m, 0, u8, cv::CMP_NE);  // 255 where nonzero
        a.dynamic_mask.push_back(u8);
      }
    }
    std::string units = "relative";
    if (npz.Has("units")) units = npz.ReadString("units");
    GEODRIVE_CHECK_INPUT(units == "metres" || units == "relative", at,
                         "units is \"", units,
                         "\", expected \"metres\" or \"relative\"");
    if (options.check_motion_direction) {
      CheckMotionDirection(a.world_from_cam, at + pose_key,
                           c2w ? "if they are world-to-camera, store them as "
                                 "cam_w2c"
                               : "if they are camera-to-world, store them as "
                                 "cam_c2w");
    }
    return Assemble(*file, ToolName(), std::move(a), GridResize::kStretch,
                    units == "metres" ? "metres" : "");
  }
};

}  // namespace

std::unique_ptr<ReconstructionReader> CreateGenericNpzReader() {
  return std::make_unique<GenericNpzReader>();
}

}  // namespace reconstruction
}  // namespace geodrive

// Our GEN3C export read back as a reconstruction (read through the generic
// npz's name, "npz": generic_npz.cc hands a GEN3C clip folder to this reader).
// The clip folder dataset/export_gen3c.cc writes (PAIR/gen3c/, linked as
// OUT/gen3c/<clip>/):
//   depth.npz    depth (T, H, W) float32: z-depth in metres, 0 = none (no
//                point drawn, or beyond GEN3C's 100 m)
//   camera.npz   w2c (T, 4, 4) float32: cam_from_world, OpenCV axes, in the
//                scene frame (camera 0 at frame 0): inverted here;
//                intrinsics (T, 3, 3) float32: pixels of the H x W grid
//                (704 x 1280 from the export)
//   rgb.mp4      T camera frames of W x H: the images
//   mask.npz     not read (it is depth > 0)
// The grid is the source image centre-cropped to W:H and resized
// (GridResize::kCenterCrop, the export's framing). Every size is checked
// against the others on the files' headers before anything is read.

#include <filesystem>

#include "geometry/reconstruction/common.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace reconstruction {
namespace fs = std::filesystem;

namespace gen3c_export {
namespace {

// The clip folder of `path`: the folder itself, or the folder of its
// depth.npz; empty when `path` is neither.
std::string ClipFolder(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) return path;
  const fs::path p(path);
  if (p.filename() == "depth.npz" && fs::is_regular_file(p, ec))
    return p.parent_path().empty() ? "." : p.parent_path().string();
  return "";
}

std::string Shape(const std::vector<int64_t>& shape) {
  std::string s = "(";
  for (size_t i = 0; i < shape.size(); ++i)
    s += (i ? ", " : "") + std::to_string(shape[i]);
  return s + (shape.size() == 1 ? ",)" : ")");
}

// The header of `key` in `npz`: float32 of shape (frames, rest...), where
// `frames` < 0 takes the array's own count and a `rest` side < 0 any size
// (H, W); `other` names the file `frames` comes from.
NpyHeader CheckedHeader(const NpzReader& npz,
                        const std::string& key,
                        int64_t frames,
                        const std::vector<int64_t>& rest,
                        const std::string& other) {
  GEODRIVE_CHECK_INPUT(npz.Has(key), npz.path(), ": no array '", key, "'");
  const NpyHeader h = npz.Header(key);
  const std::string what = npz.path() + ": " + key;
  GEODRIVE_CHECK_INPUT(h.dtype == NpyDtype::kFloat32, what, " is ",
                       NpyDtypeDescr(h.dtype), ", expected float32 (<f4)");
  bool ok = h.shape.size() == rest.size() + 1 && h.shape[0] >= 1;
  for (size_t i = 0; ok && i < rest.size(); ++i)
    ok = rest[i] < 0 ? h.shape[i + 1] >= 1 : h.shape[i + 1] == rest[i];
  std::string want = "(T";
  for (size_t i = 0; i < rest.size(); ++i)
    want += rest[i] >= 0 ? ", " + std::to_string(rest[i])
                         : std::string(i == 0 ? ", H" : ", W");
  GEODRIVE_CHECK_INPUT(ok, what, ": shape ", Shape(h.shape), ", expected ",
                       want, ")");
  GEODRIVE_CHECK_INPUT(frames < 0 || h.shape[0] == frames, what, " has ",
                       h.shape[0], " frames but ", other, " has ", frames);
  return h;
}

class Gen3cExportReader : public ReconstructionReader {
 public:
  ReconstructionFormat format() const override {
    return ReconstructionFormat::kGenericNpz;
  }
  std::string ToolName() const override { return "GEN3C export"; }
  ReconstructionConventions Conventions() const override {
    return {"camera.npz w2c (T,4,4) float32 cam_from_world: inverted",
            "none: every pixel with depth 1",
            "camera.npz intrinsics (T,3,3) float32 in pixels of depth.npz's "
            "grid (704x1280 from the export: the source image centre-cropped "
            "to 1280:704 and resized); images from rgb.mp4",
            "metres; depth 0 = none (no point, or beyond 100 m)"};
  }
  std::optional<std::string> Locate(const std::string& path) const override {
    const std::string dir = ClipFolder(path);
    if (dir.empty()) return std::nullopt;
    std::error_code ec;
    const std::string depth = dir + "/depth.npz";
    if (!fs::is_regular_file(dir + "/rgb.mp4", ec) ||
        !NpzHasKeys(depth, {"depth"}) ||
        !NpzHasKeys(dir + "/camera.npz", {"w2c", "intrinsics"}))
      return std::nullopt;
    return depth;
  }
  Monst3rFolder Read(const std::string& path,
                     const ReconstructionReadOptions& options) const override {
    const std::string dir = ClipFolder(path);
    GEODRIVE_CHECK_INPUT(!dir.empty(), path,
                         ": not a GEN3C export clip folder (depth.npz, "
                         "camera.npz, rgb.mp4)");
    const NpzReader depth_npz(dir + "/depth.npz");
    const NpzReader camera_npz(dir + "/camera.npz");
    // Every size from the headers first.
    const NpyHeader dh = CheckedHeader(depth_npz, "depth", -1, {-1, -1}, "");
    const int64_t t = dh.shape[0];
    GEODRIVE_CHECK_INPUT(
        t <= (1 << 20) && dh.shape[1] <= 16384 && dh.shape[2] <= 16384,
        depth_npz.path(), ": depth shape ", Shape(dh.shape),
        " is over the limits (frames <= 1048576, sides <= 16384)");
    const int h = static_cast<int>(dh.shape[1]);
    const int w = static_cast<int>(dh.shape[2]);
    CheckedHeader(camera_npz, "w2c", t, {4, 4}, "depth.npz");
    CheckedHeader(camera_npz, "intrinsics", t, {3, 3}, "depth.npz");
    Arrays a;
    if (options.images) {
      const ReconstructionVideoDecoder decode = GetReconstructionVideoDecoder();
      GEODRIVE_CHECK_INPUT(decode, dir,
                           "/rgb.mp4: this program decodes no video (GEN3C "
                           "export folders are read by build-dataset, "
                           "render, generate and the Python module)");
      // The video's header is checked against T, W and H before it is
      // decoded; the arrays' declared sizes against the limit before they
      // are read.
      a.rgb = decode(dir + "/rgb.mp4", t, w, h);
    }
    const std::string w2c_what = camera_npz.path() + ": w2c";
    a.depth = FloatMaps(*ReadArray(depth_npz, "depth", options),
                        depth_npz.path() + ": depth", true);
    a.world_from_cam =
        Poses(*ReadArray(camera_npz, "w2c", options), w2c_what, true);
    a.cameras =
        Cameras(*ReadArray(camera_npz, "intrinsics", options),
                camera_npz.path() + ": intrinsics", static_cast<int>(t), w, h);
    if (options.check_motion_direction) {
      CheckMotionDirection(a.world_from_cam, w2c_what,
                           "w2c must be cam_from_world (world-to-camera)");
    }
    return Assemble(dir, ToolName(), std::move(a), GridResize::kCenterCrop,
                    "metres");
  }
};

}  // namespace
}  // namespace gen3c_export

bool HasGen3cExportFiles(const std::string& path) {
  const std::string dir = gen3c_export::ClipFolder(path);
  std::error_code ec;
  return !dir.empty() && fs::is_regular_file(dir + "/depth.npz", ec) &&
         fs::is_regular_file(dir + "/camera.npz", ec) &&
         fs::is_regular_file(dir + "/rgb.mp4", ec);
}

std::unique_ptr<ReconstructionReader> CreateGen3cExportReader() {
  return std::make_unique<gen3c_export::Gen3cExportReader>();
}

}  // namespace reconstruction
}  // namespace geodrive

// CUT3R (CUT3R/CUT3R) demo output folder, one file per frame NNNNNN:
//   depth/NNNNNN.npy   (H, W) z-depth, up to scale
//   conf/NNNNNN.npy    (H, W) confidence in [1, inf) (DUSt3R's 1 + exp(x))
//   color/NNNNNN.png   the network input image (optional)
//   camera/NNNNNN.npz  pose (4, 4) camera-to-world (OpenCV), intrinsics (3, 3)
//                      in pixels of the grid, principal point (W//2, H//2)
// Frames are the depth files' numbers in numeric order. The grid is DUSt3R's
// load_images(size=512) (GridResize::kMonst3r).

#include <filesystem>
#include <map>
#include <regex>

#include "geometry/image_io.h"
#include "geometry/reconstruction/common.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace reconstruction {
namespace {

namespace fs = std::filesystem;

// Frame number -> file, for the files of `dir` named NNNN<ext>. The numbers
// must be unique ("0.npy" beside "000000.npy" is frame 0 twice, and which one
// the folder lists first is arbitrary) and consecutive (a gap is a lost
// frame): otherwise an InputError says which.
std::map<long, std::string> Numbered(const std::string& dir,
                                     const std::string& ext) {
  std::map<long, std::string> out;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return out;
  const std::regex name("(\\d{1,9})\\" + ext);
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    std::smatch m;
    const std::string file = e.path().filename().string();
    if (e.is_regular_file() && std::regex_match(file, m, name)) {
      const auto [it, added] =
          out.emplace(std::stol(m[1].str()), e.path().string());
      GEODRIVE_CHECK_INPUT(added, dir, ": frame ", it->first, " twice (",
                           fs::path(it->second).filename().string(), " and ",
                           file, ")");
    }
  }
  long expect = out.empty() ? 0 : out.begin()->first;
  for (const auto& entry : out) {
    GEODRIVE_CHECK_INPUT(entry.first == expect, dir, ": frame ", expect,
                         " is missing (frames ", out.begin()->first, "..",
                         out.rbegin()->first, " otherwise present)");
    ++expect;
  }
  return out;
}

class Cut3rReader : public ReconstructionReader {
 public:
  ReconstructionFormat format() const override {
    return ReconstructionFormat::kCut3r;
  }
  std::string ToolName() const override { return "CUT3R"; }
  ReconstructionConventions Conventions() const override {
    return {"camera/NNNNNN.npz pose (4,4) camera_to_world, as is",
            "conf/NNNNNN.npy in [1, inf) -> 1 - 1/c",
            "camera/NNNNNN.npz intrinsics (3,3) on the 512-long-side grid "
            "(DUSt3R's load_images)",
            "up to scale (LiDAR fit makes it metric)"};
  }
  std::optional<std::string> Locate(const std::string& path) const override {
    std::error_code ec;
    if (fs::is_directory(path + "/depth", ec) &&
        fs::is_directory(path + "/camera", ec))
      return path;
    return std::nullopt;
  }
  Monst3rFolder Read(const std::string& path,
                     const ReconstructionReadOptions& options) const override {
    GEODRIVE_CHECK_INPUT(Locate(path), path,
                         ": not a CUT3R output folder (needs depth/ and "
                         "camera/)");
    const auto depth = Numbered(path + "/depth", ".npy");
    const auto conf = Numbered(path + "/conf", ".npy");
    const auto color = Numbered(path + "/color", ".png");
    const auto camera = Numbered(path + "/camera", ".npz");
    GEODRIVE_CHECK_INPUT(!depth.empty(), path, "/depth: no NNNNNN.npy files");
    Arrays a;
    for (const auto& entry : depth) {
      // Named copies: clang 14 cannot capture structured bindings.
      const long index = entry.first;
      const std::string& file = entry.second;
      const std::string id = std::to_string(index);
      auto need = [&](const std::map<long, std::string>& set,
                      const char* kind) -> const std::string& {
        auto it = set.find(index);
        GEODRIVE_CHECK_INPUT(it != set.end(), path, "/", kind, ": frame ", id,
                             " is missing (", file, " exists)");
        return it->second;
      };
      a.depth.push_back(FloatMapFromNpy(file, true, options));
      const int h = a.depth.back().rows, w = a.depth.back().cols;
      const std::string& cam_file = need(camera, "camera");
      const NpzReader npz(cam_file);
      const NpyArray pose = *ReadArray(npz, "pose", options);
      a.world_from_cam.push_back(
          Poses(pose, cam_file + ": pose", /*w2c=*/false).at(0));
      a.cameras.push_back(Cameras(*ReadArray(npz, "intrinsics", options),
                                  cam_file + ": intrinsics", 1, w, h)
                              .at(0));
      if (!conf.empty()) {
        const std::string& c = need(conf, "conf");
        a.confidence01.push_back(ConfidenceToUnit(
            FloatMapFromNpy(c, false, options), ConfidenceScale::kOnePlus));
      }
      if (!color.empty()) a.rgb.push_back(ReadImageRgb(need(color, "color")));
    }
    GEODRIVE_CHECK_INPUT(camera.size() == depth.size(), path,
                         "/camera: ", camera.size(), " files for ",
                         depth.size(), " depth maps");
    if (options.check_motion_direction) {
      CheckMotionDirection(a.world_from_cam, path + "/camera",
                           "CUT3R's pose is camera-to-world; was it replaced "
                           "by world-to-camera poses?");
    }
    return Assemble(path, ToolName(), std::move(a), GridResize::kMonst3r, "");
  }
};

}  // namespace

std::unique_ptr<ReconstructionReader> CreateCut3rReader() {
  return std::make_unique<Cut3rReader>();
}

}  // namespace reconstruction
}  // namespace geodrive

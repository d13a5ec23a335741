// MonST3R output folders through the reconstruction interface
// (Monst3rFolder::Open, geometry/monst3r.h).

#include <filesystem>

#include "geometry/reconstruction/common.h"

namespace geodrive {
namespace reconstruction {
namespace {

class Monst3rReader : public ReconstructionReader {
 public:
  ReconstructionFormat format() const override {
    return ReconstructionFormat::kMonst3r;
  }
  std::string ToolName() const override { return "MonST3R"; }
  ReconstructionConventions Conventions() const override {
    return {"pred_traj.txt `t x y z qw qx qy qz` (w first) camera_to_world",
            "conf_N.npy = log(c), c = 1 + exp(x) -> 1 - exp(-v)",
            "pred_intrinsics.txt, one K per frame, on the 512-long-side grid",
            "up to scale (LiDAR fit makes it metric)"};
  }
  std::optional<std::string> Locate(const std::string& path) const override {
    std::error_code ec;
    if (std::filesystem::is_regular_file(path + "/pred_traj.txt", ec))
      return path;
    return std::nullopt;
  }
  Monst3rFolder Read(const std::string& path,
                     const ReconstructionReadOptions&) const override {
    return Monst3rFolder::Open(path);
  }
};

}  // namespace

std::unique_ptr<ReconstructionReader> CreateMonst3rReader() {
  return std::make_unique<Monst3rReader>();
}

}  // namespace reconstruction
}  // namespace geodrive

#include "geometry/trajectory_json.h"

#include <cmath>
#include <filesystem>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>

#include "geometry/reconstruction.h"
#include "geometry/trajectory_io.h"
#include "geometry/util/files.h"
#include "geometry/util/input_file.h"
#include "geometry/util/json_fields.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

using json = nlohmann::json;
using internal::JsonInt;
using internal::kMaxImageSide;
using internal::JsonNumber;
using internal::JsonVector;

}  // namespace

Trajectory ReadTrajectoryJson(const std::string& path,
                              TrajectoryFileInfo* info) {
  const json root = internal::ReadJsonObjectFile(path);
  if (internal::JsonString(path, root, "format", "") != "geodrive-trajectory") {
    ThrowInputError(path, "\"format\" must be \"geodrive-trajectory\"");
  }
  if (!root.contains("version") || !root["version"].is_number_integer() ||
      root["version"] != 1) {
    ThrowInputError(path, "unsupported \"version\" (expected 1)");
  }
  if (root.contains("convention") && root["convention"] != "world_from_cam") {
    ThrowInputError(path, "\"convention\" must be \"world_from_cam\"");
  }
  TrajectoryFileInfo file_info;
  if (root.contains("units")) {
    if (!root["units"].is_string())
      ThrowInputError(path, "\"units\" must be a string");
    file_info.units = root["units"].get<std::string>();
  }
  if (root.contains("camera")) {
    const json& c = root["camera"];
    if (!c.is_object()) ThrowInputError(path, "\"camera\" must be an object");
    for (const char* key : {"fx", "fy", "cx", "cy", "width", "height"}) {
      if (!c.contains(key))
        ThrowInputError(path, "camera: missing \"", key, "\"");
    }
    if (c.contains("pixel_convention") &&
        c["pixel_convention"] != "integer-index") {
      ThrowInputError(
          path, "camera: only pixel_convention \"integer-index\" is supported");
    }
    PinholeCamera cam(
        JsonNumber(path, c["fx"], "camera.fx"),
        JsonNumber(path, c["fy"], "camera.fy"),
        JsonNumber(path, c["cx"], "camera.cx"),
        JsonNumber(path, c["cy"], "camera.cy"),
        static_cast<int>(
            JsonInt(path, c["width"], "camera.width", 1, kMaxImageSide)),
        static_cast<int>(
            JsonInt(path, c["height"], "camera.height", 1, kMaxImageSide)));
    cam.Check(path + ": camera");
    file_info.camera = cam;
  }
  if (!root.contains("frames") || !root["frames"].is_array()) {
    ThrowInputError(path, "\"frames\" must be an array");
  }
  const json& frames = root["frames"];
  if (frames.empty()) ThrowInputError(path, "\"frames\" is empty");
  Trajectory trajectory;
  for (size_t i = 0; i < frames.size(); ++i) {
    const std::string where = "frames[" + std::to_string(i) + "]";
    const json& f = frames[i];
    if (!f.is_object()) ThrowInputError(path, where, " must be an object");
    const double t = f.contains("t") ? JsonNumber(path, f["t"], where + ".t")
                                     : static_cast<double>(i);
    if (!f.contains("position"))
      ThrowInputError(path, where, ": missing \"position\"");
    const Eigen::Vector3d position =
        JsonVector<3>(path, f["position"], where + ".position");
    Eigen::Quaterniond q;
    const bool has_q = f.contains("quaternion_wxyz"),
               has_r = f.contains("rotation");
    if (has_q == has_r) {
      ThrowInputError(
          path, where,
          ": give exactly one of \"quaternion_wxyz\" or \"rotation\"");
    }
    if (has_q) {
      const Eigen::Vector4d wxyz =
          JsonVector<4>(path, f["quaternion_wxyz"], where + ".quaternion_wxyz");
      if (std::abs(wxyz.norm() - 1.0) > 1e-3) {
        ThrowInputError(path, where, ": quaternion is not unit norm (",
                        wxyz.norm(), "), the rotation is not orthonormal");
      }
      q = QuaternionFromWxyz(wxyz.normalized());
    } else {
      const json& r = f["rotation"];
      if (!r.is_array() || r.size() != 3)
        ThrowInputError(path, where, ".rotation must be 3 rows");
      Eigen::Matrix3d m;
      for (int row = 0; row < 3; ++row) {
        m.row(row) = JsonVector<3>(
            path, r[row], where + ".rotation[" + std::to_string(row) + "]");
      }
      const double err = (m.transpose() * m - Eigen::Matrix3d::Identity())
                             .cwiseAbs()
                             .maxCoeff();
      if (err > 1e-4 || m.determinant() < 0) {
        ThrowInputError(
            path, where,
            ": rotation is not orthonormal with det +1 (|RᵀR - I| = ", err,
            ", det ", m.determinant(), ")");
      }
      q = Eigen::Quaterniond(m).normalized();
    }
    if (i > 0 && !(t > trajectory.timestamps.back())) {
      ThrowInputError(path, where, ": timestamps must be strictly increasing");
    }
    trajectory.Add(t, Rigid3d(q, position));
  }
  if (info) *info = file_info;
  return trajectory;
}

void WriteTrajectoryJson(const std::string& path,
                         const Trajectory& trajectory,
                         const TrajectoryFileInfo& info) {
  trajectory.Check(path);
  json root;
  root["format"] = "geodrive-trajectory";
  root["version"] = 1;
  root["convention"] = "world_from_cam";
  root["units"] = info.units;
  if (info.camera) {
    const PinholeCamera& c = *info.camera;
    root["camera"] = {{"fx", c.fx},
                      {"fy", c.fy},
                      {"cx", c.cx},
                      {"cy", c.cy},
                      {"width", c.width},
                      {"height", c.height},
                      {"pixel_convention", "integer-index"}};
  }
  json frames = json::array();
  for (size_t i = 0; i < trajectory.size(); ++i) {
    const Rigid3d& p = trajectory.world_from_cam[i];
    const Eigen::Vector4d q = QuaternionToWxyz(p.rotation.normalized());
    frames.push_back(
        {{"t", trajectory.timestamps[i]},
         {"position",
          {p.translation.x(), p.translation.y(), p.translation.z()}},
         {"quaternion_wxyz", {q[0], q[1], q[2], q[3]}}});
  }
  root["frames"] = frames;
  WriteFileAtomic(path, root.dump(2) + "\n");
}

namespace {
// Numbers on the first non-comment line of a text file (0 if none).
size_t FirstRowColumns(const std::string& path) {
  InputFileStream in(path);
  std::string line;
  while (std::getline(in, line)) {
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ls(line);
    std::string token;
    size_t n = 0;
    while (ls >> token) ++n;
    return n;
  }
  return 0;
}
}  // namespace

TrajectoryFormat ParseTrajectoryFormat(const std::string& text) {
  if (text == "auto") return TrajectoryFormat::kAuto;
  if (text == "json") return TrajectoryFormat::kJson;
  if (text == "tum") return TrajectoryFormat::kTum;
  if (text == "monst3r") return TrajectoryFormat::kMonst3r;
  if (text == "kitti") return TrajectoryFormat::kKitti;
  if (text == "colmap") return TrajectoryFormat::kColmap;
  if (text == "reconstruction") return TrajectoryFormat::kReconstruction;
  ThrowInputError("trajectory format", "'", text,
                  "' is not one of auto, json, tum, monst3r, kitti, colmap, "
                  "reconstruction");
}

TrajectoryFormat DetectTrajectoryFormat(const std::string& path) {
  namespace fs = std::filesystem;
  const std::string name = fs::path(path).filename().string();
  std::error_code ec;
  if (EndsWith(name, ".json")) return TrajectoryFormat::kJson;
  if (name == "pred_traj.txt") return TrajectoryFormat::kMonst3r;
  if (name == "images.txt") return TrajectoryFormat::kColmap;
  if (EndsWith(name, ".npz") || fs::is_directory(path, ec))
    return TrajectoryFormat::kReconstruction;
  return FirstRowColumns(path) == 12 ? TrajectoryFormat::kKitti
                                     : TrajectoryFormat::kTum;
}

Trajectory ReadTrajectoryAny(const std::string& path,
                             TrajectoryFormat format,
                             TrajectoryFileInfo* info) {
  namespace fs = std::filesystem;
  if (format == TrajectoryFormat::kAuto) format = DetectTrajectoryFormat(path);
  if (format == TrajectoryFormat::kJson) return ReadTrajectoryJson(path, info);
  if (info) {
    *info = TrajectoryFileInfo();
    info->units = format == TrajectoryFormat::kMonst3r ? "monst3r"
                  : format == TrajectoryFormat::kKitti ? "metres"
                                                       : "unknown";
  }
  Trajectory t;
  switch (format) {
    case TrajectoryFormat::kMonst3r:
      t = ReadMonst3rTrajectory(path);
      break;
    case TrajectoryFormat::kKitti: {
      // KITTI keeps times.txt in the sequence folder; use one beside the
      // poses when its count matches.
      const std::string times =
          (fs::path(path).parent_path() / "times.txt").string();
      std::error_code ec;
      t = ReadKittiTrajectory(
          path, fs::is_regular_file(times, ec) && FirstRowColumns(times) == 1
                    ? times
                    : "");
      break;
    }
    case TrajectoryFormat::kColmap:
      t = ReadColmapTrajectory(path);
      break;
    case TrajectoryFormat::kReconstruction: {
      const auto recon = DetectReconstructionFormat(path);
      GEODRIVE_CHECK_INPUT(recon, path,
                           ": not a reconstruction this reader recognises "
                           "(VGGT, DA3, MegaSaM or generic npz; a CUT3R or "
                           "MonST3R folder)");
      const Monst3rFolder folder = ReadReconstruction(*recon, path);
      t = folder.trajectory();
      if (info && folder.units() == "metres") info->units = "metres";
      break;
    }
    default:
      t = ReadTumTrajectory(path);
  }
  GEODRIVE_CHECK_INPUT(!t.empty(), path, ": trajectory has no poses");
  return t;
}

}  // namespace geodrive

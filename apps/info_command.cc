// `geodrive info FILE`: prints what a file is.

#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "apps/cli/cli.h"
#include "geometry/image_io.h"
#include "geometry/npy.h"
#include "geometry/point_cloud_io.h"
#include "geometry/trajectory_io.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string ShapeString(const std::vector<int64_t>& shape) {
  std::ostringstream os;
  os << "(";
  for (size_t i = 0; i < shape.size(); ++i) os << (i ? ", " : "") << shape[i];
  if (shape.size() == 1) os << ",";
  os << ")";
  return os.str();
}

void PrintCloud(const std::string& path,
                const std::string& kind,
                const PointCloud& cloud) {
  std::cout << path << ": " << kind << ", " << cloud.size() << " points\n";
  if (cloud.empty()) return;
  const auto box = cloud.Bounds();
  std::cout << std::fixed << std::setprecision(3) << "  bounds min ("
            << box.min().x() << ", " << box.min().y() << ", " << box.min().z()
            << ") max (" << box.max().x() << ", " << box.max().y() << ", "
            << box.max().z() << ")\n";
  auto range = [](const std::vector<float>& v) {
    float lo = v[0], hi = v[0];
    for (float x : v) lo = std::min(lo, x), hi = std::max(hi, x);
    return std::make_pair(lo, hi);
  };
  if (cloud.HasIntensity()) {
    auto [lo, hi] = range(cloud.intensity);
    std::cout << "  intensity " << lo << " .. " << hi << "\n";
  }
  if (cloud.HasRing()) {
    auto [lo, hi] = range(cloud.ring);
    std::cout << std::setprecision(0) << "  ring " << lo << " .. " << hi
              << "\n";
  }
  std::cout << "  colors: " << (cloud.HasColors() ? "yes" : "no") << "\n";
}

int RunInfo(const std::string& path, const std::string& format) {
  GEODRIVE_CHECK_INPUT(std::filesystem::exists(path), path, ": no such file");
  GEODRIVE_CHECK_INPUT(!std::filesystem::is_directory(path), path,
                       ": is a directory (expected a file)");
  const std::string name = std::filesystem::path(path).filename().string();
  if (EndsWith(name, ".npy")) {
    // The header only, and the file size against the data it declares:
    // describing a 4 GB array does not read it.
    const NpyHeader h = ReadNpyHeader(path);
    const uint64_t have = FileSizeOrThrow(path) - h.data_offset;
    const uint64_t need =
        static_cast<uint64_t>(h.NumElements()) * NpyDtypeSize(h.dtype);
    GEODRIVE_CHECK_INPUT(have >= need, path, ": truncated: header says ", need,
                         " bytes of data, file has ", have);
    std::cout << path << ": npy v" << h.major_version << "." << h.minor_version
              << ", dtype "
              << (h.big_endian ? ">" + NpyDtypeDescr(h.dtype).substr(1)
                               : NpyDtypeDescr(h.dtype))
              << ", shape " << ShapeString(h.shape) << ", "
              << (h.fortran_order ? "Fortran" : "C") << " order, "
              << h.NumElements() << " elements\n";
    return kExitOk;
  }
  if (EndsWith(name, ".pcd.bin")) {
    PrintCloud(path, "nuScenes LIDAR_TOP sweep (float32 x 5)",
               ReadNuscenesLidarBin(path));
    return kExitOk;
  }
  if (EndsWith(name, ".bin")) {
    PrintCloud(path, "KITTI velodyne scan (float32 x 4)",
               ReadKittiVelodyneBin(path));
    return kExitOk;
  }
  if (EndsWith(name, ".ply") || EndsWith(name, ".pcd")) {
    PrintCloud(path,
               EndsWith(name, ".ply") ? "PLY point cloud" : "PCD point cloud",
               ReadPointCloud(path));
    return kExitOk;
  }
  if (EndsWith(name, ".png") || EndsWith(name, ".jpg") ||
      EndsWith(name, ".jpeg")) {
    const cv::Mat image = ReadImageUnchanged(path);
    std::cout << path << ": image " << image.cols << "x" << image.rows << ", "
              << image.channels() << " channel(s), "
              << (image.depth() == CV_8U ? "8-bit" : "16-bit or more") << "\n";
    return kExitOk;
  }
  if (EndsWith(name, ".txt")) {
    std::string fmt = format;
    if (fmt == "auto") {
      if (name.find("intrinsics") != std::string::npos)
        fmt = "intrinsics";
      else if (name == "pred_traj.txt")
        fmt = "monst3r";
      else
        fmt = "tum";
    }
    if (fmt == "intrinsics") {
      const auto cams = ReadMonst3rIntrinsics(path, 1, 1);
      std::cout << path << ": MonST3R intrinsics, " << cams.size() << " frames";
      if (!cams.empty())
        std::cout << ", fx " << cams[0].fx << " fy " << cams[0].fy << " cx "
                  << cams[0].cx << " cy " << cams[0].cy;
      std::cout << "\n";
      return kExitOk;
    }
    const Trajectory traj = fmt == "monst3r" ? ReadMonst3rTrajectory(path)
                                             : ReadTumTrajectory(path);
    std::cout << path << ": "
              << (fmt == "monst3r" ? "MonST3R trajectory (t x y z qw qx qy qz)"
                                   : "TUM trajectory (t x y z qx qy qz qw)")
              << ", " << traj.size() << " poses, length " << traj.Length()
              << ", duration " << traj.Duration() << "\n";
    return kExitOk;
  }
  ThrowInputError(
      path,
      "unknown file type (expected .npy, .pcd.bin, .bin, .ply, .pcd, .png, "
      ".jpg or a .txt trajectory)");
}

CommandRunner SetupInfo(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  auto format = std::make_shared<std::string>("auto");
  app.add_option("file", *path,
                 "File to describe (.npy, .pcd.bin, .bin, .ply, .pcd, image, "
                 "trajectory .txt)")
      ->required();
  app.add_option("--format", *format,
                 "For .txt files: monst3r (t x y z qw qx qy qz), tum (t x y z "
                 "qx qy qz qw), "
                 "intrinsics, or auto (pred_traj.txt = monst3r, *intrinsics* = "
                 "intrinsics, "
                 "else tum)")
      ->check(CLI::IsMember({"auto", "monst3r", "tum", "intrinsics"}));
  return [path, format] { return RunInfo(*path, *format); };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    info,
    "info",
    "Print what a file is (npy, point cloud, trajectory, image)",
    SetupInfo);

}  // namespace geodrive

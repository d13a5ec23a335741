// `geodrive info FILE`: prints what a file is.

#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include "apps/cli/cli.h"
#include "apps/info_waymo.h"
#include "geodrive_version.h"
#include "geometry/image_io.h"
#include "geometry/npy.h"
#include "geometry/npz.h"
#include "geometry/point_cloud_io.h"
#include "geometry/reconstruction.h"
#include "geometry/trajectory_io.h"
#include "geometry/trajectory_json.h"
#include "geometry/util/files.h"
#include "geometry/util/plugin.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

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
  if (cloud.HasFootprints()) {
    auto [lo, hi] = range(cloud.footprints);
    std::cout << std::setprecision(4) << "  capture footprints " << lo << " .. "
              << hi << (cloud.footprint_u.empty() ? "" : ", with surface axes")
              << "\n";
  }
  std::cout << "  colors: " << (cloud.HasColors() ? "yes" : "no") << "\n";
}

// A reconstruction tool's output (geometry/reconstruction.h): what it is and
// how it is converted.
void PrintReconstruction(const std::string& path, ReconstructionFormat format) {
  const auto reader = CreateReconstructionReaderFor(format, path);
  ReconstructionReadOptions options;
  options.images = false;  // this binary decodes no video (GEN3C's rgb.mp4)
  const Monst3rFolder r = reader->Read(path, options);
  const PinholeCamera& c = r.cameras().front();
  std::cout << path << ": " << reader->ToolName() << " reconstruction ("
            << ToString(format) << "), " << r.num_frames() << " frames, grid "
            << r.width() << "x" << r.height() << " ("
            << ToString(r.grid_resize()) << " resize of the source image), "
            << (r.units() == "metres" ? "metric depth" : "depth up to scale")
            << "\n"
            << std::fixed << std::setprecision(2) << "  frame 0: fx " << c.fx
            << " fy " << c.fy << " cx " << c.cx << " cy " << c.cy
            << "; images: " << (r.has_rgb() ? "yes" : "none read")
            << "; confidence: " << (r.has_confidence() ? "yes" : "no") << "\n";
  const ReconstructionConventions k = reader->Conventions();
  std::cout << "  poses: " << k.pose << "\n  confidence: " << k.confidence
            << "\n  intrinsics: " << k.intrinsics << "\n  units: " << k.units
            << "\n";
}

// `info FILE.tfrecord`: the Waymo reader links protobuf, whose loading adds
// milliseconds to every start-up (about what the rest of `geodrive --version`
// costs), so it lives in the commands plugin, loaded for a .tfrecord only
// (sanitizer builds link everything in).
void DescribeWaymo(const std::string& path) {
#ifdef GEODRIVE_COMMANDS_BUILT_IN
  DescribeWaymoSegment(path);
#else
  const char* const kPlugin = "libgeodrive-commands.so";
  const CommandPluginInfo plugin = reinterpret_cast<CommandPluginEntry>(
      LoadPluginSymbol(kPlugin, kCommandPluginEntry))();
  if (plugin.version == nullptr ||
      std::string(plugin.version) != GEODRIVE_VERSION) {
    throw std::runtime_error(std::string(kPlugin) + " is version " +
                             (plugin.version ? plugin.version : "?") +
                             ", this program " + GEODRIVE_VERSION);
  }
  reinterpret_cast<DescribeWaymoSegmentEntry>(
      LoadPluginSymbol(kPlugin, kDescribeWaymoSegmentSymbol))(path);
#endif
}

int RunInfo(const std::string& path,
            const std::string& format,
            const std::string& to_tum) {
  GEODRIVE_CHECK_INPUT(std::filesystem::exists(path), path, ": no such file");
  if (!to_tum.empty()) {
    const TrajectoryFormat f = format == "auto" || format == "intrinsics"
                                   ? TrajectoryFormat::kAuto
                                   : ParseTrajectoryFormat(format);
    const Trajectory t = ReadTrajectoryAny(path, f);
    WriteTumTrajectory(to_tum, t);
    std::cout << to_tum << ": " << t.size()
              << " poses written as TUM (t x y z qx qy qz qw, evo's order)\n";
    return kExitOk;
  }
  if (std::filesystem::is_directory(path)) {
    const auto recon = DetectReconstructionFormat(path);
    GEODRIVE_CHECK_INPUT(recon, path,
                         ": is a directory, and not a reconstruction folder "
                         "(MonST3R, CUT3R, or one holding a VGGT, DA3, "
                         "MegaSaM or generic npz)");
    PrintReconstruction(path, *recon);
    return kExitOk;
  }
  const std::string name = std::filesystem::path(path).filename().string();
  if (EndsWith(name, ".npz")) {
    if (const auto recon = DetectReconstructionFormat(path)) {
      PrintReconstruction(path, *recon);
      return kExitOk;
    }
    const NpzReader npz(path);
    std::cout << path << ": npz archive, " << npz.Keys().size()
              << " arrays (no reconstruction format: see `geodrive info "
                 "--help`)\n";
    for (const std::string& key : npz.Keys()) {
      try {
        const NpyHeader h = npz.Header(key);
        std::cout << "  " << key << ": " << NpyDtypeDescr(h.dtype) << " "
                  << ShapeString(h.shape) << "\n";
      } catch (const InputError&) {
        std::cout << "  " << key << ": (a dtype this reader does not take)\n";
      }
    }
    return kExitOk;
  }
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
  if (EndsWith(name, ".tfrecord")) {
    DescribeWaymo(path);
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
    if (fmt == "auto" && name.find("intrinsics") != std::string::npos)
      fmt = "intrinsics";
    if (fmt == "intrinsics") {
      const auto cams = ReadMonst3rIntrinsics(path, 1, 1);
      std::cout << path << ": MonST3R intrinsics, " << cams.size() << " frames";
      if (!cams.empty())
        std::cout << ", fx " << cams[0].fx << " fy " << cams[0].fy << " cx "
                  << cams[0].cx << " cy " << cams[0].cy;
      std::cout << "\n";
      return kExitOk;
    }
    const TrajectoryFormat f = fmt == "auto" ? DetectTrajectoryFormat(path)
                                             : ParseTrajectoryFormat(fmt);
    const Trajectory traj = ReadTrajectoryAny(path, f);
    const char* kind =
        f == TrajectoryFormat::kMonst3r ? "MonST3R trajectory (t x y z qw qx "
                                          "qy qz)"
        : f == TrajectoryFormat::kKitti ? "KITTI odometry poses (3x4 "
                                          "world_from_cam0 per line)"
        : f == TrajectoryFormat::kColmap
            ? "COLMAP images.txt (cam_from_world, QW first)"
            : "TUM trajectory (t x y z qx qy qz qw)";
    std::cout << path << ": " << kind << ", " << traj.size()
              << " poses, length " << traj.Length() << ", duration "
              << traj.Duration() << "\n";
    return kExitOk;
  }
  ThrowInputError(
      path,
      "unknown file type (expected .npy, .npz, .pcd.bin, .bin, .ply, .pcd, "
      ".png, .jpg, a .txt trajectory, a Waymo .tfrecord or a reconstruction "
      "folder)");
}

CommandRunner SetupInfo(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  auto format = std::make_shared<std::string>("auto");
  app.add_option(
         "file", *path,
         "File to describe (.npy, .npz, .pcd.bin, .bin, .ply, .pcd, "
         "image, trajectory .txt, Waymo Open Dataset v1 .tfrecord: "
         "frames, poses, camera calibrations), or a reconstruction: "
         "a MonST3R or CUT3R folder, VGGT predictions.npz, Depth Anything 3 "
         "results.npz, MegaSaM *_sgd_cvd_hr.npz / *_droid.npz, our "
         "generic npz (docs/RECONSTRUCTIONS.md)")
      ->required();
  app.add_option("--format", *format,
                 "For .txt files: monst3r (t x y z qw qx qy qz), tum (t x y z "
                 "qx qy qz qw), kitti (12 numbers per line), colmap "
                 "(images.txt), intrinsics, or auto (pred_traj.txt = "
                 "monst3r, images.txt = colmap, *intrinsics* = intrinsics, "
                 "12 numbers per row = kitti, else tum)")
      ->check(CLI::IsMember({"auto", "monst3r", "tum", "kitti", "colmap",
                             "reconstruction", "intrinsics"}));
  auto to_tum = std::make_shared<std::string>();
  app.add_option("--to-tum", *to_tum,
                 "Write the trajectory of FILE (any format --format takes, a "
                 "reconstruction's camera track included) as TUM `t x y z qx "
                 "qy qz qw` (evo's order) to this path");
  return [path, format, to_tum] { return RunInfo(*path, *format, *to_tum); };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    info,
    "info",
    "Print what a file is (npy, npz, point cloud, trajectory, image, "
    "reconstruction, Waymo TFRecord)",
    SetupInfo);

}  // namespace geodrive

#pragma once
// GeoDrive's own trajectory file: JSON, schema in
// data_schema/trajectory.schema.json.
//
//   {
//     "format": "geodrive-trajectory", "version": 1,
//     "convention": "world_from_cam",            // camera-to-world; camera
//     axes OpenCV "units": "metres",                          // or "monst3r"
//     (unknown scale) or free text "camera":
//     {"fx":..,"fy":..,"cx":..,"cy":..,"width":..,"height":..,
//                "pixel_convention": "integer-index"},           // optional
//     "frames": [ {"t": 0.0, "position": [x, y, z],
//                  "quaternion_wxyz": [w, x, y, z]}              // or
//                  "rotation": 3x3 rows
//                 , ... ]
//   }
//
// On read: quaternions must have unit norm within 1e-3 (then normalised);
// rotation matrices must be orthonormal within 1e-4 with determinant +1; values
// must be finite; timestamps strictly increasing. Every failure throws
// InputError naming the file and the frame.

#include <optional>
#include <string>

#include "geometry/camera.h"
#include "geometry/trajectory.h"

namespace geodrive {

struct TrajectoryFileInfo {
  std::string units = "metres";
  std::optional<PinholeCamera> camera;  // kIntegerIndex intrinsics
};

Trajectory ReadTrajectoryJson(const std::string& path,
                              TrajectoryFileInfo* info = nullptr);
// Writes quaternions (w first). Throws InputError if the file cannot be
// written.
void WriteTrajectoryJson(const std::string& path,
                         const Trajectory& trajectory,
                         const TrajectoryFileInfo& info = {});

enum class TrajectoryFormat {
  kAuto,
  kJson,
  kTum,
  kMonst3r,
  // KITTI odometry poses (12 numbers per line; times.txt beside it is used).
  kKitti,
  // COLMAP images.txt (w2c, w-first quaternions).
  kColmap,
  // The camera track of a reconstruction (geometry/reconstruction.h: a VGGT,
  // DA3, MegaSaM or generic npz, a CUT3R or MonST3R folder).
  kReconstruction,
};
// "auto", "json", "tum", "monst3r", "kitti", "colmap", "reconstruction";
// throws InputError otherwise.
TrajectoryFormat ParseTrajectoryFormat(const std::string& text);
// kAuto: *.json -> JSON; a file named pred_traj.txt -> MonST3R (t x y z qw qx
// qy qz); images.txt -> COLMAP; an .npz or a folder -> a reconstruction's
// camera track; a text file whose first row has 12 numbers -> KITTI; any
// other file -> TUM (t x y z qx qy qz qw).
// The format kAuto resolves to for `path` (never kAuto).
TrajectoryFormat DetectTrajectoryFormat(const std::string& path);
Trajectory ReadTrajectoryAny(const std::string& path,
                             TrajectoryFormat format = TrajectoryFormat::kAuto,
                             TrajectoryFileInfo* info = nullptr);

}  // namespace geodrive

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

enum class TrajectoryFormat { kAuto, kJson, kTum, kMonst3r };
// "auto", "json", "tum", "monst3r"; throws InputError otherwise.
TrajectoryFormat ParseTrajectoryFormat(const std::string& text);
// kAuto: *.json -> JSON, a file named pred_traj.txt -> MonST3R (t x y z qw qx
// qy qz), any other file -> TUM (t x y z qx qy qz qw).
Trajectory ReadTrajectoryAny(const std::string& path,
                             TrajectoryFormat format = TrajectoryFormat::kAuto,
                             TrajectoryFileInfo* info = nullptr);

}  // namespace geodrive

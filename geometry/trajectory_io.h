#pragma once
// Trajectory and intrinsics text formats. Each format has its own named function; the quaternion
// order is never guessed.

#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/trajectory.h"

namespace geodrive {

// MonST3R `pred_traj.txt`: one line per frame `t x y z qw qx qy qz` (w FIRST), camera-to-world
// (world_from_cam). `t` is the frame index written as a float. Throws InputError naming the file
// and line on malformed input (wrong column count, non-numeric, non-finite, zero quaternion).
Trajectory ReadMonst3rTrajectory(const std::string& path);
void WriteMonst3rTrajectory(const std::string& path, const Trajectory& trajectory);

// Standard TUM RGB-D format: `t x y z qx qy qz qw` (w LAST), world_from_cam. Lines starting with
// '#' are comments.
Trajectory ReadTumTrajectory(const std::string& path);
void WriteTumTrajectory(const std::string& path, const Trajectory& trajectory);

// MonST3R `pred_intrinsics.txt`: one line per frame with 9 numbers, the row-major 3x3 K in
// processed-image pixels. The image size is not in the file: pass it.
std::vector<PinholeCamera> ReadMonst3rIntrinsics(const std::string& path, int width, int height);
void WriteMonst3rIntrinsics(const std::string& path, const std::vector<PinholeCamera>& cameras);

}  // namespace geodrive

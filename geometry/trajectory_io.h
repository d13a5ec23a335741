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

// KITTI odometry poses (`poses/NN.txt`): one line per frame with 12 numbers,
// the row-major 3x4 world_from_cam0 (world = camera 0 of the first frame;
// OpenCV axes). Timestamps in seconds from `times_path` (KITTI's times.txt,
// one per line, same count) when given, else the frame index. Rotations must
// be orthonormal within 1e-5 (the files carry 7 significant digits) and are
// re-orthonormalised.
Trajectory ReadKittiTrajectory(const std::string& path,
                               const std::string& times_path = "");

// COLMAP `images.txt` (text model): per image a line `IMAGE_ID QW QX QY QZ TX
// TY TZ CAMERA_ID NAME` (w FIRST; cam_from_world, inverted here) followed by
// its POINTS2D line; '#' comments. Frames in the order of NAME (video frames
// are named in order), timestamps = that index.
Trajectory ReadColmapTrajectory(const std::string& path);

// MonST3R `pred_intrinsics.txt`: one line per frame with 9 numbers, the row-major 3x3 K in
// processed-image pixels. The image size is not in the file: pass it.
std::vector<PinholeCamera> ReadMonst3rIntrinsics(const std::string& path, int width, int height);
void WriteMonst3rIntrinsics(const std::string& path, const std::vector<PinholeCamera>& cameras);

}  // namespace geodrive

#pragma once
// Trajectory edits for novel-view conditioning videos (GeoDrive's ±3 m lateral
// views, reversing, speed changes, yaw offsets). All functions are pure: they
// return a new trajectory.
//
// Axes: OpenCV camera axes (x right, y down, z forward). "Left", "up" and "yaw"
// refer to the FIRST camera's axes: shifting left by d moves every camera
// centre by d * (-x_first) in the world.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "geometry/rigid3.h"
#include "geometry/trajectory.h"

namespace geodrive {

// Moves every camera centre by `offset_in_first_cam` (a vector in the first
// camera's axes); the orientations are unchanged. E.g. (-3, 0, 0) = 3 units to
// the left.
Trajectory ShiftInFirstCamera(const Trajectory& trajectory,
                              const Eigen::Vector3d& offset_in_first_cam);
// Convenience: d units left (-x), right (+x), up (-y) in the first camera's
// axes.
Trajectory ShiftLeft(const Trajectory& trajectory, double d);
Trajectory ShiftRight(const Trajectory& trajectory, double d);
Trajectory ShiftUp(const Trajectory& trajectory, double d);

// Drive forward then back: with N frames and m = (N - 1) / 2 (integer
// division), output frame k has pose k for k <= m and pose 2m - k afterwards
// (the cameras keep facing forward, as a reversing car). Timestamps are kept,
// so speeds are unchanged; frame 0 stays frame 0.
Trajectory ForwardThenBack(const Trajectory& trajectory);
// The poses in reverse order with the original timestamps (drive the path
// backwards).
Trajectory ReverseOrder(const Trajectory& trajectory);

// Speed scaling: output frame k gets the pose at time t0 + factor * (t_k - t0).
// Beyond the last frame the last segment's motion (rotation and translation
// rates) is extrapolated. factor > 0.
Trajectory ScaleSpeed(const Trajectory& trajectory, double factor);

// Pose at any time: interpolation (slerp/lerp) inside, constant-velocity
// extrapolation outside.
Rigid3d PoseAtExtrapolated(const Trajectory& trajectory, double t);
// Temporal resampling at the given times (interpolated, extrapolated outside).
Trajectory ResampleAtTimes(const Trajectory& trajectory,
                           const std::vector<double>& times);
// `num_frames` uniformly spaced times over [t_first, t_last] (num_frames >= 1).
Trajectory ResampleUniform(const Trajectory& trajectory, int num_frames);
// Frames every 1/fps seconds starting at t_first, up to and including t_last.
Trajectory ResampleFps(const Trajectory& trajectory, double fps);

// Rotates every camera about its own vertical axis (camera y) by `yaw_deg`;
// positive turns the camera to the LEFT (towards -x), i.e. counter-clockwise
// seen from above.
Trajectory ApplyYawOffset(const Trajectory& trajectory, double yaw_deg);
// One yaw offset per frame (size must match).
Trajectory ApplyYawOffsets(const Trajectory& trajectory,
                           const std::vector<double>& yaw_deg);

// A clip trajectory from absolute world_from_cam poses, re-expressed relative
// to the first frame (the first pose becomes the identity). Throws InputError
// on NaN/non-unit rotations or non-increasing timestamps.
Trajectory ClipTrajectoryFromPoses(const std::vector<double>& timestamps,
                                   const std::vector<Rigid3d>& world_from_cam);
// Same from ego poses (e.g. nuScenes ego_pose) and the camera's fixed
// extrinsics: world_from_cam_t = world_from_ego_t * ego_from_cam.
Trajectory ClipTrajectoryFromEgoPoses(
    const std::vector<double>& timestamps,
    const std::vector<Rigid3d>& world_from_ego,
    const Rigid3d& ego_from_cam);

// All edits in one options struct, applied in this order: speed scale,
// resample, yaw, shift, forward-then-back.
struct TrajectoryEditOptions {
  double shift_left = 0;  // units of the trajectory (metres after alignment)
  double shift_right = 0;
  double shift_up = 0;
  double yaw_deg = 0;       // positive = turn left
  double speed_scale = 1;   // > 0
  int resample_frames = 0;  // 0 = keep the frames
  bool forward_then_back = false;

  void Check() const;
  // e.g. "shift_left=3 speed_scale=1.5" ("none" if nothing is edited).
  std::string Describe() const;
};
Trajectory ApplyTrajectoryEdits(const Trajectory& trajectory,
                                const TrajectoryEditOptions& options);

}  // namespace geodrive

#pragma once
// Camera trajectories: timestamps plus world_from_cam poses.

#include <string>
#include <vector>

#include "geometry/rigid3.h"

namespace geodrive {

struct Trajectory {
  // Seconds (any origin); strictly increasing for the time-based queries.
  std::vector<double> timestamps;
  // world_from_cam per frame (camera axes OpenCV).
  std::vector<Rigid3d> world_from_cam;

  size_t size() const { return world_from_cam.size(); }
  bool empty() const { return world_from_cam.empty(); }
  void Add(double timestamp, const Rigid3d& pose);

  // Throws InputError (naming `what`) if sizes differ, a pose is invalid (NaN, non-unit
  // quaternion) or timestamps are not strictly increasing.
  void Check(const std::string& what = "trajectory") const;

  // Poses re-expressed in the first camera's frame: first_from_cam_t = first_from_world *
  // world_from_cam_t (the first pose becomes the identity).
  Trajectory RelativeToFirst() const;
  // Sum of distances between consecutive camera centres (units of the poses).
  double Length() const;
  // Last minus first timestamp (0 for fewer than 2 frames).
  double Duration() const;
  // Speed per segment i -> i+1 (distance / time); size() - 1 values.
  std::vector<double> SegmentSpeeds() const;
  double MeanSpeed() const;
  // Pose at time t by slerp/lerp between the bracketing frames, clamped at the ends.
  Rigid3d PoseAt(double t) const;
};

}  // namespace geodrive

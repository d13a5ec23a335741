#include "geometry/trajectory.h"

#include <algorithm>
#include <cmath>

#include "geometry/util/status.h"

namespace geodrive {

void Trajectory::Add(double timestamp, const Rigid3d& pose) {
  timestamps.push_back(timestamp);
  world_from_cam.push_back(pose);
}

void Trajectory::Check(const std::string& what) const {
  GEODRIVE_CHECK_INPUT(timestamps.size() == world_from_cam.size(), what, ": ", timestamps.size(),
                       " timestamps but ", world_from_cam.size(), " poses");
  for (size_t i = 0; i < size(); ++i) {
    GEODRIVE_CHECK_INPUT(std::isfinite(timestamps[i]), what, ": frame ", i,
                         " has a non-finite timestamp");
    GEODRIVE_CHECK_INPUT(world_from_cam[i].IsValid(1e-3), what, ": frame ", i,
                         " has an invalid pose (non-finite or non-unit quaternion)");
    if (i > 0) {
      GEODRIVE_CHECK_INPUT(timestamps[i] > timestamps[i - 1], what, ": timestamps not strictly "
                           "increasing at frame ", i);
    }
  }
}

Trajectory Trajectory::RelativeToFirst() const {
  Trajectory out;
  if (empty()) return out;
  const Rigid3d first_from_world = world_from_cam.front().Inverse();
  for (size_t i = 0; i < size(); ++i) out.Add(timestamps[i], first_from_world * world_from_cam[i]);
  return out;
}

double Trajectory::Length() const {
  double length = 0;
  for (size_t i = 1; i < size(); ++i) {
    length += (world_from_cam[i].translation - world_from_cam[i - 1].translation).norm();
  }
  return length;
}

double Trajectory::Duration() const {
  return size() < 2 ? 0.0 : timestamps.back() - timestamps.front();
}

std::vector<double> Trajectory::SegmentSpeeds() const {
  std::vector<double> speeds;
  for (size_t i = 1; i < size(); ++i) {
    const double dt = timestamps[i] - timestamps[i - 1];
    const double d = (world_from_cam[i].translation - world_from_cam[i - 1].translation).norm();
    speeds.push_back(dt > 0 ? d / dt : 0.0);
  }
  return speeds;
}

double Trajectory::MeanSpeed() const {
  const double duration = Duration();
  return duration > 0 ? Length() / duration : 0.0;
}

Rigid3d Trajectory::PoseAt(double t) const {
  GEODRIVE_CHECK_INPUT(!empty(), "Trajectory::PoseAt on an empty trajectory");
  if (size() == 1 || t <= timestamps.front()) return world_from_cam.front();
  if (t >= timestamps.back()) return world_from_cam.back();
  const auto it = std::upper_bound(timestamps.begin(), timestamps.end(), t);
  const size_t i1 = static_cast<size_t>(it - timestamps.begin());
  const size_t i0 = i1 - 1;
  const double alpha = (t - timestamps[i0]) / (timestamps[i1] - timestamps[i0]);
  return Interpolate(world_from_cam[i0], world_from_cam[i1], alpha);
}

}  // namespace geodrive

#include "geometry/trajectory_edit.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "geometry/util/status.h"

namespace geodrive {
namespace {

void CheckNonEmpty(const Trajectory& trajectory, const char* what) {
  GEODRIVE_CHECK_INPUT(!trajectory.empty(), what, ": empty trajectory");
}

// Left Jacobian V(w) of SO(3) (the SE(3) exponential's translation part): t =
// V(w) rho.
Eigen::Matrix3d LeftJacobian(const Eigen::Vector3d& w) {
  const double theta = w.norm();
  Eigen::Matrix3d wx;
  wx << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  double a, b;
  if (theta < 1e-6) {
    a = 0.5 - theta * theta / 24.0;
    b = 1.0 / 6.0 - theta * theta / 120.0;
  } else {
    a = (1.0 - std::cos(theta)) / (theta * theta);
    b = (theta - std::sin(theta)) / (theta * theta * theta);
  }
  return Eigen::Matrix3d::Identity() + a * wx + b * wx * wx;
}

// motion^a = exp(a log(motion)) on SE(3) (a screw motion; for integer a it
// equals applying the motion a times).
Rigid3d ScaleMotion(const Rigid3d& motion, double a) {
  const Eigen::Vector3d w = QuaternionToAngleAxis(motion.rotation);
  const Eigen::Vector3d rho = LeftJacobian(w).inverse() * motion.translation;
  const Eigen::Vector3d wa = a * w;
  return Rigid3d(QuaternionFromAngleAxis(wa), LeftJacobian(wa) * (a * rho));
}

}  // namespace

Trajectory ShiftInFirstCamera(const Trajectory& trajectory,
                              const Eigen::Vector3d& offset_in_first_cam) {
  CheckNonEmpty(trajectory, "ShiftInFirstCamera");
  GEODRIVE_CHECK_INPUT(offset_in_first_cam.allFinite(),
                       "trajectory shift: non-finite offset");
  const Eigen::Vector3d offset_in_world =
      trajectory.world_from_cam.front().rotation * offset_in_first_cam;
  Trajectory out = trajectory;
  for (auto& pose : out.world_from_cam) pose.translation += offset_in_world;
  return out;
}

Trajectory ShiftLeft(const Trajectory& trajectory, double d) {
  return ShiftInFirstCamera(trajectory, Eigen::Vector3d(-d, 0, 0));
}
Trajectory ShiftRight(const Trajectory& trajectory, double d) {
  return ShiftInFirstCamera(trajectory, Eigen::Vector3d(d, 0, 0));
}
Trajectory ShiftUp(const Trajectory& trajectory, double d) {
  return ShiftInFirstCamera(trajectory, Eigen::Vector3d(0, -d, 0));
}

Trajectory ForwardThenBack(const Trajectory& trajectory) {
  CheckNonEmpty(trajectory, "ForwardThenBack");
  const int n = static_cast<int>(trajectory.size());
  const int m = (n - 1) / 2;
  Trajectory out;
  for (int k = 0; k < n; ++k) {
    const int src = k <= m ? k : 2 * m - k;
    out.Add(trajectory.timestamps[k],
            trajectory.world_from_cam[std::max(0, src)]);
  }
  return out;
}

Trajectory ReverseOrder(const Trajectory& trajectory) {
  Trajectory out;
  const size_t n = trajectory.size();
  for (size_t k = 0; k < n; ++k)
    out.Add(trajectory.timestamps[k], trajectory.world_from_cam[n - 1 - k]);
  return out;
}

Rigid3d PoseAtExtrapolated(const Trajectory& trajectory, double t) {
  CheckNonEmpty(trajectory, "PoseAtExtrapolated");
  GEODRIVE_CHECK_INPUT(std::isfinite(t), "trajectory: non-finite query time");
  const size_t n = trajectory.size();
  if (n == 1) return trajectory.world_from_cam.front();
  const auto& ts = trajectory.timestamps;
  const auto& poses = trajectory.world_from_cam;
  if (t > ts.back()) {
    const Rigid3d motion =
        poses[n - 2].Inverse() * poses[n - 1];  // prev_from_last
    return poses[n - 1] *
           ScaleMotion(motion, (t - ts.back()) / (ts[n - 1] - ts[n - 2]));
  }
  if (t < ts.front()) {
    const Rigid3d motion = poses[1].Inverse() * poses[0];  // second_from_first
    return poses[0] * ScaleMotion(motion, (ts.front() - t) / (ts[1] - ts[0]));
  }
  return trajectory.PoseAt(t);
}

Trajectory ScaleSpeed(const Trajectory& trajectory, double factor) {
  CheckNonEmpty(trajectory, "ScaleSpeed");
  GEODRIVE_CHECK_INPUT(std::isfinite(factor) && factor > 0,
                       "trajectory speed scale ", factor, " must be > 0");
  trajectory.Check("ScaleSpeed input");
  Trajectory out;
  const double t0 = trajectory.timestamps.front();
  for (size_t k = 0; k < trajectory.size(); ++k) {
    const double tk = trajectory.timestamps[k];
    out.Add(tk, PoseAtExtrapolated(trajectory, t0 + factor * (tk - t0)));
  }
  return out;
}

Trajectory ResampleAtTimes(const Trajectory& trajectory,
                           const std::vector<double>& times) {
  CheckNonEmpty(trajectory, "ResampleAtTimes");
  trajectory.Check("ResampleAtTimes input");
  Trajectory out;
  for (double t : times) out.Add(t, PoseAtExtrapolated(trajectory, t));
  return out;
}

Trajectory ResampleUniform(const Trajectory& trajectory, int num_frames) {
  CheckNonEmpty(trajectory, "ResampleUniform");
  GEODRIVE_CHECK_INPUT(num_frames >= 1 && num_frames <= 1000000,
                       "trajectory resample: ", num_frames,
                       " frames (need 1..1000000)");
  const double t0 = trajectory.timestamps.front(),
               t1 = trajectory.timestamps.back();
  std::vector<double> times(num_frames);
  for (int k = 0; k < num_frames; ++k) {
    times[k] = num_frames == 1 ? t0 : t0 + (t1 - t0) * k / (num_frames - 1);
  }
  if (num_frames > 1 && t1 == t0) {
    for (int k = 0; k < num_frames; ++k)
      times[k] = t0 + k;  // single-frame input: 1 s spacing
  }
  return ResampleAtTimes(trajectory, times);
}

Trajectory ResampleFps(const Trajectory& trajectory, double fps) {
  CheckNonEmpty(trajectory, "ResampleFps");
  GEODRIVE_CHECK_INPUT(std::isfinite(fps) && fps > 0,
                       "trajectory resample: fps ", fps, " must be > 0");
  const double t0 = trajectory.timestamps.front(),
               t1 = trajectory.timestamps.back();
  const double count = std::floor((t1 - t0) * fps + 1e-9) + 1;
  GEODRIVE_CHECK_INPUT(count <= 1000000, "trajectory resample: ", count,
                       " frames is too many");
  std::vector<double> times;
  for (int k = 0; k < static_cast<int>(count); ++k)
    times.push_back(t0 + k / fps);
  return ResampleAtTimes(trajectory, times);
}

Trajectory ApplyYawOffsets(const Trajectory& trajectory,
                           const std::vector<double>& yaw_deg) {
  GEODRIVE_CHECK_INPUT(yaw_deg.size() == trajectory.size(),
                       "trajectory yaw offsets: ", yaw_deg.size(),
                       " values for ", trajectory.size(), " frames");
  Trajectory out = trajectory;
  for (size_t k = 0; k < out.size(); ++k) {
    GEODRIVE_CHECK_INPUT(std::isfinite(yaw_deg[k]),
                         "trajectory yaw offsets: non-finite value");
    // Camera y points down: a left turn (counter-clockwise from above) is a
    // negative rotation about +y.
    const double angle = -yaw_deg[k] * M_PI / 180.0;
    const Eigen::Quaterniond cam_from_newcam(
        Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitY()));
    out.world_from_cam[k].rotation =
        (out.world_from_cam[k].rotation * cam_from_newcam).normalized();
  }
  return out;
}

Trajectory ApplyYawOffset(const Trajectory& trajectory, double yaw_deg) {
  return ApplyYawOffsets(trajectory,
                         std::vector<double>(trajectory.size(), yaw_deg));
}

Trajectory ClipTrajectoryFromPoses(const std::vector<double>& timestamps,
                                   const std::vector<Rigid3d>& world_from_cam) {
  Trajectory abs;
  abs.timestamps = timestamps;
  abs.world_from_cam = world_from_cam;
  GEODRIVE_CHECK_INPUT(!abs.empty(), "clip trajectory: no poses");
  abs.Check("clip trajectory");
  for (auto& pose : abs.world_from_cam) pose.rotation.normalize();
  Trajectory out = abs.RelativeToFirst();
  for (auto& pose : out.world_from_cam) pose.rotation.normalize();
  return out;
}

Trajectory ClipTrajectoryFromEgoPoses(
    const std::vector<double>& timestamps,
    const std::vector<Rigid3d>& world_from_ego,
    const Rigid3d& ego_from_cam) {
  GEODRIVE_CHECK_INPUT(ego_from_cam.IsValid(1e-3),
                       "clip trajectory: invalid ego_from_cam");
  std::vector<Rigid3d> world_from_cam;
  for (const auto& pose : world_from_ego)
    world_from_cam.push_back(pose * ego_from_cam);
  return ClipTrajectoryFromPoses(timestamps, world_from_cam);
}

void TrajectoryEditOptions::Check() const {
  for (double v : {shift_left, shift_right, shift_up, yaw_deg, speed_scale}) {
    GEODRIVE_CHECK_INPUT(std::isfinite(v), "trajectory edit: non-finite value");
  }
  GEODRIVE_CHECK_INPUT(speed_scale > 0, "trajectory edit: speed_scale ",
                       speed_scale, " must be > 0");
  GEODRIVE_CHECK_INPUT(resample_frames >= 0 && resample_frames <= 1000000,
                       "trajectory edit: resample_frames ", resample_frames,
                       " out of range");
}

std::string TrajectoryEditOptions::Describe() const {
  std::ostringstream os;
  if (speed_scale != 1) os << " speed_scale=" << speed_scale;
  if (resample_frames > 0) os << " resample_frames=" << resample_frames;
  if (yaw_deg != 0) os << " yaw_deg=" << yaw_deg;
  if (shift_left != 0) os << " shift_left=" << shift_left;
  if (shift_right != 0) os << " shift_right=" << shift_right;
  if (shift_up != 0) os << " shift_up=" << shift_up;
  if (forward_then_back) os << " forward_then_back";
  const std::string s = os.str();
  return s.empty() ? "none" : s.substr(1);
}

Trajectory ApplyTrajectoryEdits(const Trajectory& trajectory,
                                const TrajectoryEditOptions& options) {
  options.Check();
  CheckNonEmpty(trajectory, "trajectory edit");
  Trajectory out = trajectory;
  if (options.speed_scale != 1) out = ScaleSpeed(out, options.speed_scale);
  if (options.resample_frames > 0)
    out = ResampleUniform(out, options.resample_frames);
  if (options.yaw_deg != 0) out = ApplyYawOffset(out, options.yaw_deg);
  const Eigen::Vector3d shift(options.shift_right - options.shift_left,
                              -options.shift_up, 0);
  if (!shift.isZero()) out = ShiftInFirstCamera(out, shift);
  if (options.forward_then_back) out = ForwardThenBack(out);
  return out;
}

}  // namespace geodrive

#include "geometry/alignment.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "geometry/util/status.h"

namespace geodrive {

std::string ToString(AlignmentType type) {
  switch (type) {
    case AlignmentType::kNone:
      return "none";
    case AlignmentType::kSE3:
      return "se3";
    case AlignmentType::kSim3:
      return "sim3";
    case AlignmentType::kScale:
      return "scale";
  }
  return "?";
}

AlignmentType ParseAlignmentType(const std::string& text) {
  if (text == "none") return AlignmentType::kNone;
  if (text == "se3") return AlignmentType::kSE3;
  if (text == "sim3") return AlignmentType::kSim3;
  if (text == "scale") return AlignmentType::kScale;
  throw InputError("unknown alignment '" + text +
                   "' (expected none, se3, sim3 or scale)");
}

Sim3d AlignPoints(const std::vector<Eigen::Vector3d>& est,
                  const std::vector<Eigen::Vector3d>& ref,
                  AlignmentType type) {
  GEODRIVE_CHECK_INPUT(
      est.size() == ref.size(), "trajectory alignment: ", est.size(),
      " estimated positions but ", ref.size(), " reference positions");
  if (type == AlignmentType::kNone) return Sim3d();
  GEODRIVE_CHECK_INPUT(est.size() >= 3,
                       "trajectory alignment: needs at least 3 poses, got ",
                       est.size());
  Eigen::Matrix3Xd src(3, est.size()), dst(3, ref.size());
  for (size_t i = 0; i < est.size(); ++i) {
    GEODRIVE_CHECK_INPUT(est[i].allFinite() && ref[i].allFinite(),
                         "trajectory alignment: non-finite position at frame ",
                         i);
    src.col(i) = est[i];
    dst.col(i) = ref[i];
  }
  // Degeneracy: all points (nearly) identical -> no rotation or scale is
  // defined.
  const Eigen::Vector3d mean = src.rowwise().mean();
  const double spread = (src.colwise() - mean).norm();
  GEODRIVE_CHECK_INPUT(
      spread > 1e-12,
      "trajectory alignment: estimated positions are all equal");
  const bool with_scale =
      type == AlignmentType::kSim3 || type == AlignmentType::kScale;
  const Eigen::Matrix4d t = Eigen::umeyama(src, dst, with_scale);
  Sim3d sim = Sim3d::FromMatrix(t, 1e-6);
  if (type == AlignmentType::kScale)
    return Sim3d(sim.scale, Eigen::Quaterniond::Identity(),
                 Eigen::Vector3d::Zero());
  if (type == AlignmentType::kSE3) sim.scale = 1.0;
  return sim;
}

ErrorStats ComputeErrorStats(std::vector<double> errors) {
  ErrorStats s;
  s.count = errors.size();
  if (errors.empty()) return s;
  double sum = 0, sq = 0;
  for (double e : errors) {
    sum += e;
    sq += e * e;
    s.max = std::max(s.max, e);
  }
  s.mean = sum / errors.size();
  s.rms = std::sqrt(sq / errors.size());
  const size_t mid = errors.size() / 2;
  std::nth_element(errors.begin(), errors.begin() + mid, errors.end());
  if (errors.size() % 2 == 1) {
    s.median = errors[mid];
  } else {
    const double upper = errors[mid];
    const double lower =
        *std::max_element(errors.begin(), errors.begin() + mid);
    s.median = 0.5 * (lower + upper);
  }
  return s;
}

Trajectory TransformTrajectory(const Sim3d& new_from_old,
                               const Trajectory& trajectory) {
  Trajectory out;
  out.timestamps = trajectory.timestamps;
  out.world_from_cam.reserve(trajectory.size());
  for (const auto& pose : trajectory.world_from_cam) {
    out.world_from_cam.push_back(TransformPose(new_from_old, pose));
  }
  return out;
}

TrajectoryErrorReport EvaluateTrajectory(const Trajectory& est,
                                         const Trajectory& ref,
                                         AlignmentType alignment) {
  GEODRIVE_CHECK_INPUT(est.size() == ref.size(),
                       "trajectory evaluation: estimate has ", est.size(),
                       " poses but reference has ", ref.size());
  GEODRIVE_CHECK_INPUT(!est.empty(),
                       "trajectory evaluation: empty trajectories");
  std::vector<Eigen::Vector3d> pe, pr;
  for (size_t i = 0; i < est.size(); ++i) {
    pe.push_back(est.world_from_cam[i].translation);
    pr.push_back(ref.world_from_cam[i].translation);
  }
  TrajectoryErrorReport report;
  report.alignment = alignment;
  report.ref_from_est = AlignPoints(pe, pr, alignment);
  const Trajectory aligned = TransformTrajectory(report.ref_from_est, est);
  std::vector<double> ate, rpe_t, rpe_r;
  for (size_t i = 0; i < est.size(); ++i) {
    ate.push_back((aligned.world_from_cam[i].translation -
                   ref.world_from_cam[i].translation)
                      .norm());
    if (i + 1 < est.size()) {
      const Rigid3d ref_rel =
          ref.world_from_cam[i].Inverse() * ref.world_from_cam[i + 1];
      const Rigid3d est_rel =
          aligned.world_from_cam[i].Inverse() * aligned.world_from_cam[i + 1];
      const Rigid3d e = ref_rel.Inverse() * est_rel;
      rpe_t.push_back(e.translation.norm());
      rpe_r.push_back(
          RotationDistanceDeg(Eigen::Quaterniond::Identity(), e.rotation));
    }
  }
  report.ate = ComputeErrorStats(ate);
  report.rpe_trans = ComputeErrorStats(rpe_t);
  report.rpe_rot_deg = ComputeErrorStats(rpe_r);
  return report;
}

std::string TrajectoryErrorReport::BriefReport() const {
  std::ostringstream os;
  os << "alignment " << ToString(alignment) << " (scale " << ref_from_est.scale
     << "), ATE rms " << ate.rms << " median " << ate.median << " max "
     << ate.max << ", RPE trans rms " << rpe_trans.rms << ", RPE rot rms "
     << rpe_rot_deg.rms << " deg over " << ate.count << " poses";
  return os.str();
}

}  // namespace geodrive

#include "eval/trajectory_metrics.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "geometry/util/status.h"

namespace geodrive {

void TrajectoryErrorOptions::Check() const {
  GEODRIVE_CHECK_INPUT(
      n_to_align == -1 || n_to_align >= 1,
      "trajectory errors: n_to_align must be -1 (all) or >= 1, got ",
      n_to_align);
}

std::vector<Eigen::Vector3d> CameraCentres(const Trajectory& trajectory) {
  std::vector<Eigen::Vector3d> centres;
  centres.reserve(trajectory.size());
  for (const Rigid3d& pose : trajectory.world_from_cam)
    centres.push_back(pose.translation);
  return centres;
}

TrajectoryErrors TrajectoryErrors::Scaled(double f) const {
  TrajectoryErrors out = *this;
  out.ade *= f;
  out.fde *= f;
  out.rmse *= f;
  out.max *= f;
  for (double& e : out.per_frame) e *= f;
  out.factor *= f;
  return out;
}

std::string TrajectoryErrors::BriefReport() const {
  std::ostringstream os;
  os << per_frame.size() << " poses, alignment " << ToString(alignment)
     << ": ADE " << ade << ", FDE " << fde << ", RMSE " << rmse << " ("
     << units;
  if (factor != 1.0) os << ", x" << factor;
  os << ")";
  if (alignment == AlignmentType::kSim3 || alignment == AlignmentType::kScale) {
    os << ", scale " << gt_from_pred.scale;
  }
  return os.str();
}

TrajectoryErrors ComputeTrajectoryErrors(
    const Trajectory& pred,
    const Trajectory& gt,
    const TrajectoryErrorOptions& options) {
  options.Check();
  GEODRIVE_CHECK_INPUT(!pred.empty(),
                       "trajectory errors: the predicted trajectory is empty");
  GEODRIVE_CHECK_INPUT(
      !gt.empty(), "trajectory errors: the ground-truth trajectory is empty");
  GEODRIVE_CHECK_INPUT(pred.size() == gt.size(),
                       "trajectory errors: trajectories differ in length (",
                       "predicted ", pred.size(), " poses, ground truth ",
                       gt.size(), ")");
  const std::vector<Eigen::Vector3d> p = CameraCentres(pred),
                                     g = CameraCentres(gt);
  for (size_t i = 0; i < p.size(); ++i) {
    GEODRIVE_CHECK_INPUT(p[i].allFinite(), "trajectory errors: predicted pose ",
                         i, " is not finite");
    GEODRIVE_CHECK_INPUT(g[i].allFinite(),
                         "trajectory errors: ground-truth pose ", i,
                         " is not finite");
  }
  TrajectoryErrors out;
  out.alignment = options.alignment;
  out.units = options.units;
  const size_t n_align =
      options.n_to_align < 0
          ? p.size()
          : std::min(p.size(), static_cast<size_t>(options.n_to_align));
  out.gt_from_pred =
      AlignPoints(std::vector<Eigen::Vector3d>(p.begin(), p.begin() + n_align),
                  std::vector<Eigen::Vector3d>(g.begin(), g.begin() + n_align),
                  options.alignment);
  double sum = 0, sq = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    const double e = (out.gt_from_pred * p[i] - g[i]).norm();
    out.per_frame.push_back(e);
    sum += e;
    sq += e * e;
    out.max = std::max(out.max, e);
  }
  out.ade = sum / p.size();
  out.fde = out.per_frame.back();
  out.rmse = std::sqrt(sq / p.size());
  // Finite inputs can still overflow (positions near 1e300): an error, never
  // an infinite figure in a report.
  GEODRIVE_CHECK_INPUT(std::isfinite(out.ade) && std::isfinite(out.fde) &&
                           std::isfinite(out.rmse),
                       "trajectory errors: the errors overflow (ADE ", out.ade,
                       "): positions too large to compare (units?)");
  return out;
}

}  // namespace geodrive

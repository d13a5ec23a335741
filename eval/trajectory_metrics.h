#pragma once
// ADE / FDE between a predicted and a ground-truth camera trajectory (GeoDrive
// App. B.4).
//
// ADE = (1/T) sum_t ||c_t - c^_t||_2 and FDE = ||c_T - c^_T||_2 over the camera
// centres c (the translation of world_from_cam), frame by frame (same length
// required). GeoDrive states no alignment, so the default is none; SE(3),
// Sim(3) and scale-only alignments follow evo (Umeyama via Eigen::umeyama,
// geometry/alignment.h) and are reported as separate numbers. Units are those
// of the ground-truth trajectory (after Sim(3)/scale alignment) or of the
// inputs (none/SE(3)): MonST3R units for MonST3R-estimated trajectories, metres
// for ego poses. The paper prints ADE x 10^2 and FDE x 10^2:
// `TrajectoryErrors::Scaled(100)`.

#include <string>
#include <vector>

#include "geometry/alignment.h"
#include "geometry/rigid3.h"
#include "geometry/trajectory.h"

namespace geodrive {

struct TrajectoryErrorOptions {
  AlignmentType alignment = AlignmentType::kNone;
  // Align on the first n poses only (evo --n_to_align); -1 = all poses.
  int n_to_align = -1;
  // Name of the unit of the inputs, copied into the result ("MonST3R units",
  // "m").
  std::string units = "input units";
  void Check() const;
};

struct TrajectoryErrors {
  double ade = 0;  // mean over frames of the per-frame distance
  double fde = 0;  // distance at the last frame
  double rmse = 0;
  double max = 0;
  std::vector<double> per_frame;  // distances after alignment
  AlignmentType alignment = AlignmentType::kNone;
  Sim3d gt_from_pred;  // the alignment applied to the prediction
  std::string units;
  // Presentation factor already applied to ade/fde/rmse/max/per_frame (1 or 100
  // for "x10^2").
  double factor = 1.0;

  // A copy with every distance multiplied by `factor` (100 for the paper's
  // x10^2 columns).
  TrajectoryErrors Scaled(double factor) const;
  std::string BriefReport() const;
};

// Camera centres (world_from_cam translations) of a trajectory.
std::vector<Eigen::Vector3d> CameraCentres(const Trajectory& trajectory);

// ADE/FDE of `pred` against `gt`. Throws InputError for empty or
// different-length trajectories, non-finite poses, or a degenerate alignment.
TrajectoryErrors ComputeTrajectoryErrors(
    const Trajectory& pred,
    const Trajectory& gt,
    const TrajectoryErrorOptions& options = {});

}  // namespace geodrive

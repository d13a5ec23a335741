#pragma once
// Trajectory alignment (Umeyama) and the trajectory error metrics of the evo
// tool.
//
// Conventions follow evo (github.com/MichaelGrupp/evo):
//  - APE/ATE: after aligning the estimate to the reference, the translation
//  error per pose is
//    ||t_ref_i - t_est_i||; statistics are RMS, mean, median, max over poses.
//  - RPE (delta = 1 frame, translation part): E_i = (ref_i^-1 ref_{i+1})^-1
//  (est_i^-1 est_{i+1});
//    the error is ||translation(E_i)||. RPE is invariant to a rigid alignment
//    but not to scale.
// Units are those of the reference trajectory (metres for metric references).

#include <Eigen/Core>
#include <string>
#include <vector>

#include "geometry/rigid3.h"
#include "geometry/trajectory.h"

namespace geodrive {

enum class AlignmentType {
  kNone,   // no alignment
  kSE3,    // rotation + translation (evo --align)
  kSim3,   // rotation + translation + scale (evo --align --correct_scale)
  kScale,  // scale only (evo --correct_scale without --align): the Umeyama
           // Sim(3) scale, alone
};
std::string ToString(AlignmentType type);
// Parses none|se3|sim3|scale; throws InputError otherwise.
AlignmentType ParseAlignmentType(const std::string& text);

// Finds ref_from_est minimising sum ||ref_i - ref_from_est * est_i||^2 (Umeyama
// 1991, via Eigen::umeyama). Needs >= 3 non-collinear points for SE3/Sim3
// (throws InputError otherwise) and equal-length inputs.
Sim3d AlignPoints(const std::vector<Eigen::Vector3d>& est,
                  const std::vector<Eigen::Vector3d>& ref,
                  AlignmentType type);

struct ErrorStats {
  double rms = 0, mean = 0, median = 0, max = 0;
  size_t count = 0;
};
ErrorStats ComputeErrorStats(std::vector<double> errors);

struct TrajectoryErrorReport {
  AlignmentType alignment = AlignmentType::kNone;
  Sim3d ref_from_est;    // the alignment applied to the estimate
  ErrorStats ate;        // absolute translation error after alignment
  ErrorStats rpe_trans;  // relative translation error, delta 1 frame (after
                         // alignment scale)
  ErrorStats rpe_rot_deg;
  std::string BriefReport() const;
};

// Aligns `est` to `ref` (camera centres, frame by frame; equal sizes required)
// and computes ATE and RPE. The estimate's poses are transformed by the
// alignment before RPE (so Sim(3) and scale alignment fix the scale of the
// relative motion too).
TrajectoryErrorReport EvaluateTrajectory(const Trajectory& est,
                                         const Trajectory& ref,
                                         AlignmentType alignment);

// Applies a similarity to every pose (world'_from_cam = sim * world_from_cam).
Trajectory TransformTrajectory(const Sim3d& new_from_old,
                               const Trajectory& trajectory);

}  // namespace geodrive

#pragma once
// Camera pose refinement by reprojection least squares over static, confident
// pixels (GeoDrive eq. 3):
//   cam_from_world_t* = argmin sum_{(i,j) static, confident} rho(|| pi(K
//   cam_from_world_t O_t(i,j))
//                                                                  - (i, j)
//                                                                  ||^2)
// O_t is frame t's pointmap in WORLD coordinates, held fixed: it comes from the
// reconstruction (a raw network pointmap, another model's pointmap, or a
// reference reconstruction), never from frame t's own pose -- otherwise the
// stored pose would be the trivial optimum. Pixels (i, j) are integer indices
// (MonST3R convention). The solver is Ceres (geometry/cost_functions.h), kept
// out of this header; the summary is solver-neutral.

#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/pointmap.h"
#include "geometry/rigid3.h"

namespace geodrive {

enum class RobustLoss { kNone, kHuber, kCauchy };
std::string ToString(RobustLoss loss);
// Parses "none", "huber" or "cauchy"; throws InputError otherwise.
RobustLoss ParseRobustLoss(const std::string& text);

struct PoseRefinementOptions {
  // Robust loss rho on the squared pixel error, with its scale in pixels.
  RobustLoss loss = RobustLoss::kHuber;
  double loss_scale_px = 1.0;
  // Pixels used per frame: stratified over a grid of cells (about 4 samples per
  // cell), seeded. 0 = every valid pixel.
  int num_samples = 4096;
  uint32_t seed = 0;
  // Refine one multiplicative focal factor (fx, fy scaled together; shared by
  // the clip in joint mode, as MonST3R's shared focal).
  bool refine_focal = false;
  // Solver.
  int max_iterations = 50;
  double function_tolerance = 1e-12;
  double gradient_tolerance = 1e-12;
  double parameter_tolerance = 1e-12;
  int num_threads = 1;
  // A residual is an inlier when its norm is below this (px).
  double inlier_threshold_px = 2.0;
  // Frames with fewer valid pixels are skipped (summary says why).
  int min_valid_pixels = 32;
  // Initialisation: OpenCV solvePnPRansac when no initial pose is given, or
  // when the given one is far off (median reprojection error above
  // pnp_trigger_px or over half the points behind the camera); the better of
  // the two (median error) is used.
  bool pnp_fallback = true;
  double pnp_trigger_px = 20.0;
  double pnp_ransac_threshold_px = 4.0;
  int pnp_ransac_iterations = 300;
  // Joint mode: temporal smoothness weights (second difference of camera
  // centres, residual per scene unit; change of relative rotation, residual per
  // radian). 0 = off.
  double smoothness_translation_weight = 0.0;
  double smoothness_rotation_weight = 0.0;

  // Throws InputError naming the bad field.
  void Check() const;
};

// One frame's input. `points_in_world` (CV_32FC3, H x W) is O_t; `valid_mask`
// (CV_8UC1, 255 = use; empty = every finite point) selects the static confident
// pixels.
struct PoseRefinementInput {
  int frame_index = 0;
  cv::Mat points_in_world;
  cv::Mat valid_mask;
  PinholeCamera camera;
  std::optional<Rigid3d> initial_world_from_cam;
};

struct PoseRefinementSummary {
  int frame_index = 0;
  bool skipped = false;
  std::string skip_reason;
  std::string initialization;  // "given", "pnp-ransac", "pnp-ransac (given pose
                               // far off)"
  int num_valid_pixels = 0;
  int num_residuals = 0;  // sampled pixels
  int num_inliers = 0;    // final residual norm < inlier_threshold_px
  double initial_rms_px =
      0;  // at the pose the solver starts from (all sampled pixels)
  double final_rms_px = 0;
  double initial_median_px = 0;
  double final_median_px = 0;
  double final_inlier_rms_px = 0;
  double initial_focal_scale = 1, final_focal_scale = 1;
  int iterations = 0;
  std::string termination;  // solver's termination type, e.g. CONVERGENCE
  bool usable = false;
  double seconds = 0;

  std::string BriefReport() const;
};

struct PoseRefinementResult {
  Rigid3d
      world_from_cam;    // refined (the initial pose, or identity, if skipped)
  PinholeCamera camera;  // focal refined if asked
  PoseRefinementSummary summary;
};

// Stratified, seeded sample of up to `num_samples` pixels (u = column, v = row)
// among the nonzero pixels of `valid_mask`: the image is cut into a grid of
// about num_samples / 4 cells and cells are visited round-robin, each giving
// one shuffled pixel per round. 0 = all valid pixels.
std::vector<Eigen::Vector2i> SamplePixelsStratified(const cv::Mat& valid_mask,
                                                    int num_samples,
                                                    uint32_t seed);

// Refines one frame (eq. 3). Never throws for a degenerate frame: the summary
// says it was skipped.
PoseRefinementResult RefineFramePose(const PoseRefinementInput& input,
                                     const PoseRefinementOptions& options);

// Refines every frame of a clip. joint = false: independent problems (OpenMP
// over frames). joint = true: one problem, with the temporal smoothness term
// between consecutive inputs and one shared focal factor when refine_focal.
std::vector<PoseRefinementResult> RefineClipPoses(
    const std::vector<PoseRefinementInput>& inputs,
    const PoseRefinementOptions& options,
    bool joint);

// The eq. 3 inputs of a MonST3R folder's `frames`: O_t is pts3d_t.npy when
// the folder has it, else frame t's depth unprojected with its stored pose
// (then the refinement checks consistency); the pixels kept are those
// `filter` keeps; the initial pose is the stored one.
std::vector<PoseRefinementInput> PoseRefinementInputs(
    const Monst3rFolder& folder,
    const std::vector<int>& frames,
    const PointmapFilterOptions& filter);

}  // namespace geodrive

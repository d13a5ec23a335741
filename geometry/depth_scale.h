#pragma once
// Robust fit of a depth scale s in d_ref ~= s * d_est (e.g. LiDAR depth vs
// MonST3R depth).
//
// The fit works on log ratios r_i = log(d_ref_i / d_est_i), so
// depth-proportional noise has the same weight at every range: an optional
// RANSAC front (one-sample hypotheses, inlier band |r_i - log s| <
// inlier_log_threshold), the median of the inlier ratios as the start, then
// iteratively reweighted least squares with Cauchy weights w = 1 / (1 + (e /
// c)^2) on the log residuals e, then a plain mean of the inlier log ratios (no
// outlier bias). Residuals are reported in the units of d_ref (metres for
// LiDAR): |d_ref - s d_est|.

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace geodrive {

struct DepthScaleOptions {
  // RANSAC front (robust to large outlier fractions); off = start from the
  // median of all ratios.
  bool use_ransac = true;
  int ransac_iterations = 200;
  // Inlier band on |log(d_ref / (s d_est))|; 0.1 ~ 10 % relative depth error.
  double inlier_log_threshold = 0.1;
  // IRLS iterations and the Cauchy scale (log units).
  int irls_iterations = 20;
  double cauchy_scale = 0.05;
  // Minimum number of valid pairs (after discarding non-positive / non-finite
  // depths).
  int min_points = 20;
  uint64_t seed = 0;
  // Throws InputError naming the bad field.
  void Check() const;
};

struct DepthScaleResult {
  bool success = false;
  std::string message;  // why it failed (or "ok")
  double scale = 0;
  int num_points = 0;  // valid pairs used
  int num_inliers = 0;
  double inlier_fraction = 0;
  // Percentiles of |d_ref - s d_est| over the inliers (units of d_ref).
  double residual_p50 = 0, residual_p90 = 0, residual_p99 = 0;
  std::string BriefReport() const;
};

// Fits s from paired depths (same length). Pairs with non-finite or
// non-positive depth are ignored. Failure (too few points, non-finite or
// non-positive scale) is reported in the result, not thrown.
DepthScaleResult FitDepthScale(const std::vector<double>& d_ref,
                               const std::vector<double>& d_est,
                               const DepthScaleOptions& options = {});

// Bilinear sample of a CV_32F depth map at continuous integer-index coordinates
// (u, v) (pixel (i, j) centre at (i, j)). Returns NaN when any of the 4
// neighbours is outside the image, non-finite, <= 0, or marked in
// `invalid_mask` (CV_8U, non-zero = invalid; may be empty).
double SampleDepthBilinear(const cv::Mat& depth,
                           const cv::Mat& invalid_mask,
                           double u,
                           double v);

}  // namespace geodrive

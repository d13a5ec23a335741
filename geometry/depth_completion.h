#pragma once
// Classical depth completion of a sparse LiDAR depth image on the CPU: the
// morphological pipeline of Ku, Harakeh and Waslander, "In Defense of
// Classical Image Processing: Fast Depth Completion on the CPU" (CRV 2018,
// "IP-Basic"), with the support restricted to where the LiDAR reaches.
//
// The pipeline (all on the inverted depth d' = max_depth - d, so that a
// max-filter keeps the nearest surface; held in 16-bit levels of 1.5 mm at
// the default 100 m, for speed):
//   1. dilate with a diamond kernel (default 5x5);
//   1b. (ours, on by default) plane interpolation between scan lines: in
//      each column, where three consecutive runs of filled pixels have
//      centres whose inverse depths lie on a line (a plane seen through a
//      pinhole has an inverse depth affine in the pixel: the road, walls),
//      the column between the outer centres is set along that line, gaps
//      and the dilation's plateaus alike. The morphological steps fill such
//      gaps with steps of constant depth, which tear apart into stripes when
//      the road is approached;
//   2. close small holes (full kernel, 5x5);
//   3. fill remaining empty pixels by a dilation with a 7x7 full kernel;
//   4. fill remaining empty pixels by a dilation with a large full kernel
//      (31x31): the gaps between scan lines;
//   5. median blur 5x5, then Gaussian blur 5x5, each applied only to filled
//      pixels (outlier removal and smoothing);
//   5b. (ours, on by default) pixels below the envelope still empty (gaps
//      wider than the large kernel, the rows under the lowest scan line) are
//      filled along each column: between two completed pixels along the
//      line through their inverse depths, below the lowest with its depth;
//   6. invert back; keep only pixels below the support envelope.
// The support envelope: for each column, the top-most pixel with a LiDAR
// return within +-envelope_half_width columns. The LiDAR's top beam is about
// 10 degrees above the horizon, so the sky and tall structures above it have
// no support; completion would only smear the top returns upwards there, so
// those pixels stay empty and are reported (fill_above_envelope, off by
// default, extends each column's top depth upwards as IP-Basic's
// "extrapolate to top" does).

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "geometry/camera.h"

namespace geodrive {

struct DepthCompletionOptions {
  // Returns farther than this (metres) are ignored; also the inversion
  // constant of the pipeline.
  double max_depth_m = 100.0;
  // Step 1: side of the diamond kernel (odd, >= 1).
  int diamond_kernel = 5;
  // Step 1b: plane interpolation between scan lines (false: IP-Basic as
  // published), for gaps of at most `plane_max_gap` rows, when the slopes of
  // inverse depth between consecutive run centres agree within
  // `plane_tolerance` (relative).
  bool plane_interpolation = true;
  int plane_max_gap = 64;
  double plane_tolerance = 0.05;
  // Step 2: side of the closing kernel (odd, >= 1).
  int close_kernel = 5;
  // Step 3: side of the small-hole fill kernel (odd, >= 1).
  int small_fill_kernel = 7;
  // Step 4: side of the large-hole fill kernel (odd, >= 1); Ku et al. use 31
  // at KITTI's 1242x375 with 64 beams.
  int large_fill_kernel = 31;
  // Step 5: median blur (3 or 5; 1 = off) and Gaussian blur (odd; 1 = off).
  int median_kernel = 5;
  int gaussian_kernel = 5;
  // Half width (pixels) of the column window of the support envelope.
  int envelope_half_width = 8;
  // Step 5b: fill the supported pixels still empty along their column.
  bool fill_supported_gaps = true;
  // Extend each column's top-most completed depth up to the image top (off:
  // pixels above the envelope stay empty).
  bool fill_above_envelope = false;

  bool Check() const;
};

struct DepthCompletionReport {
  // Pixels of the sparse input with a return.
  int64_t input_pixels = 0;
  // Fraction of the image below the support envelope.
  double supported_fraction = 0;
  // Fraction of the supported pixels with a completed depth.
  double coverage_of_supported = 0;
  // Fraction of all pixels with a completed depth.
  double coverage = 0;

  // One line: "1234 returns, supported 0.64 of the image, 0.97 of it
  // completed (0.62 of all pixels)".
  std::string BriefReport() const;
};

// The nearest of `points_in_camera` (camera axes OpenCV, metres) per pixel of
// `camera` (kIntegerIndex, rounded to the nearest pixel): CV_32F, 0 = none.
// Points nearer than `min_depth_m` are ignored.
cv::Mat SparseDepthImage(const std::vector<Eigen::Vector3f>& points_in_camera,
                         const PinholeCamera& camera,
                         double min_depth_m = 0.5);

// Completes `sparse` (CV_32F, metres, 0 = no return; NaN/negatives are not
// allowed) into a dense depth image of the same size (0 = no depth). Throws
// InputError when the image is not CV_32F or the options are invalid.
cv::Mat CompleteDepth(const cv::Mat& sparse,
                      const DepthCompletionOptions& options,
                      DepthCompletionReport* report = nullptr);

// Accuracy of the completion against returns held out of its input, as KITTI
// depth completion reports it.
struct DepthCompletionAccuracy {
  // Held-out returns, and how many of them the completion covered.
  int64_t held_out = 0;
  int64_t covered = 0;
  // Over the covered held-out returns: mean absolute and RMS error (metres),
  // and the fractions within 5 % and 10 % of the held-out depth.
  double mae_m = 0;
  double rmse_m = 0;
  double within_5_percent = 0;
  double within_10_percent = 0;

  std::string BriefReport() const;
};

// Holds out a seeded `fraction` of the returns of `sparse`, completes from the
// rest and compares the completed depth with each held-out return.
DepthCompletionAccuracy HoldOutAccuracy(const cv::Mat& sparse,
                                        double fraction,
                                        uint64_t seed,
                                        const DepthCompletionOptions& options);

}  // namespace geodrive

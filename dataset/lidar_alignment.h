#pragma once
// Metric scale for MonST3R clips from LiDAR, and metric trajectories (issue:
// LiDAR alignment).
//
// For each clip frame i (a DriveClip frame, MonST3R frame i), a LiDAR sweep
// of the clip's LidarProvider near its timestamp (nearest, or the sample's
// keyframe sweep, within a maximum time gap) is projected into the camera
// with the full chain (sensor -> ego at lidar time -> world -> ego at camera
// time -> camera, devkit rules:
// depth > 1 m, 1 < u < W-1, 1 < v < H-1), its pixels are mapped to the MonST3R
// image (MonST3R's 512-long-side resize + crop, integer-index pixels), the
// MonST3R depth is sampled bilinearly there (skipping invalid and dynamic
// pixels), and d_lidar ~= s * d_monst3r is fitted robustly
// (geometry/depth_scale.h) per frame and pooled per clip. The scaled MonST3R
// trajectory is then aligned to the metric camera trajectory (ego poses ∘
// calibration) with Umeyama (geometry/alignment.h), reporting ATE / RPE in
// metres (evo conventions).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "dataset/drive_clip.h"
#include "dataset/lidar_projection.h"
#include "geometry/alignment.h"
#include "geometry/depth_scale.h"
#include "geometry/monst3r.h"
#include "geometry/trajectory.h"

namespace geodrive {

enum class LidarSweepChoice { kNearest, kKeyframe };

struct LidarScaleOptions {
  LidarSweepChoice sweep = LidarSweepChoice::kNearest;
  // Maximum |t_lidar - t_camera| in seconds (LIDAR_TOP runs at 20 Hz: nearest
  // is <= 25 ms).
  double max_time_gap_s = 0.05;
  LidarProjectionOptions projection;  // devkit rules (min_dist 1 m)
  // Skip LiDAR pixels on dynamic MonST3R pixels (enlarged masks when present).
  bool skip_dynamic = true;
  bool use_enlarged_masks = true;
  // Robust fit (per frame and pooled per clip).
  DepthScaleOptions fit;
  // Trajectory alignment of the scaled MonST3R trajectory to the metric one.
  AlignmentType alignment = AlignmentType::kSE3;
  void Check() const;
};

// One LiDAR point that hit a valid MonST3R pixel.
struct LidarDepthSample {
  float u = 0, v = 0;   // MonST3R image pixel (integer-index)
  float d_lidar = 0;    // metres
  float d_monst3r = 0;  // MonST3R units
};

struct FrameScaleReport {
  int frame = -1;
  bool used = false;
  std::string skip_reason;  // why the frame was skipped (empty when used)
  // The sweep used (index into the clip LiDAR provider's Sweeps()).
  std::optional<size_t> lidar_sweep;
  double time_gap_s = 0;
  int points_in_image = 0;  // LiDAR points inside the camera image
  DepthScaleResult fit;
  std::vector<LidarDepthSample> samples;
};

struct ClipScaleReport {
  bool success = false;
  std::string message;
  DepthScaleResult clip_fit;  // pooled over all used frames
  std::vector<FrameScaleReport> frames;
  // Scaled MonST3R trajectory (metres, MonST3R world = first camera) vs the
  // metric camera trajectory from ego poses (re-expressed relative to the first
  // camera).
  Trajectory metric_reference;  // relative to the first camera, metres
  Trajectory scaled_monst3r;    // s * MonST3R, metres
  Trajectory aligned_monst3r;   // scaled and aligned to metric_reference
  TrajectoryErrorReport trajectory_error;
  std::string BriefReport() const;
};

// Fits the clip scale. The clip's frames are the MonST3R frames, in order
// (their count must equal the folder's frame count). Frames without a usable
// sweep or with too few points are skipped with a reason. Throws InputError
// for inconsistent inputs (frame counts, image sizes).
ClipScaleReport FitClipLidarScale(const DriveClip& clip,
                                  const Monst3rFolder& monst3r,
                                  const LidarScaleOptions& options);

// The LiDAR sweep used for clip frame `frame` (nullopt and a reason if none).
std::optional<size_t> FindLidarSweep(const DriveClip& clip,
                                     int frame,
                                     LidarSweepChoice choice,
                                     double max_time_gap_s,
                                     std::string* reason);

// Metric camera trajectory of the clip: world_from_cam per frame, timestamps
// in seconds.
Trajectory CameraTrajectory(const DriveClip& clip);

// Writes the report as JSON (scale, inliers, residual percentiles, per-frame
// entries, ATE/RPE).
std::string ClipScaleReportToJson(const ClipScaleReport& report);

// A picture of the fit: the MonST3R RGB of `frame` with the LiDAR samples drawn
// as dots coloured by relative residual |d_lidar - s d| / d_lidar (green 0 ->
// red >= 10 %), upscaled x2.
cv::Mat DrawScaleResiduals(const Monst3rFrame& frame,
                           const FrameScaleReport& report,
                           double scale);

}  // namespace geodrive

#pragma once
// The outputs of `geodrive eval`: report.json, a per-video CSV, a Markdown
// table in the paper's layout (GeoDrive Table 1 columns) and a PNG plot
// (per-frame PSNR/SSIM, trajectories top view).

#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "eval/image_metrics.h"
#include "eval/trajectory_metrics.h"
#include "eval/video_matching.h"

namespace geodrive {

struct VideoEvalRecord {
  std::string id;
  std::string pred_path;
  std::string gt_path;
  VideoScores scores;
  // LPIPS (docs/EVAL.md): mean over frames, and per frame; NaN / empty when
  // not computed.
  double lpips = NAN;
  std::vector<double> lpips_per_frame;
};

// A set-level Fréchet distance (FID over all frames, FVD over clips).
struct FrechetReport {
  double distance = NAN;
  int64_t pred_samples = 0;  // feature vectors of the prediction
  // Ground-truth feature vectors; empty when the reference statistics were
  // read from the cache (gt_stats) instead of computed.
  std::optional<int64_t> gt_samples;
  int dims = 0;
  std::string model;     // TorchScript model path
  std::string gt_stats;  // reference statistics prefix ("" if none)
};

// Mean and population standard deviation over videos (common_metrics'
// convention).
struct MeanStd {
  double mean = 0;
  double std = 0;
  int count = 0;
};

struct EvalReport {
  std::string pred;  // as given on the command line
  std::string gt;
  std::vector<std::string> metrics;  // requested, in order
  std::string method = "ours";       // row label of the Markdown table
  FrameMetricsOptions frame_options;
  std::vector<VideoEvalRecord> videos;
  // Which ground-truth videos were evaluated (absent when no ground truth was
  // read, e.g. FID/FVD against cached statistics).
  std::optional<EvalSubsetSummary> subset;
  std::optional<TrajectoryErrors> trajectory;  // already scaled when x100
  bool x100 = false;
  std::optional<FrechetReport> fid, fvd;
  std::string lpips_model;  // TorchScript model path when LPIPS was computed
  // Camera centres for the plot (ground truth and aligned prediction).
  std::vector<Eigen::Vector3d> gt_centres;
  std::vector<Eigen::Vector3d> pred_centres_aligned;

  // Dataset-level statistic of a per-video mean ("psnr", "ssim", "psnr_y",
  // "ssim_y", "lpips").
  MeanStd Aggregate(const std::string& metric) const;
};

// Writes `json_path` and, next to it with the same stem, .csv, .md and .png.
// Throws InputError if a file cannot be written. Returns the paths written.
std::vector<std::string> WriteEvalOutputs(const EvalReport& report,
                                          const std::string& json_path);

}  // namespace geodrive

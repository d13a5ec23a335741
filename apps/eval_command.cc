// `geodrive eval`: PSNR/SSIM between predicted and ground-truth videos, ADE/FDE
// between trajectories; writes report.json + report.csv + report.md +
// report.png (docs/EVAL.md).

#include <iostream>
#include <memory>
#include <set>
#include <sstream>

#include "apps/command.h"
#include "eval/deep_metrics.h"
#include "eval/image_metrics.h"
#include "eval/report.h"
#include "eval/trajectory_metrics.h"
#include "eval/video_io.h"
#include "geometry/status.h"
#include "geometry/trajectory_io.h"

namespace geodrive {
namespace {

struct EvalArgs {
  std::string pred, gt, out, metrics = "psnr,ssim";
  std::string align = "none", pred_traj, gt_traj, traj_format = "tum";
  std::string pred_name = "pred.mp4", gt_name = "gt.mp4", units,
              method = "ours";
  bool x100 = false;
  int threads = 0;
};

std::vector<std::string> SplitMetrics(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  const std::set<std::string> known = {
      "psnr", "ssim", "psnr_y", "ssim_y", "lpips", "fid", "fvd", "ade", "fde"};
  while (std::getline(ss, item, ',')) {
    if (item.empty()) continue;
    GEODRIVE_CHECK_INPUT(
        known.count(item), "--metrics: unknown metric '", item,
        "' (known: psnr, ssim, psnr_y, ssim_y, lpips, fid, fvd, ade, fde)");
    out.push_back(item);
  }
  GEODRIVE_CHECK_INPUT(!out.empty(), "--metrics: no metric given");
  return out;
}

int RunEval(const EvalArgs& args) {
  const std::vector<std::string> metrics = SplitMetrics(args.metrics);
  auto wants = [&](const char* m) {
    return std::find(metrics.begin(), metrics.end(), m) != metrics.end();
  };
  if ((wants("lpips") || wants("fid") || wants("fvd")) &&
      !DeepMetricsAvailable()) {
    std::cerr << "geodrive eval: error: " << DeepMetricsUnavailableMessage()
              << std::endl;
    return kExitBadInput;
  }
  const bool image =
      wants("psnr") || wants("ssim") || wants("psnr_y") || wants("ssim_y");
  const bool traj = wants("ade") || wants("fde");

  EvalReport report;
  report.pred = args.pred;
  report.gt = args.gt;
  report.metrics = metrics;
  report.method = args.method;
  report.x100 = args.x100;
  report.frame_options.psnr = wants("psnr") || wants("psnr_y");
  report.frame_options.ssim = wants("ssim") || wants("ssim_y");
  report.frame_options.luma = wants("psnr_y") || wants("ssim_y");
  report.frame_options.num_threads = args.threads;

  if (image) {
    GEODRIVE_CHECK_INPUT(!args.pred.empty() && !args.gt.empty(),
                         "--pred and --gt are required for psnr/ssim");
    const auto pairs = MatchVideos(ListVideos(args.pred, args.pred_name),
                                   ListVideos(args.gt, args.gt_name));
    for (const VideoPairSource& pair : pairs) {
      VideoEvalRecord record{pair.id, pair.pred_path, pair.gt_path, {}};
      record.scores = CompareVideos(ReadVideoFrames(pair.pred_path),
                                    ReadVideoFrames(pair.gt_path),
                                    report.frame_options, pair.id);
      std::cerr << pair.id << ": " << record.scores.Summary() << "\n";
      report.videos.push_back(std::move(record));
    }
  }
  if (traj) {
    GEODRIVE_CHECK_INPUT(!args.pred_traj.empty() && !args.gt_traj.empty(),
                         "--pred-traj and --gt-traj are required for ade/fde");
    auto read = [&](const std::string& path) {
      return args.traj_format == "monst3r" ? ReadMonst3rTrajectory(path)
                                           : ReadTumTrajectory(path);
    };
    const Trajectory pred = read(args.pred_traj), gt = read(args.gt_traj);
    TrajectoryErrorOptions options;
    options.alignment = ParseAlignmentType(args.align);
    options.units = !args.units.empty()             ? args.units
                    : args.traj_format == "monst3r" ? "MonST3R units"
                                                    : "units of the TUM files";
    TrajectoryErrors errors = ComputeTrajectoryErrors(pred, gt, options);
    report.gt_centres = CameraCentres(gt);
    for (const Eigen::Vector3d& c : CameraCentres(pred)) {
      report.pred_centres_aligned.push_back(errors.gt_from_pred * c);
    }
    if (args.x100) errors = errors.Scaled(100.0);
    std::cerr << "trajectory: " << errors.Summary() << "\n";
    report.trajectory = errors;
  }
  for (const std::string& path : WriteEvalOutputs(report, args.out)) {
    std::cout << "wrote " << path << "\n";
  }
  for (const char* m : {"psnr", "ssim", "psnr_y", "ssim_y"}) {
    if (!wants(m)) continue;
    const MeanStd s = report.Aggregate(m);
    std::cout << m << " " << s.mean << " (std " << s.std << ", " << s.count
              << " videos)\n";
  }
  if (report.trajectory)
    std::cout << "trajectory " << report.trajectory->Summary() << "\n";
  return kExitOk;
}

CommandRunner SetupEval(CLI::App& app) {
  auto args = std::make_shared<EvalArgs>();
  app.add_option("--pred", args->pred,
                 "Predicted videos: an MP4, a frame folder, a folder of "
                 "videos/frame folders, or "
                 "a pairs folder (<clip>/<pred-name>)");
  app.add_option("--gt", args->gt,
                 "Ground-truth videos, same forms (pairs: <clip>/<gt-name>)");
  app.add_option("--metrics", args->metrics,
                 "Comma list: psnr,ssim,psnr_y,ssim_y (BT.601 luma),ade,fde; "
                 "lpips,fid,fvd need "
                 "GEODRIVE_WITH_TORCH")
      ->capture_default_str();
  app.add_option("--align", args->align, "Trajectory alignment before ADE/FDE")
      ->check(CLI::IsMember({"none", "se3", "sim3", "scale"}))
      ->capture_default_str();
  app.add_flag("--x100", args->x100,
               "Report ADE/FDE x 10^2 (the paper's presentation)");
  app.add_option("--pred-traj", args->pred_traj,
                 "Predicted trajectory (TUM, or see --traj-format)");
  app.add_option("--gt-traj", args->gt_traj, "Ground-truth trajectory");
  app.add_option("--traj-format", args->traj_format,
                 "tum (t x y z qx qy qz qw) or monst3r (pred_traj.txt: t x y z "
                 "qw qx qy qz)")
      ->check(CLI::IsMember({"tum", "monst3r"}))
      ->capture_default_str();
  app.add_option("--units", args->units,
                 "Name of the trajectory units for the report");
  app.add_option("--pred-name", args->pred_name,
                 "Member of a pairs clip folder used as prediction")
      ->capture_default_str();
  app.add_option("--gt-name", args->gt_name,
                 "Member of a pairs clip folder used as ground truth")
      ->capture_default_str();
  app.add_option("--method", args->method, "Row label of the Markdown table")
      ->capture_default_str();
  app.add_option("--threads", args->threads,
                 "Threads for frame metrics (0 = all cores)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--out", args->out,
                 "report.json (also writes .csv, .md and .png beside it)")
      ->required();
  return [args] { return RunEval(*args); };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    eval,
    "eval",
    "PSNR/SSIM between videos and ADE/FDE between trajectories, with a "
    "JSON/CSV/Markdown/PNG report",
    SetupEval);

}  // namespace geodrive

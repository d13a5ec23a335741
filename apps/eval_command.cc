// `geodrive eval`: PSNR/SSIM (and, with LibTorch and user-provided TorchScript
// models, LPIPS/FID/FVD) between predicted and ground-truth videos, ADE/FDE
// between trajectories; writes report.json + report.csv + report.md +
// report.png (docs/EVAL.md).

#include <algorithm>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <set>
#include <sstream>
#include <thread>
#include <utility>

#include "apps/cli/cli.h"
#include "eval/deep_metrics.h"
#include "eval/frechet.h"
#include "eval/image_metrics.h"
#include "eval/report.h"
#include "eval/trajectory_metrics.h"
#include "eval/video_matching.h"
#include "geometry/trajectory_io.h"
#include "geometry/trajectory_json.h"
#include "geometry/util/files.h"
#include "geometry/util/memory.h"
#include "geometry/util/status.h"
#include "render/video/ffmpeg_decode.h"
#include "render/video/video_io.h"

namespace geodrive {
namespace {

// Compares one pair a chunk of frames at a time, the two videos decoded side
// by side: memory holds a chunk of each (max(8, 2 x threads) frames), whatever
// their length. The scores are those of CompareVideos on the whole videos.
void ComparePairStreaming(const VideoPairSource& pair,
                          bool image,
                          LpipsModel* lpips,
                          const FrameMetricsOptions& options,
                          VideoEvalRecord* record) {
  VideoFrameStream pred(pair.pred_path), gt(pair.gt_path);
  const int threads =
      options.num_threads > 0
          ? options.num_threads
          : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const size_t chunk = static_cast<size_t>(std::max(8, 2 * threads));
  std::vector<cv::Mat> p, g;
  double lpips_sum = 0;
  int64_t done = 0;
  while (true) {
    p.clear();
    g.clear();
    cv::Mat frame;
    while (p.size() < chunk && pred.Next(&frame)) p.push_back(frame);
    while (g.size() < chunk && gt.Next(&frame)) g.push_back(frame);
    if (p.size() != g.size()) {  // count the rest of the longer one
      while (pred.Next(&frame)) {
      }
      while (gt.Next(&frame)) {
      }
      ThrowInputError(pair.id, "frame counts differ (predicted ",
                      pred.frames_read(), ", ground truth ", gt.frames_read(),
                      ")");
    }
    if (p.empty()) break;
    if (image) {
      const VideoScores s = CompareVideos(p, g, options, pair.id, done);
      record->scores.width = s.width;
      record->scores.height = s.height;
      record->scores.frames.insert(record->scores.frames.end(),
                                   s.frames.begin(), s.frames.end());
    }
    if (lpips) {
      for (size_t i = 0; i < p.size(); ++i) {
        record->lpips_per_frame.push_back(lpips->Distance(p[i], g[i]));
        lpips_sum += record->lpips_per_frame.back();
      }
    }
    done += static_cast<int64_t>(p.size());
  }
  if (image) {
    record->scores.mean = MeanOfFrames(record->scores.frames);
    std::cerr << pair.id << ": " << record->scores.BriefReport() << "\n";
  }
  if (lpips) {
    record->lpips = lpips_sum / static_cast<double>(done);
    std::cerr << pair.id << ": lpips " << record->lpips << "\n";
  }
}

// Decoded bytes of a video file as its header declares them (0 for a frame
// folder or a container that does not declare its frame count).
uint64_t DeclaredDecodedBytes(const std::string& path) {
  if (path.empty() || !IsVideoFile(path)) return 0;
  const VideoFileReader reader(path);
  return static_cast<uint64_t>(reader.declared_frames()) *
         static_cast<uint64_t>(
             VideoFrameBytes(reader.width(), reader.height()));
}

struct EvalArgs {
  std::string pred, gt, out, metrics = "psnr,ssim";
  std::string align = "none", pred_traj, gt_traj, traj_format = "tum";
  std::string pred_name = "pred.mp4", gt_name = "gt.mp4", units,
              method = "ours";
  // Which ground-truth videos to evaluate: all or predicted.
  std::string subset = "all";
  bool x100 = false;
  int threads = 0;
  // Deep metrics: TorchScript models and cached reference statistics.
  std::string lpips_model, fid_model, fvd_model, fid_stats, fvd_stats;
};

// Stacks per-video feature blocks (same number of columns) into one matrix.
Eigen::MatrixXd StackRows(const std::vector<Eigen::MatrixXd>& blocks) {
  Eigen::Index rows = 0;
  for (const Eigen::MatrixXd& b : blocks) rows += b.rows();
  Eigen::MatrixXd out(rows, blocks.empty() ? 0 : blocks[0].cols());
  Eigen::Index r = 0;
  for (const Eigen::MatrixXd& b : blocks) {
    GEODRIVE_CHECK_INPUT(b.cols() == out.cols(),
                         "feature dimension changed between videos (",
                         out.cols(), " vs ", b.cols(), ")");
    out.middleRows(r, b.rows()) = b;
    r += b.rows();
  }
  return out;
}

bool StatsCached(const std::string& prefix) {
  return !prefix.empty() && std::filesystem::exists(prefix + "_mu.npy") &&
         std::filesystem::exists(prefix + "_sigma.npy");
}

// FID or FVD of the collected features. The ground-truth side comes from the
// cached statistics at `stats_prefix` when they exist; otherwise from
// `gt_features`, and then they are written there (when a prefix is given).
FrechetReport Frechet(const char* name,
                      const std::string& model,
                      const std::string& stats_prefix,
                      const std::vector<Eigen::MatrixXd>& pred_features,
                      const std::vector<Eigen::MatrixXd>& gt_features) {
  FrechetReport out;
  out.model = model;
  out.gt_stats = stats_prefix;
  const Eigen::MatrixXd pred = StackRows(pred_features);
  out.pred_samples = pred.rows();
  out.dims = static_cast<int>(pred.cols());
  const FeatureStatistics pred_stats = ComputeFeatureStatistics(
      pred, std::string(name) + " features of the predicted videos");
  FeatureStatistics gt_stats;
  if (StatsCached(stats_prefix)) {
    gt_stats = LoadFeatureStatistics(stats_prefix);
    GEODRIVE_CHECK_INPUT(gt_stats.dims() == out.dims, stats_prefix,
                         "_mu.npy: reference statistics have ", gt_stats.dims(),
                         " dimensions, the ", name, " model gives ", out.dims);
  } else {
    const Eigen::MatrixXd gt = StackRows(gt_features);
    out.gt_samples = gt.rows();
    gt_stats = ComputeFeatureStatistics(
        gt, std::string(name) + " features of the ground-truth videos");
    if (!stats_prefix.empty()) {
      const std::filesystem::path parent =
          std::filesystem::path(stats_prefix).parent_path();
      std::error_code ec;
      if (!parent.empty()) std::filesystem::create_directories(parent, ec);
      SaveFeatureStatistics(stats_prefix, gt_stats);
      std::cout << "wrote " << stats_prefix << "_mu.npy and " << stats_prefix
                << "_sigma.npy\n";
    }
  }
  const FrechetResult result = FrechetDistance(pred_stats, gt_stats);
  out.distance = result.distance;
  std::cerr << name << ": " << result.BriefReport() << "\n";
  return out;
}

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

// ADE/FDE of --pred-traj against --gt-traj, with the aligned centres for the
// plot.
void EvaluateTrajectories(const EvalArgs& args, EvalReport* report) {
  GEODRIVE_CHECK_INPUT(!args.pred_traj.empty() && !args.gt_traj.empty(),
                       "--pred-traj and --gt-traj are required for ade/fde");
  auto read = [&](const std::string& path) {
    // The default "tum" keeps its meaning for any file name; "auto" detects
    // (geometry/trajectory_json.h: MonST3R, COLMAP, KITTI, reconstructions).
    return ReadTrajectoryAny(path, ParseTrajectoryFormat(args.traj_format));
  };
  const Trajectory pred = read(args.pred_traj), gt = read(args.gt_traj);
  TrajectoryErrorOptions options;
  options.alignment = ParseAlignmentType(args.align);
  options.units = !args.units.empty()             ? args.units
                  : args.traj_format == "monst3r" ? "MonST3R units"
                  : args.traj_format == "kitti"   ? "metres"
                                                  : "units of the files";
  TrajectoryErrors errors = ComputeTrajectoryErrors(pred, gt, options);
  report->gt_centres = CameraCentres(gt);
  for (const Eigen::Vector3d& c : CameraCentres(pred)) {
    report->pred_centres_aligned.push_back(errors.gt_from_pred * c);
  }
  if (args.x100) errors = errors.Scaled(100.0);
  std::cerr << "trajectory: " << errors.BriefReport() << "\n";
  report->trajectory = errors;
}

// One line per computed metric on stdout.
void PrintEvalSummary(const EvalReport& report,
                      const std::function<bool(const char*)>& wants,
                      bool lpips) {
  if (report.subset) std::cout << report.subset->BriefReport() << "\n";
  for (const char* m : {"psnr", "ssim", "psnr_y", "ssim_y"}) {
    if (!wants(m)) continue;
    const MeanStd s = report.Aggregate(m);
    std::cout << m << " " << s.mean << " (std " << s.std << ", " << s.count
              << " videos)\n";
  }
  if (lpips) {
    const MeanStd s = report.Aggregate("lpips");
    std::cout << "lpips " << s.mean << " (std " << s.std << ", " << s.count
              << " videos)\n";
  }
  for (const auto& [name, f] :
       {std::pair("fid", &report.fid), {"fvd", &report.fvd}}) {
    if (!*f) continue;
    std::cout << name << " " << (*f)->distance << " (" << (*f)->pred_samples
              << " predicted vs "
              << ((*f)->gt_samples
                      ? std::to_string(*(*f)->gt_samples) + " ground truth"
                      : "cached " + (*f)->gt_stats)
              << ", " << (*f)->dims << "-d)\n";
  }
  if (report.trajectory)
    std::cout << "trajectory " << report.trajectory->BriefReport() << "\n";
}

int RunEval(const EvalArgs& args) {
  const std::vector<std::string> metrics = SplitMetrics(args.metrics);
  const EvalSubset subset = ParseEvalSubset(args.subset);
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
  const bool lpips = wants("lpips"), fid = wants("fid"), fvd = wants("fvd");
  GEODRIVE_CHECK_INPUT(!lpips || !args.lpips_model.empty(),
                       "--metrics lpips needs --lpips-model (a TorchScript "
                       "LPIPS model, docs/EVAL.md)");
  GEODRIVE_CHECK_INPUT(!fid || !args.fid_model.empty(),
                       "--metrics fid needs --fid-model (a TorchScript "
                       "pytorch-fid Inception, docs/EVAL.md)");
  GEODRIVE_CHECK_INPUT(!fvd || !args.fvd_model.empty(),
                       "--metrics fvd needs --fvd-model (a TorchScript I3D, "
                       "docs/EVAL.md)");
  // An unusable output folder fails now, not after every metric is computed.
  {
    const std::filesystem::path parent =
        std::filesystem::path(args.out).parent_path();
    CreateOutputDirectory(parent.empty() ? "." : parent.string());
    GEODRIVE_CHECK_INPUT(!std::filesystem::is_directory(args.out), args.out,
                         ": is a folder (--out names the report.json file)");
  }
  // Load the models first: a bad model file fails before any video is read.
  std::unique_ptr<LpipsModel> lpips_net;
  std::unique_ptr<FeatureExtractor> fid_net, fvd_net;
  if (lpips) lpips_net = LoadLpipsModel(args.lpips_model);
  if (fid)
    fid_net =
        LoadFeatureExtractor(args.fid_model, FeatureNetwork::kInceptionFid);
  if (fvd)
    fvd_net = LoadFeatureExtractor(args.fvd_model, FeatureNetwork::kI3dFvd);
  // Ground-truth features are needed unless cached reference statistics exist.
  const bool fid_gt = fid && !StatsCached(args.fid_stats);
  const bool fvd_gt = fvd && !StatsCached(args.fvd_stats);
  const bool need_gt = image || lpips || fid_gt || fvd_gt;
  const bool videos = need_gt || fid || fvd;

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

  std::vector<Eigen::MatrixXd> fid_pred, fid_gt_rows, fvd_pred, fvd_gt_rows;
  if (videos) {
    GEODRIVE_CHECK_INPUT(!args.pred.empty(),
                         "--pred is required for psnr/ssim/lpips/fid/fvd");
    GEODRIVE_CHECK_INPUT(!need_gt || !args.gt.empty(),
                         "--gt is required for psnr/ssim/lpips, and for "
                         "fid/fvd without cached --fid-stats/--fvd-stats");
    std::vector<VideoPairSource> pairs;
    if (need_gt) {
      EvalVideoMatch match =
          MatchEvalVideos(ListVideos(args.pred, args.pred_name),
                          ListVideos(args.gt, args.gt_name), subset);
      pairs = std::move(match.pairs);
      report.subset = match.summary;
    } else {
      for (const VideoSource& v : ListVideos(args.pred, args.pred_name))
        pairs.push_back({v.id, v.path, ""});
    }
    for (const VideoPairSource& pair : pairs) {
      VideoEvalRecord record;
      record.id = pair.id;
      record.pred_path = pair.pred_path;
      record.gt_path = pair.gt_path;
      if (!fid && !fvd) {  // frame by frame: stream both videos
        ComparePairStreaming(pair, image, lpips_net.get(), report.frame_options,
                             &record);
        report.videos.push_back(std::move(record));
        continue;
      }
      // FID/FVD take whole videos: what both hold decoded is checked against
      // the memory available before either is decoded.
      const uint64_t need = DeclaredDecodedBytes(pair.pred_path) +
                            (need_gt ? DeclaredDecodedBytes(pair.gt_path) : 0);
      const uint64_t available = AvailableMemoryBytes();
      GEODRIVE_CHECK_INPUT(need <= available, pair.id,
                           ": fid/fvd hold the videos decoded whole, about ",
                           need >> 20, " MiB, and ", available >> 20,
                           " MiB are available");
      const std::vector<cv::Mat> pred = ReadVideoFrames(pair.pred_path);
      const std::vector<cv::Mat> gt =
          need_gt ? ReadVideoFrames(pair.gt_path) : std::vector<cv::Mat>();
      if (image) {
        record.scores = CompareVideos(pred, gt, report.frame_options, pair.id);
        std::cerr << pair.id << ": " << record.scores.BriefReport() << "\n";
      }
      if (lpips) {
        GEODRIVE_CHECK_INPUT(pred.size() == gt.size(), pair.id,
                             ": frame counts differ (predicted ", pred.size(),
                             ", ground truth ", gt.size(), ")");
        double sum = 0;
        for (size_t i = 0; i < pred.size(); ++i) {
          record.lpips_per_frame.push_back(lpips_net->Distance(pred[i], gt[i]));
          sum += record.lpips_per_frame.back();
        }
        record.lpips = sum / pred.size();
        std::cerr << pair.id << ": lpips " << record.lpips << "\n";
      }
      if (fid) {
        fid_pred.push_back(fid_net->Extract({pred}));
        if (fid_gt) fid_gt_rows.push_back(fid_net->Extract({gt}));
      }
      if (fvd) {
        fvd_pred.push_back(fvd_net->Extract({pred}));
        if (fvd_gt) fvd_gt_rows.push_back(fvd_net->Extract({gt}));
      }
      report.videos.push_back(std::move(record));
    }
  }
  if (lpips) report.lpips_model = args.lpips_model;
  if (fid) {
    report.fid =
        Frechet("fid", args.fid_model, args.fid_stats, fid_pred, fid_gt_rows);
  }
  if (fvd) {
    report.fvd =
        Frechet("fvd", args.fvd_model, args.fvd_stats, fvd_pred, fvd_gt_rows);
  }
  if (traj) EvaluateTrajectories(args, &report);
  for (const std::string& path : WriteEvalOutputs(report, args.out)) {
    std::cout << "wrote " << path << "\n";
  }
  PrintEvalSummary(report, wants, lpips);
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
                 "lpips,fid,fvd need GEODRIVE_WITH_TORCH and a TorchScript "
                 "model each")
      ->capture_default_str();
  app.add_option("--lpips-model", args->lpips_model,
                 "TorchScript LPIPS model (x, y in [-1,1]) -> [N,1,1,1]");
  app.add_option("--fid-model", args->fid_model,
                 "TorchScript pytorch-fid Inception, [N,3,299,299] in [-1,1] "
                 "-> [N,2048(,1,1)]");
  app.add_option("--fvd-model", args->fvd_model,
                 "TorchScript I3D (i3d_torchscript.pt), [N,3,T,224,224] in "
                 "[-1,1] -> [N,400]");
  app.add_option("--fid-stats", args->fid_stats,
                 "Reference FID statistics <prefix>_mu.npy/_sigma.npy: used "
                 "instead of --gt when they exist, else computed from --gt "
                 "and written");
  app.add_option("--fvd-stats", args->fvd_stats,
                 "Reference FVD statistics, same workflow as --fid-stats");
  app.add_option("--align", args->align, "Trajectory alignment before ADE/FDE")
      ->check(CLI::IsMember({"none", "se3", "sim3", "scale"}))
      ->capture_default_str();
  app.add_flag("--x100", args->x100,
               "Report ADE/FDE x 10^2 (the paper's presentation)");
  app.add_option("--pred-traj", args->pred_traj,
                 "Predicted trajectory (TUM, or see --traj-format)");
  app.add_option("--gt-traj", args->gt_traj, "Ground-truth trajectory");
  app.add_option("--traj-format", args->traj_format,
                 "tum (t x y z qx qy qz qw), monst3r (pred_traj.txt: t x y z "
                 "qw qx qy qz), kitti (12 numbers per line, world_from_cam0; "
                 "times.txt beside it), colmap (images.txt, w2c), "
                 "reconstruction (the camera track of a VGGT/DA3/MegaSaM/"
                 "generic npz or a CUT3R/MonST3R folder) or auto")
      ->check(CLI::IsMember(
          {"tum", "monst3r", "kitti", "colmap", "reconstruction", "auto"}))
      ->capture_default_str();
  app.add_option("--units", args->units,
                 "Name of the trajectory units for the report");
  app.add_option("--pred-name", args->pred_name,
                 "Member of a pairs clip folder used as prediction")
      ->capture_default_str();
  app.add_option("--gt-name", args->gt_name,
                 "Member of a pairs clip folder used as ground truth")
      ->capture_default_str();
  app.add_option("--subset", args->subset,
                 "Ground-truth videos to evaluate: all (each needs a "
                 "prediction) or predicted (only those with a prediction, "
                 "e.g. after generate --limit N; the report counts and lists "
                 "the others)")
      ->check(CLI::IsMember({"all", "predicted"}))
      ->capture_default_str();
  app.add_option("--method", args->method, "Row label of the Markdown table")
      ->capture_default_str();
  app.add_option("--threads", args->threads,
                 "Threads for frame metrics (0 = all cores)")
      ->check(ThreadCountValidator());
  app.add_option("--out", args->out,
                 "report.json (also writes .csv, .md and .png beside it)")
      ->required();
  return [args] { return RunEval(*args); };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    eval,
    "eval",
    "PSNR/SSIM/LPIPS/FID/FVD between videos and ADE/FDE between "
    "trajectories, with a JSON/CSV/Markdown/PNG report",
    SetupEval);

}  // namespace geodrive

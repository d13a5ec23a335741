#include "eval/report.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "geometry/image_io.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace fs = std::filesystem;

namespace geodrive {
namespace {

double Get(const FrameScores& f, const std::string& metric) {
  if (metric == "psnr") return f.psnr_rgb;
  if (metric == "ssim") return f.ssim_rgb;
  if (metric == "psnr_y") return f.psnr_y;
  return f.ssim_y;
}

bool Has(const EvalReport& r, const std::string& metric) {
  return std::find(r.metrics.begin(), r.metrics.end(), metric) !=
         r.metrics.end();
}

nlohmann::json Num(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json();
}

void WriteText(const std::string& path, const std::string& text) {
  WriteFileAtomic(path, text);
}

std::string Fixed(double v, int digits) {
  if (!std::isfinite(v)) return "-";
  std::ostringstream os;
  os << std::fixed << std::setprecision(digits) << v;
  return os.str();
}

// Polyline plot of series (values per frame) into `roi` of `canvas`.
void PlotCurves(cv::Mat& canvas,
                const cv::Rect& roi,
                const std::string& title,
                const std::vector<std::vector<double>>& series,
                const std::vector<double>& mean) {
  cv::rectangle(canvas, roi, cv::Scalar(200, 200, 200), 1);
  cv::putText(canvas, title, roi.tl() + cv::Point(8, 20),
              cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  double lo = 1e300, hi = -1e300;
  size_t frames = 0;
  for (const auto& s : series) {
    frames = std::max(frames, s.size());
    for (double v : s) {
      if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
    }
  }
  if (frames < 1 || lo > hi) return;
  if (hi - lo < 1e-9) hi = lo + 1;
  const int margin = 30;
  auto point = [&](size_t i, double v) {
    const double x = frames > 1 ? static_cast<double>(i) / (frames - 1) : 0.5;
    return cv::Point(
        roi.x + margin + static_cast<int>(x * (roi.width - 2 * margin)),
        roi.y + roi.height - margin -
            static_cast<int>((v - lo) / (hi - lo) * (roi.height - 2 * margin)));
  };
  auto draw = [&](const std::vector<double>& s, const cv::Scalar& color,
                  int thickness) {
    for (size_t i = 1; i < s.size(); ++i) {
      if (std::isfinite(s[i - 1]) && std::isfinite(s[i])) {
        cv::line(canvas, point(i - 1, s[i - 1]), point(i, s[i]), color,
                 thickness, cv::LINE_AA);
      }
    }
  };
  for (const auto& s : series) draw(s, cv::Scalar(200, 170, 140), 1);
  draw(mean, cv::Scalar(160, 60, 0), 2);
  cv::putText(canvas, Fixed(hi, 3), roi.tl() + cv::Point(roi.width - 90, 20),
              cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(80, 80, 80), 1,
              cv::LINE_AA);
  cv::putText(canvas, Fixed(lo, 3),
              cv::Point(roi.x + roi.width - 90, roi.y + roi.height - 8),
              cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(80, 80, 80), 1,
              cv::LINE_AA);
  cv::putText(canvas, "frame",
              cv::Point(roi.x + roi.width / 2 - 20, roi.y + roi.height - 8),
              cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(80, 80, 80), 1,
              cv::LINE_AA);
}

// Top view: the two axes along which the ground truth moves most.
void PlotTrajectories(cv::Mat& canvas,
                      const cv::Rect& roi,
                      const EvalReport& r) {
  cv::rectangle(canvas, roi, cv::Scalar(200, 200, 200), 1);
  cv::putText(canvas, "trajectories (top view): gt black, pred red",
              roi.tl() + cv::Point(8, 20), cv::FONT_HERSHEY_SIMPLEX, 0.5,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  if (r.gt_centres.empty()) return;
  Eigen::Vector3d lo = r.gt_centres[0], hi = r.gt_centres[0];
  for (const auto* set : {&r.gt_centres, &r.pred_centres_aligned}) {
    for (const auto& c : *set) lo = lo.cwiseMin(c), hi = hi.cwiseMax(c);
  }
  const Eigen::Vector3d extent = hi - lo;
  int drop = 0;
  extent.minCoeff(&drop);
  const int u = drop == 0 ? 1 : 0, v = drop == 2 ? 1 : 2;
  const double span = std::max({extent[u], extent[v], 1e-9});
  const int margin = 40;
  const double scale = (std::min(roi.width, roi.height) - 2 * margin) / span;
  auto point = [&](const Eigen::Vector3d& c) {
    return cv::Point(
        roi.x + margin + static_cast<int>((c[u] - lo[u]) * scale),
        roi.y + roi.height - margin - static_cast<int>((c[v] - lo[v]) * scale));
  };
  auto draw = [&](const std::vector<Eigen::Vector3d>& cs,
                  const cv::Scalar& color) {
    for (size_t i = 1; i < cs.size(); ++i) {
      cv::line(canvas, point(cs[i - 1]), point(cs[i]), color, 2, cv::LINE_AA);
    }
    if (!cs.empty())
      cv::circle(canvas, point(cs.front()), 4, color, -1, cv::LINE_AA);
  };
  draw(r.gt_centres, cv::Scalar(0, 0, 0));
  draw(r.pred_centres_aligned, cv::Scalar(0, 0, 220));
  const char* axes = "xyz";
  std::ostringstream label;
  label << "axes " << axes[u] << " (right) / " << axes[v] << " (up)";
  if (r.trajectory) {
    label << ", ADE " << Fixed(r.trajectory->ade, 4) << " FDE "
          << Fixed(r.trajectory->fde, 4);
  }
  cv::putText(
      canvas, label.str(), cv::Point(roi.x + 8, roi.y + roi.height - 10),
      cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(80, 80, 80), 1, cv::LINE_AA);
}

}  // namespace

MeanStd EvalReport::Aggregate(const std::string& metric) const {
  MeanStd out;
  double sum = 0, sq = 0;
  for (const VideoEvalRecord& v : videos) {
    const double x = metric == "lpips" ? v.lpips : Get(v.scores.mean, metric);
    if (!std::isfinite(x)) continue;
    sum += x;
    sq += x * x;
    ++out.count;
  }
  if (out.count == 0) return {NAN, NAN, 0};
  out.mean = sum / out.count;
  out.std = std::sqrt(std::max(0.0, sq / out.count - out.mean * out.mean));
  return out;
}

namespace {

// The metrics of `r` that every video has (PSNR/SSIM family).
std::vector<std::string> PresentImageMetrics(const EvalReport& r) {
  const std::vector<std::string> image_metrics = {"psnr", "ssim", "psnr_y",
                                                  "ssim_y"};
  std::vector<std::string> present;
  const bool image_requested =
      std::any_of(image_metrics.begin(), image_metrics.end(),
                  [&](const std::string& m) { return Has(r, m); });
  for (const std::string& m : image_metrics) {
    if (image_requested && !r.videos.empty() &&
        std::isfinite(Get(r.videos[0].scores.mean, m)))
      present.push_back(m);
  }
  return present;
}

// The conventions block of report.json.
nlohmann::json Conventions(const EvalReport& r) {
  return {
      {"psnr",
       "10*log10(R^2/MSE) per frame over all channels, float64; identical "
       "frames give " +
           Fixed(r.frame_options.psnr_options.max_db, 1) +
           "; per video = mean over frames"},
      {"psnr_data_range", r.frame_options.psnr_options.data_range},
      {"ssim",
       "Wang et al. 2004 as skimage "
       "structural_similarity(gaussian_weights=True, sigma=" +
           Fixed(r.frame_options.ssim_options.sigma, 2) +
           ", use_sample_covariance=False, channel_axis=-1); per video = mean "
           "over frames"},
      {"ssim_data_range", r.frame_options.ssim_options.data_range},
      {"luma", "full-range BT.601 Y = 0.299 R + 0.587 G + 0.114 B (float64)"},
      {"dataset", "mean and population std over videos of the per-video means"},
      {"lpips",
       "TorchScript LPIPS model on frames /255*2-1, no resize; per video = "
       "mean over frames"},
      {"fid",
       "Frechet distance of TorchScript Inception features of all frames "
       "(/255, bilinear 299x299, 2x-1), unbiased covariance"},
      {"fvd",
       "Frechet distance of TorchScript I3D features of whole clips "
       "(common_metrics: /255, short side 224, centre crop, 2x-1)"}};
}

void WriteReportJson(const EvalReport& r,
                     const std::vector<std::string>& present,
                     const std::string& json_path) {
  nlohmann::json j;
  j["pred"] = r.pred;
  j["gt"] = r.gt;
  j["metrics"] = r.metrics;
  j["conventions"] = Conventions(r);
  nlohmann::json summary;
  for (const std::string& m : present) {
    const MeanStd s = r.Aggregate(m);
    summary[m] = {
        {"mean", Num(s.mean)}, {"std", Num(s.std)}, {"videos", s.count}};
  }
  const bool has_lpips = !r.lpips_model.empty();
  if (has_lpips) {
    const MeanStd s = r.Aggregate("lpips");
    summary["lpips"] = {{"mean", Num(s.mean)},
                        {"std", Num(s.std)},
                        {"videos", s.count},
                        {"model", r.lpips_model}};
  }
  for (const auto& [name, f] : {std::pair("fid", &r.fid), {"fvd", &r.fvd}}) {
    if (!*f) continue;
    const FrechetReport& x = **f;
    summary[name] = {{"value", Num(x.distance)},
                     {"pred_samples", x.pred_samples},
                     {"gt_samples", x.gt_samples ? nlohmann::json(*x.gt_samples)
                                                 : nlohmann::json(nullptr)},
                     {"dims", x.dims},
                     {"model", x.model},
                     {"gt_stats", x.gt_stats}};
  }
  if (r.trajectory) {
    const TrajectoryErrors& t = *r.trajectory;
    summary["ade"] = Num(t.ade);
    summary["fde"] = Num(t.fde);
    j["trajectory"] = {{"alignment", ToString(t.alignment)},
                       {"units", t.units},
                       {"factor", t.factor},
                       {"ade", Num(t.ade)},
                       {"fde", Num(t.fde)},
                       {"rmse", Num(t.rmse)},
                       {"max", Num(t.max)},
                       {"scale", t.gt_from_pred.scale},
                       {"per_frame", t.per_frame}};
  }
  j["summary"] = summary;
  if (r.subset) {
    j["subset"] = {{"mode", ToString(r.subset->subset)},
                   {"evaluated", r.subset->evaluated},
                   {"ground_truth", r.subset->ground_truth},
                   {"without_prediction", r.subset->without_prediction},
                   {"description", r.subset->BriefReport()}};
  }
  nlohmann::json videos = nlohmann::json::array();
  for (const VideoEvalRecord& v : r.videos) {
    nlohmann::json jv = {{"id", v.id},
                         {"pred", v.pred_path},
                         {"gt", v.gt_path},
                         {"frames", v.scores.frames.size()},
                         {"width", v.scores.width},
                         {"height", v.scores.height}};
    for (const std::string& m : present) {
      jv[m] = Num(Get(v.scores.mean, m));
      std::vector<double> per_frame;
      for (const FrameScores& f : v.scores.frames)
        per_frame.push_back(Get(f, m));
      jv[m + "_per_frame"] = per_frame;
    }
    if (has_lpips) {
      jv["lpips"] = Num(v.lpips);
      jv["lpips_per_frame"] = v.lpips_per_frame;
    }
    videos.push_back(jv);
  }
  j["videos"] = videos;
  WriteText(json_path, j.dump(2) + "\n");
}

void WriteReportCsv(const EvalReport& r,
                    const std::vector<std::string>& present,
                    const std::string& csv_path) {
  const bool has_lpips = !r.lpips_model.empty();
  std::ostringstream csv;
  csv << "id,frames,width,height";
  for (const std::string& m : present) csv << "," << m;
  if (has_lpips) csv << ",lpips";
  csv << ",pred,gt\n";
  csv << std::setprecision(10);
  for (const VideoEvalRecord& v : r.videos) {
    csv << v.id << "," << v.scores.frames.size() << "," << v.scores.width << ","
        << v.scores.height;
    for (const std::string& m : present) csv << "," << Get(v.scores.mean, m);
    if (has_lpips) csv << "," << v.lpips;
    csv << "," << v.pred_path << "," << v.gt_path << "\n";
  }
  WriteText(csv_path, csv.str());
}

// GeoDrive's Table 1 layout.
void WriteReportMarkdown(const EvalReport& r, const std::string& md_path) {
  const bool has_lpips = !r.lpips_model.empty();
  const std::string suffix = r.x100 ? "×10²" : "";
  std::ostringstream md;
  md << "| Model | LPIPS↓ | PSNR↑ | SSIM↑ | FID↓ | FVD↓ | ADE" << suffix
     << "↓ | FDE" << suffix << "↓ |\n|---|---|---|---|---|---|---|---|\n";
  auto cell = [&](const std::string& m, int digits) {
    if (!Has(r, m)) return std::string("-");
    return Fixed(r.Aggregate(m).mean, digits);
  };
  auto frechet = [](const std::optional<FrechetReport>& f) {
    return f ? Fixed(f->distance, 2) : std::string("-");
  };
  md << "| " << r.method << " | "
     << (has_lpips ? Fixed(r.Aggregate("lpips").mean, 4) : "-") << " | "
     << cell("psnr", 3) << " | " << cell("ssim", 4) << " | " << frechet(r.fid)
     << " | " << frechet(r.fvd) << " | "
     << (r.trajectory && Has(r, "ade") ? Fixed(r.trajectory->ade, 2) : "-")
     << " | "
     << (r.trajectory && Has(r, "fde") ? Fixed(r.trajectory->fde, 2) : "-")
     << " |\n\n";
  md << r.videos.size() << " videos";
  if (r.subset) md << "; " << r.subset->BriefReport();
  md << ". PSNR: data range " << r.frame_options.psnr_options.data_range
     << ", mean over frames then videos. SSIM: "
     << "11×11 Gaussian σ 1.5, population covariance (skimage "
        "gaussian_weights=True). ";
  if (r.trajectory) {
    md << "ADE/FDE: alignment " << ToString(r.trajectory->alignment) << ", "
       << r.trajectory->units << (r.x100 ? ", ×10²" : "") << ". ";
  }
  if (has_lpips) md << "LPIPS: " << r.lpips_model << ", mean over frames. ";
  if (r.fid) {
    md << "FID: " << r.fid->model << ", " << r.fid->pred_samples
       << " predicted frames vs "
       << (r.fid->gt_samples
               ? std::to_string(*r.fid->gt_samples) + " ground-truth frames"
               : "cached statistics " + r.fid->gt_stats)
       << ". ";
  }
  if (r.fvd) {
    md << "FVD: " << r.fvd->model << ", " << r.fvd->pred_samples
       << " predicted clips vs "
       << (r.fvd->gt_samples
               ? std::to_string(*r.fvd->gt_samples) + " ground-truth clips"
               : "cached statistics " + r.fvd->gt_stats)
       << ". ";
  }
  if (!has_lpips && !r.fid && !r.fvd) md << "LPIPS/FID/FVD: not computed.";
  md << "\n";
  if (Has(r, "psnr_y") || r.frame_options.luma) {
    md << "\nLuma (BT.601 Y): PSNR-Y " << Fixed(r.Aggregate("psnr_y").mean, 3)
       << ", SSIM-Y " << Fixed(r.Aggregate("ssim_y").mean, 4) << "\n";
  }
  WriteText(md_path, md.str());
}

// Per-frame PSNR/SSIM curves and the trajectories.
void WriteReportPlot(const EvalReport& r, const std::string& png_path) {
  cv::Mat canvas(720, 1280, CV_8UC3, cv::Scalar(255, 255, 255));
  std::vector<std::vector<double>> psnr, ssim;
  size_t max_frames = 0;
  for (const VideoEvalRecord& v : r.videos)
    max_frames = std::max(max_frames, v.scores.frames.size());
  std::vector<double> psnr_mean(max_frames, 0), ssim_mean(max_frames, 0);
  std::vector<int> count(max_frames, 0);
  for (const VideoEvalRecord& v : r.videos) {
    psnr.emplace_back();
    ssim.emplace_back();
    for (size_t i = 0; i < v.scores.frames.size(); ++i) {
      psnr.back().push_back(v.scores.frames[i].psnr_rgb);
      ssim.back().push_back(v.scores.frames[i].ssim_rgb);
      psnr_mean[i] += v.scores.frames[i].psnr_rgb;
      ssim_mean[i] += v.scores.frames[i].ssim_rgb;
      ++count[i];
    }
  }
  for (size_t i = 0; i < max_frames; ++i) {
    psnr_mean[i] /= std::max(count[i], 1);
    ssim_mean[i] /= std::max(count[i], 1);
  }
  PlotCurves(canvas, cv::Rect(10, 10, 620, 340),
             "PSNR (dB) per frame, mean in blue", psnr, psnr_mean);
  PlotCurves(canvas, cv::Rect(10, 370, 620, 340),
             "SSIM per frame, mean in blue", ssim, ssim_mean);
  PlotTrajectories(canvas, cv::Rect(650, 10, 620, 700), r);
  // Drawn in OpenCV's BGR order (the colours named above); written as RGB.
  cv::Mat rgb;
  cv::cvtColor(canvas, rgb, cv::COLOR_BGR2RGB);
  WriteImageRgb(png_path, rgb);
}

}  // namespace

std::vector<std::string> WriteEvalOutputs(const EvalReport& r,
                                          const std::string& json_path) {
  const fs::path base = fs::path(json_path).replace_extension();
  const std::string csv_path = base.string() + ".csv",
                    md_path = base.string() + ".md",
                    png_path = base.string() + ".png";
  if (fs::path(json_path).has_parent_path()) {
    CreateOutputDirectory(fs::path(json_path).parent_path().string());
  }
  const std::vector<std::string> present = PresentImageMetrics(r);
  WriteReportJson(r, present, json_path);
  WriteReportCsv(r, present, csv_path);
  WriteReportMarkdown(r, md_path);
  WriteReportPlot(r, png_path);
  return {json_path, csv_path, md_path, png_path};
}

}  // namespace geodrive

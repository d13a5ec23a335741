#include "dataset/lidar_alignment.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "geometry/util/status.h"

namespace geodrive {

void LidarScaleOptions::Check() const {
  GEODRIVE_CHECK_INPUT(max_time_gap_s > 0,
                       "lidar scale: max_time_gap_s must be > 0");
  projection.Check();
  fit.Check();
}

std::optional<size_t> FindLidarSweep(const DriveClip& clip,
                                     int frame,
                                     LidarSweepChoice choice,
                                     double max_time_gap_s,
                                     std::string* reason) {
  const DriveFrame& f = clip.frames.at(frame);
  if (!clip.lidar) {
    if (reason) *reason = "dataset has no LiDAR (LIDAR_TOP)";
    return std::nullopt;
  }
  const std::optional<size_t> best = choice == LidarSweepChoice::kKeyframe
                                         ? f.keyframe_sweep
                                         : clip.lidar->Nearest(f.timestamp_us);
  if (!best) {
    if (reason) *reason = "no LiDAR sweep in the scene";
    return std::nullopt;
  }
  const double gap =
      std::abs(clip.lidar->Sweeps()[*best].timestamp_us - f.timestamp_us) *
      1e-6;
  if (gap > max_time_gap_s) {
    if (reason) {
      std::ostringstream os;
      os << "nearest LiDAR sweep is " << gap * 1e3 << " ms away (max "
         << max_time_gap_s * 1e3 << " ms)";
      *reason = os.str();
    }
    return std::nullopt;
  }
  return best;
}

Trajectory CameraTrajectory(const DriveClip& clip) {
  Trajectory t;
  for (const DriveFrame& f : clip.frames)
    t.Add(f.timestamp_us * 1e-6, f.world_from_cam);
  return t;
}

ClipScaleReport FitClipLidarScale(const DriveClip& clip,
                                  const Monst3rFolder& monst3r,
                                  const LidarScaleOptions& options) {
  options.Check();
  GEODRIVE_CHECK_INPUT(clip.num_frames() == monst3r.num_frames(),
                       monst3r.dir(), ": MonST3R folder has ",
                       monst3r.num_frames(), " frames but the clip has ",
                       clip.num_frames());
  ClipScaleReport report;
  std::vector<double> all_lidar, all_est;
  Monst3rLoadOptions load;
  load.rgb = false;
  load.confidence = false;
  load.dynamic_masks = options.skip_dynamic && !options.use_enlarged_masks;
  load.enlarged_dynamic_masks =
      options.skip_dynamic && options.use_enlarged_masks;
  load.reject_all_invalid_confidence = false;
  for (int i = 0; i < clip.num_frames(); ++i) {
    FrameScaleReport fr;
    fr.frame = i;
    const DriveFrame& cam_frame = clip.frames[i];
    std::string reason;
    fr.lidar_sweep = FindLidarSweep(clip, i, options.sweep,
                                    options.max_time_gap_s, &reason);
    if (!fr.lidar_sweep) {
      fr.skip_reason = reason;
      report.frames.push_back(fr);
      continue;
    }
    const LidarSweepInfo& sweep = clip.lidar->Sweeps()[*fr.lidar_sweep];
    fr.time_gap_s = std::abs(sweep.timestamp_us - cam_frame.timestamp_us) *
                    1e-6;
    const PointCloud cloud = clip.lidar->Load(*fr.lidar_sweep);
    const PinholeCamera& cam = cam_frame.camera;
    const LidarProjection proj = MapPointCloudToImage(
        cloud.positions, sweep.ego_from_sensor, sweep.world_from_ego,
        cam_frame.world_from_ego, cam_frame.ego_from_cam, cam.K(), cam.width,
        cam.height, options.projection);
    fr.points_in_image = static_cast<int>(proj.size());
    const ImageResizeSpec spec = monst3r.SourceToGrid(cam.width, cam.height);
    GEODRIVE_CHECK_INPUT(
        spec.width == monst3r.width() && spec.height == monst3r.height(),
        monst3r.dir(), ": ", monst3r.format(), " images are ", monst3r.width(),
        "x", monst3r.height(), " but the camera's ", cam.width, "x", cam.height,
        " maps to ", spec.width, "x", spec.height, " (",
        ToString(monst3r.grid_resize()), ")");
    const Monst3rFrame frame = monst3r.LoadFrame(i, load);
    const cv::Mat& mask = !options.skip_dynamic ? cv::Mat()
                          : options.use_enlarged_masks
                              ? frame.enlarged_dynamic_mask
                              : frame.dynamic_mask;
    const double sx = static_cast<double>(spec.resized_width) / cam.width;
    const double sy = static_cast<double>(spec.resized_height) / cam.height;
    std::vector<double> dl, de;
    for (size_t k = 0; k < proj.size(); ++k) {
      // Integer-index pixels: centres map as u' + 0.5 = (u + 0.5) * s, then the
      // crop.
      const double u = (proj.pixels[k].x() + 0.5) * sx - 0.5 - spec.crop_left;
      const double v = (proj.pixels[k].y() + 0.5) * sy - 0.5 - spec.crop_top;
      const double d = SampleDepthBilinear(frame.depth, mask, u, v);
      if (!std::isfinite(d)) continue;
      dl.push_back(proj.depths[k]);
      de.push_back(d);
      fr.samples.push_back({static_cast<float>(u), static_cast<float>(v),
                            static_cast<float>(proj.depths[k]),
                            static_cast<float>(d)});
    }
    fr.fit = FitDepthScale(dl, de, options.fit);
    if (!fr.fit.success) {
      fr.skip_reason = "scale fit failed: " + fr.fit.message;
    } else {
      fr.used = true;
      all_lidar.insert(all_lidar.end(), dl.begin(), dl.end());
      all_est.insert(all_est.end(), de.begin(), de.end());
    }
    report.frames.push_back(std::move(fr));
  }
  report.clip_fit = FitDepthScale(all_lidar, all_est, options.fit);
  if (!report.clip_fit.success) {
    report.message = "clip scale fit failed: " + report.clip_fit.message;
    return report;
  }
  const double s = report.clip_fit.scale;
  report.metric_reference = CameraTrajectory(clip).RelativeToFirst();
  report.scaled_monst3r.timestamps = report.metric_reference.timestamps;
  const Rigid3d first_inv =
      monst3r.trajectory().world_from_cam.front().Inverse();
  for (const auto& pose : monst3r.trajectory().world_from_cam) {
    Rigid3d rel = first_inv * pose;
    rel.translation *= s;
    report.scaled_monst3r.world_from_cam.push_back(rel);
  }
  if (report.scaled_monst3r.size() >= 3) {
    report.trajectory_error = EvaluateTrajectory(
        report.scaled_monst3r, report.metric_reference, options.alignment);
    report.aligned_monst3r = TransformTrajectory(
        report.trajectory_error.ref_from_est, report.scaled_monst3r);
  } else {
    report.aligned_monst3r = report.scaled_monst3r;
  }
  report.success = true;
  report.message = "ok";
  return report;
}

std::string ClipScaleReport::BriefReport() const {
  std::ostringstream os;
  int used = 0;
  for (const auto& f : frames) used += f.used;
  os << (success ? "ok" : "FAILED: " + message) << "; "
     << clip_fit.BriefReport() << "; frames " << used << "/" << frames.size()
     << " used";
  if (success && aligned_monst3r.size() >= 3)
    os << "; " << trajectory_error.BriefReport();
  return os.str();
}

std::string ClipScaleReportToJson(const ClipScaleReport& r) {
  using nlohmann::json;
  auto fit_json = [](const DepthScaleResult& f) {
    return json{{"success", f.success},
                {"message", f.message},
                {"scale", f.scale},
                {"num_points", f.num_points},
                {"num_inliers", f.num_inliers},
                {"inlier_fraction", f.inlier_fraction},
                {"residual_p50_m", f.residual_p50},
                {"residual_p90_m", f.residual_p90},
                {"residual_p99_m", f.residual_p99}};
  };
  auto stats = [](const ErrorStats& s) {
    return json{{"rms", s.rms},
                {"mean", s.mean},
                {"median", s.median},
                {"max", s.max},
                {"count", s.count}};
  };
  json j;
  j["success"] = r.success;
  j["message"] = r.message;
  j["units"] =
      "metres (LiDAR); MonST3R depth in MonST3R units; scale = metres per "
      "MonST3R unit";
  j["clip"] = fit_json(r.clip_fit);
  json frames = json::array();
  for (const auto& f : r.frames) {
    json fj = {{"frame", f.frame},
               {"used", f.used},
               {"skip_reason", f.skip_reason},
               {"time_gap_s", f.time_gap_s},
               {"points_in_image", f.points_in_image},
               {"points_on_valid_depth", f.samples.size()}};
    if (f.lidar_sweep) fj["fit"] = fit_json(f.fit);
    frames.push_back(fj);
  }
  j["frames"] = frames;
  if (r.success) {
    j["trajectory"] = {
        {"alignment", ToString(r.trajectory_error.alignment)},
        {"convention", "evo APE/RPE (delta 1 frame), translation in metres"},
        {"ate_m", stats(r.trajectory_error.ate)},
        {"rpe_trans_m", stats(r.trajectory_error.rpe_trans)},
        {"rpe_rot_deg", stats(r.trajectory_error.rpe_rot_deg)}};
  }
  return j.dump(2) + "\n";
}

cv::Mat DrawScaleResiduals(const Monst3rFrame& frame,
                           const FrameScaleReport& report,
                           double scale) {
  cv::Mat canvas;
  if (!frame.rgb.empty()) {
    cv::resize(frame.rgb, canvas, cv::Size(), 2.0, 2.0, cv::INTER_LINEAR);
  } else {
    canvas = cv::Mat(frame.depth.rows * 2, frame.depth.cols * 2, CV_8UC3,
                     cv::Scalar(40, 40, 40));
  }
  for (const auto& s : report.samples) {
    const double rel = std::min(
        1.0, std::abs(s.d_lidar - scale * s.d_monst3r) / s.d_lidar / 0.1);
    const cv::Scalar color(255 * rel, 255 * (1 - rel),
                           0);  // RGB: green good -> red bad
    cv::circle(canvas,
               cv::Point(static_cast<int>(std::lround(2 * s.u)),
                         static_cast<int>(std::lround(2 * s.v))),
               2, color, cv::FILLED, cv::LINE_AA);
  }
  return canvas;
}

}  // namespace geodrive

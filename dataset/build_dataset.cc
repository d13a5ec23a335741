#include "dataset/build_dataset.h"

#include <glog/logging.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>
#include <thread>

#include "dataset/clips.h"
#include "dataset/job.h"
#include "dataset/lidar_alignment.h"
#include "dataset/nuscenes.h"
#include "dataset/nuscenes_projection.h"
#include "dataset/pairs.h"
#include "geodrive_version.h"
#include "geometry/image_io.h"
#include "geometry/monst3r.h"
#include "geometry/pointmap.h"
#include "geometry/status.h"
#include "render/boxes.h"
#include "render/dynamic_edit.h"
#include "render/presets.h"
#include "render/renderer.h"
#include "render/video.h"
#include "render/video_h264.h"

namespace geodrive {

namespace fs = std::filesystem;
using nlohmann::json;

std::string ToString(GeometrySource source) {
  return source == GeometrySource::kMonst3r ? "monst3r" : "lidar";
}

GeometrySource ParseGeometrySource(const std::string& text) {
  if (text == "monst3r") return GeometrySource::kMonst3r;
  if (text == "lidar") return GeometrySource::kLidar;
  throw InputError("unknown geometry source '" + text +
                   "' (expected monst3r or lidar)");
}

void BuildDatasetOptions::Check() {
  GEODRIVE_CHECK_INPUT(!dataroot.empty(),
                       "build-dataset: --dataroot is required");
  GEODRIVE_CHECK_INPUT(fs::is_directory(dataroot), dataroot,
                       ": dataroot is not a directory");
  GEODRIVE_CHECK_INPUT(!out.empty(), "build-dataset: --out is required");
  if (geometry == "auto") geometry = monst3r_root.empty() ? "lidar" : "monst3r";
  const GeometrySource source = ParseGeometrySource(geometry);
  if (source == GeometrySource::kMonst3r) {
    GEODRIVE_CHECK_INPUT(!monst3r_root.empty(),
                         "build-dataset: --geometry monst3r needs --monst3r");
    GEODRIVE_CHECK_INPUT(fs::is_directory(monst3r_root), monst3r_root,
                         ": MonST3R root is not a directory");
  }
  GEODRIVE_CHECK_INPUT(threads >= 1 && threads <= 256,
                       "build-dataset: --threads must be 1..256");
  GEODRIVE_CHECK_INPUT(
      shard_count >= 1 && shard_index >= 0 && shard_index < shard_count,
      "build-dataset: --shard must be i/N with 0 <= i < N");
  ParseRenderPreset(preset);
  GEODRIVE_CHECK_INPUT(
      edit_mode == "3d" || edit_mode == "2d" || edit_mode == "none",
      "build-dataset: --edit-mode must be 3d, 2d or none");
  GEODRIVE_CHECK_INPUT(
      width >= 16 && height >= 16 && width <= 16384 && height <= 16384,
      "build-dataset: output size must be within 16..16384");
  ParseResizeMode(resize_mode);
  GEODRIVE_CHECK_INPUT(fps > 0 && fps <= 240,
                       "build-dataset: --fps must be in (0, 240]");
  GEODRIVE_CHECK_INPUT(clip_frames >= 2 && clip_stride >= 1,
                       "build-dataset: bad clip options");
  GEODRIVE_CHECK_INPUT(min_confidence >= 0 && min_confidence <= 1,
                       "build-dataset: --min-confidence must be in [0, 1]");
  GEODRIVE_CHECK_INPUT(
      min_depth_m >= 0 && max_depth_m > min_depth_m,
      "build-dataset: depth range must satisfy 0 <= min < max");
  GEODRIVE_CHECK_INPUT(splat_radius_px >= 0 && splat_radius_px <= 16,
                       "build-dataset: --splat-radius must be in [0, 16]");
}

std::string BuildDatasetOptions::ContentOptionsJson() const {
  json j;  // nlohmann::json objects keep keys sorted: stable text
  j["version"] = version;
  j["geometry"] = geometry;
  j["preset"] = preset;
  j["edit_mode"] = edit_mode;
  j["clip_frames"] = clip_frames;
  j["clip_stride"] = clip_stride;
  j["width"] = width;
  j["height"] = height;
  j["resize_mode"] = resize_mode;
  j["fps"] = fps;
  j["lossless_frames"] = lossless_frames;
  j["video_preset"] = video_preset;
  j["video_crf"] = video_crf;
  j["min_confidence"] = min_confidence;
  j["min_depth_m"] = min_depth_m;
  j["max_depth_m"] = max_depth_m;
  j["splat_radius_px"] = splat_radius_px;
  j["lidar_window_s"] = {lidar_window_before_s, lidar_window_after_s};
  return j.dump();
}

std::string BuildDatasetSummary::BriefReport() const {
  std::ostringstream os;
  os << "pairs built " << built << ", skipped (already built) "
     << skipped_existing;
  if (skipped_no_monst3r)
    os << ", skipped (no MonST3R folder) " << skipped_no_monst3r;
  os << ", failed " << failed;
  for (const auto& [stage, n] : failures_by_stage)
    os << " [" << stage << ": " << n << "]";
  os << " of " << clips_total << " clips in " << seconds_total << " s";
  if (interrupted) os << " (interrupted: rerun to resume)";
  os << "\ntime per stage (s, summed over clips):";
  for (const auto& [stage, s] : seconds_by_stage)
    os << " " << stage << " " << s;
  return os.str();
}

namespace {

// A failure inside one clip, tagged with the stage it happened in.
struct StageError : std::runtime_error {
  StageError(std::string s, const std::string& what)
      : std::runtime_error(what), stage(std::move(s)) {}
  std::string stage;
};

class StageTimer {
 public:
  explicit StageTimer(std::map<std::string, double>* sink) : sink_(sink) {}
  template <typename F>
  auto Run(const std::string& stage, F&& f) -> decltype(f()) {
    const auto t0 = std::chrono::steady_clock::now();
    try {
      if constexpr (std::is_void_v<decltype(f())>) {
        f();
        Add(stage, t0);
      } else {
        auto result = f();
        Add(stage, t0);
        return result;
      }
    } catch (const StageError&) {
      Add(stage, t0);
      throw;
    } catch (const std::exception& e) {
      Add(stage, t0);
      throw StageError(stage, e.what());
    }
  }

 private:
  void Add(const std::string& stage, std::chrono::steady_clock::time_point t0) {
    (*sink_)[stage] +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
            .count();
  }
  std::map<std::string, double>* sink_;
};

cv::Mat ResizeToOutput(const cv::Mat& rgb, const ImageResizeSpec& spec) {
  cv::Mat resized;
  const bool down = spec.resized_width < rgb.cols;
  cv::resize(rgb, resized, cv::Size(spec.resized_width, spec.resized_height), 0,
             0, down ? cv::INTER_AREA : cv::INTER_LINEAR);
  return resized(
             cv::Rect(spec.crop_left, spec.crop_top, spec.width, spec.height))
      .clone();
}

bool IsVehicle(const std::string& category) {
  return category.rfind("vehicle.", 0) == 0;
}

// PSNR (dB, data range 255) over the pixels where mask != 0; NaN if none.
double MaskedPsnr(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  double se = 0;
  int64_t n = 0;
  for (int y = 0; y < a.rows; ++y) {
    const auto* pa = a.ptr<cv::Vec3b>(y);
    const auto* pb = b.ptr<cv::Vec3b>(y);
    const auto* pm = mask.ptr<uint8_t>(y);
    for (int x = 0; x < a.cols; ++x) {
      if (!pm[x]) continue;
      for (int c = 0; c < 3; ++c) {
        const double d = static_cast<double>(pa[x][c]) - pb[x][c];
        se += d * d;
      }
      n += 3;
    }
  }
  if (n == 0) return std::nan("");
  const double mse = se / n;
  return mse <= 0 ? 100.0 : 10.0 * std::log10(255.0 * 255.0 / mse);
}

struct ClipContext {
  const Nuscenes* nusc = nullptr;
  const BuildDatasetOptions* options = nullptr;
  GeometrySource source = GeometrySource::kMonst3r;
  bool has_lidar = false;
};

// The static LiDAR cloud around frame 0, in the frame of camera 0, coloured
// from the clip's images (points not seen by any frame are dropped; boxes of
// annotated objects are removed).
PointCloud BuildLidarCloud(const ClipContext& ctx,
                           const Clip& clip,
                           const std::vector<cv::Mat>& images_full) {
  const Nuscenes& nusc = *ctx.nusc;
  const int32_t lidar_sensor = nusc.FindSensor("LIDAR_TOP");
  GEODRIVE_CHECK_INPUT(lidar_sensor != kNoIndex,
                       "dataset has no LIDAR_TOP: use --geometry monst3r");
  const auto& chain = nusc.Chain(clip.scene, lidar_sensor);
  const int64_t t0 = clip.timestamps.front();
  const int64_t lo =
      t0 - static_cast<int64_t>(ctx.options->lidar_window_before_s * 1e6);
  const int64_t hi =
      t0 + static_cast<int64_t>(ctx.options->lidar_window_after_s * 1e6);
  const Rigid3d cam0_from_global =
      nusc.WorldFromSensor(clip.sample_data.front()).Inverse();
  PointCloud cloud;
  std::vector<int64_t> point_time;
  for (int32_t sd : chain) {
    const int64_t t = nusc.sample_data()[sd].timestamp;
    if (t < lo || t > hi) continue;
    const PointCloud sweep = nusc.LoadLidar(sd);
    const Rigid3d global_from_lidar = nusc.WorldFromSensor(sd);
    const std::vector<NuscenesBox> boxes = nusc.GetBoxes(sd);
    for (size_t i = 0; i < sweep.size(); ++i) {
      const Eigen::Vector3d p = sweep.positions[i].cast<double>();
      if (p.head<2>().norm() < 2.5) continue;  // ego vehicle returns
      const Eigen::Vector3d g = global_from_lidar * p;
      bool in_box = false;
      for (const auto& b : boxes) {
        const Eigen::Vector3d local =
            b.orientation.conjugate() * (g - b.center);
        if (std::abs(local.x()) <= b.wlh.y() / 2 + 0.3 &&
            std::abs(local.y()) <= b.wlh.x() / 2 + 0.3 &&
            std::abs(local.z()) <= b.wlh.z() / 2 + 0.3) {
          in_box = true;
          break;
        }
      }
      if (in_box) continue;
      cloud.positions.push_back((cam0_from_global * g).cast<float>());
      point_time.push_back(t);
    }
  }
  // Colour: each point from the clip frame nearest in time where it projects
  // inside the image and is not hidden (its depth within 5 % of the nearest
  // point in its 4x4-pixel cell).
  const size_t n = cloud.size();
  std::vector<int> best_frame(n, -1);
  std::vector<int64_t> best_dt(n, INT64_MAX);
  std::vector<Color3u8> colors(n, Color3u8(0, 0, 0));
  for (size_t f = 0; f < clip.sample_data.size(); ++f) {
    const int32_t sd = clip.sample_data[f];
    const PinholeCamera cam = nusc.Camera(sd);
    const Rigid3d cam_from_cam0 =
        nusc.WorldFromSensor(sd).Inverse() *
        nusc.WorldFromSensor(clip.sample_data.front());
    const int cw = (cam.width + 3) / 4, ch = (cam.height + 3) / 4;
    std::vector<float> zmin(static_cast<size_t>(cw) * ch,
                            std::numeric_limits<float>::infinity());
    std::vector<Eigen::Vector3f> proj(n);
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d pc =
          cam_from_cam0 * cloud.positions[i].cast<double>();
      proj[i] = Eigen::Vector3f(-1, -1, -1);
      if (pc.z() < 1.0) continue;
      const Eigen::Vector2d uv = cam.Project(pc);
      if (uv.x() < 0 || uv.y() < 0 || uv.x() > cam.width - 1 ||
          uv.y() > cam.height - 1)
        continue;
      proj[i] = Eigen::Vector3f(uv.x(), uv.y(), pc.z());
      float& z = zmin[static_cast<size_t>(uv.y() / 4) * cw +
                      static_cast<size_t>(uv.x() / 4)];
      z = std::min(z, static_cast<float>(pc.z()));
    }
    const cv::Mat& img = images_full[f];
    for (size_t i = 0; i < n; ++i) {
      if (proj[i].z() <= 0) continue;
      const float z = zmin[static_cast<size_t>(proj[i].y() / 4) * cw +
                           static_cast<size_t>(proj[i].x() / 4)];
      if (proj[i].z() > z * 1.05f) continue;
      const int64_t dt = std::llabs(clip.timestamps[f] - point_time[i]);
      if (dt >= best_dt[i]) continue;
      best_dt[i] = dt;
      best_frame[i] = static_cast<int>(f);
      const cv::Vec3b c =
          img.at<cv::Vec3b>(static_cast<int>(std::lround(proj[i].y())),
                            static_cast<int>(std::lround(proj[i].x())));
      colors[i] = Color3u8(c[0], c[1], c[2]);
    }
  }
  PointCloud out;
  for (size_t i = 0; i < n; ++i) {
    if (best_frame[i] < 0) continue;
    out.positions.push_back(cloud.positions[i]);
    out.colors.push_back(colors[i]);
  }
  GEODRIVE_CHECK_INPUT(!out.empty(),
                       "no LiDAR point of the clip is visible in its images");
  return out;
}

// Builds one pair into `tmp_dir`; returns its meta. Throws StageError.
PairMeta BuildPair(const ClipContext& ctx,
                   const Clip& clip,
                   const std::string& tmp_dir,
                   std::map<std::string, double>* stage_seconds) {
  const Nuscenes& nusc = *ctx.nusc;
  const BuildDatasetOptions& opt = *ctx.options;
  StageTimer timer(stage_seconds);
  const int n = static_cast<int>(clip.sample_data.size());
  const int32_t sd0 = clip.sample_data.front();
  const PinholeCamera cam_full =
      timer.Run("gt", [&] { return nusc.Camera(sd0); });
  const ResizeMode resize_mode = ParseResizeMode(opt.resize_mode);
  const ImageResizeSpec out_spec = ComputeResizeSpec(
      cam_full.width, cam_full.height, opt.width, opt.height, resize_mode);

  // 1. Ground-truth frames.
  std::vector<cv::Mat> images_full(n), gt(n);
  timer.Run("gt", [&] {
    for (int i = 0; i < n; ++i) {
      images_full[i] = ReadImageRgb(nusc.DataPath(clip.sample_data[i]));
      GEODRIVE_CHECK_INPUT(images_full[i].cols == cam_full.width &&
                               images_full[i].rows == cam_full.height,
                           nusc.DataPath(clip.sample_data[i]), ": image is ",
                           images_full[i].cols, "x", images_full[i].rows,
                           " but sample_data says ", cam_full.width, "x",
                           cam_full.height);
      gt[i] = ResizeToOutput(images_full[i], out_spec);
    }
  });

  PairMeta meta;
  meta.clip_id = clip.id;
  meta.scene_name = nusc.scenes()[clip.scene].name;
  meta.scene_token = nusc.scenes()[clip.scene].token.ToString();
  for (int i = 0; i < n; ++i) {
    const auto& sd = nusc.sample_data()[clip.sample_data[i]];
    meta.frames.push_back({sd.token.ToString(), sd.timestamp, sd.filename});
  }
  meta.fps = opt.fps;
  meta.resize_mode = opt.resize_mode;
  meta.geometry_source = ToString(ctx.source);
  meta.preset = opt.preset;
  meta.edit_mode = opt.edit_mode;
  meta.options_json = opt.ContentOptionsJson();
  meta.options_hash = StableHash64(meta.options_json);
  meta.tool_version = GEODRIVE_VERSION;

  // 2. Geometry: a cloud in the frame of camera 0, per-frame cam0_from_cam, and
  // the camera at the output size.
  PointCloud cloud;
  std::vector<Rigid3d> cam0_from_cam(n);
  PinholeCamera cam_out;
  cv::Mat dynamic_mask0;
  bool metric = true;
  if (ctx.source == GeometrySource::kMonst3r) {
    const std::string dir = opt.monst3r_root + "/" + clip.id;
    const Monst3rFolder folder =
        timer.Run("geometry", [&] { return Monst3rFolder::Open(dir); });
    if (folder.num_frames() != n) {
      throw StageError("geometry", dir + ": MonST3R folder has " +
                                       std::to_string(folder.num_frames()) +
                                       " frames but the clip has " +
                                       std::to_string(n));
    }
    double scale = 1.0;
    if (ctx.has_lidar) {
      const ClipScaleReport report = timer.Run("scale", [&] {
        return FitClipLidarScale(nusc, clip.sample_data, folder,
                                 LidarScaleOptions());
      });
      if (report.success) {
        scale = report.clip_fit.scale;
        meta.scale_source = "lidar";
        meta.scale_report = report.BriefReport();
        meta.quality.scale_inlier_fraction = report.clip_fit.inlier_fraction;
      } else {
        metric = false;
        meta.scale_source = "none";
        meta.scale_report = report.message;
      }
    } else {
      metric = false;
      meta.scale_source = "none";
      meta.scale_report =
          "no LiDAR in the dataset: poses and depth stay in MonST3R units";
    }
    timer.Run("geometry", [&] {
      Monst3rLoadOptions load;
      load.init_confidence = false;
      const Monst3rFrame frame0 = folder.LoadFrame(0, load);
      dynamic_mask0 = frame0.enlarged_dynamic_mask.empty()
                          ? frame0.dynamic_mask
                          : frame0.enlarged_dynamic_mask;
      Pointmap pm = BuildPointmap(frame0, scale);
      PointmapFilterOptions filter;
      filter.min_confidence = opt.min_confidence;
      filter.min_depth = metric ? opt.min_depth_m : 0.0;
      filter.max_depth =
          metric ? opt.max_depth_m : std::numeric_limits<double>::infinity();
      filter.selection =
          PixelSelection::kAll;  // dynamic objects are handled by the editor
      const cv::Mat valid = ComputeValidMask(pm, filter);
      const PointCloud in_world = ExtractPoints(pm, valid);
      GEODRIVE_CHECK_INPUT(!in_world.empty(), dir,
                           ": no frame-0 pixel passes the filters");
      // Express everything in camera 0's frame (MonST3R world = its first
      // camera, up to noise).
      Rigid3d world_from_cam0 = folder.trajectory().world_from_cam.front();
      world_from_cam0.translation *= scale;
      const Rigid3d cam0_from_world = world_from_cam0.Inverse();
      cloud = in_world;
      for (auto& p : cloud.positions)
        p = (cam0_from_world * p.cast<double>()).cast<float>();
      for (int i = 0; i < n; ++i) {
        Rigid3d w = folder.trajectory().world_from_cam[i];
        w.translation *= scale;
        cam0_from_cam[i] = cam0_from_world * w;
      }
      // MonST3R intrinsics (processed pixels) -> output size, with the same
      // resize mode.
      const PinholeCamera& k = folder.cameras().front();
      cam_out =
          ApplyResizeSpec(k, ComputeResizeSpec(k.width, k.height, opt.width,
                                               opt.height, resize_mode));
    });
    meta.scale = scale;
  } else {
    timer.Run("geometry", [&] {
      cloud = BuildLidarCloud(ctx, clip, images_full);
      const Rigid3d cam0_from_global = nusc.WorldFromSensor(sd0).Inverse();
      for (int i = 0; i < n; ++i) {
        cam0_from_cam[i] =
            cam0_from_global * nusc.WorldFromSensor(clip.sample_data[i]);
      }
      cam_out = ApplyResizeSpec(cam_full, out_spec);
    });
    meta.scale = 1.0;
    meta.scale_source = "ego";
    meta.scale_report = "metric from LiDAR and ego poses";
  }
  meta.pose_units = metric ? "metres" : "monst3r";
  meta.world_from_cam = cam0_from_cam;
  meta.intrinsics = cam_out;

  // 3. Boxes of the clip's vehicles: 3D in camera 0's frame (metric only), 2D
  // at output size from the dataset's own camera poses.
  BoxSequences boxes;
  timer.Run("boxes", [&] {
    boxes.image_width = opt.width;
    boxes.image_height = opt.height;
    boxes.num_frames = n;
    boxes.units = metric ? "metres" : "monst3r";
    const Rigid3d cam0_from_global = nusc.WorldFromSensor(sd0).Inverse();
    const PinholeCamera true_cam_out = ApplyResizeSpec(cam_full, out_spec);
    std::map<std::string, BoxSequence> by_instance;
    for (int i = 0; i < n; ++i) {
      const int32_t sd = clip.sample_data[i];
      const Rigid3d cam_from_global = nusc.WorldFromSensor(sd).Inverse();
      for (const NuscenesBox& b : nusc.GetBoxes(sd)) {
        if (b.category == kNoIndex ||
            !IsVehicle(nusc.categories()[b.category].name))
          continue;
        Box3d global{b.center, b.wlh, b.orientation};
        const auto box2d =
            ProjectBox3d(global, true_cam_out, cam_from_global, /*near=*/0.1);
        const NuscenesBox in_cam0 = b.Transformed(cam0_from_global);
        BoxFrame frame;
        frame.frame = i;
        if (box2d) frame.box_2d = box2d;
        if (metric)
          frame.box_3d =
              Box3d{in_cam0.center, in_cam0.wlh, in_cam0.orientation};
        if (!frame.box_2d && !frame.box_3d) continue;
        const std::string id = nusc.instances()[b.instance].token.ToString();
        BoxSequence& seq = by_instance[id];
        seq.id = id;
        seq.category = nusc.categories()[b.category].name;
        seq.frames.push_back(frame);
      }
    }
    for (auto& [id, seq] : by_instance)
      boxes.instances.push_back(std::move(seq));
    boxes.Check("clip boxes");
  });

  // 4. Render along the trajectory (with dynamic editing).
  const RenderPreset preset = ParseRenderPreset(opt.preset);
  std::vector<Rigid3d> cam_from_cam0(n);
  for (int i = 0; i < n; ++i) cam_from_cam0[i] = cam0_from_cam[i].Inverse();
  std::vector<cv::Mat> cond;
  std::vector<double> coverage(n, 0.0);
  std::vector<cv::Mat> instance_masks(n);
  timer.Run("render", [&] {
    RenderOptions ro = PresetRenderOptions(preset);
    PinholeCamera cam_render = cam_out;
    if (preset == RenderPreset::kPaper) {
      ro.width = opt.width;
      ro.height = opt.height;
      ro.radius_px = opt.splat_radius_px;
      if (!metric) {  // depth range in metres is meaningless in MonST3R units
        ro.near = 1e-6;
        ro.far = std::numeric_limits<double>::infinity();
      }
    } else {
      cam_render = ResizeCamera(cam_out, ro.width, ro.height);
    }
    ro.num_threads = opt.threads > 1 ? 1 : 0;
    RenderResult result;
    if (opt.edit_mode == "none" || boxes.instances.empty()) {
      result = RenderFrames(cloud, {cam_render}, cam_from_cam0, ro);
    } else {
      DynamicEditOptions eo;
      eo.mode = ParseEditMode(opt.edit_mode);
      eo.frame0_image = gt.front();
      if (!dynamic_mask0.empty()) eo.dynamic_mask = dynamic_mask0;
      eo.num_threads = ro.num_threads;
      if (!metric) eo.box_margin = 0.0;
      BoxSequences render_boxes = boxes;
      render_boxes.image_width = opt.width;
      render_boxes.image_height = opt.height;
      DynamicEditResult edited = RenderWithDynamicEdits(
          cloud, {cam_render}, cam_from_cam0, render_boxes, {}, eo, ro);
      result.frames = std::move(edited.frames);
      for (int i = 0; i < n; ++i) instance_masks[i] = result.frames[i].instance;
    }
    for (int i = 0; i < n; ++i) coverage[i] = result.frames[i].coverage();
    cond = FinalFrames(
        result, preset,
        preset == RenderPreset::kGeodriveCompat ? gt.front() : cv::Mat());
    for (auto& f : cond) {
      if (f.cols != opt.width || f.rows != opt.height) {
        cv::Mat r;
        cv::resize(f, r, cv::Size(opt.width, opt.height), 0, 0, cv::INTER_AREA);
        f = r;
      }
    }
    // Static-region agreement with GT: rendered pixels outside every vehicle
    // (box grown 4 px).
    for (int i = 0; i < n; ++i) {
      cv::Mat mask;
      if (result.frames[i].mask.size() == cond[i].size()) {
        mask = result.frames[i].mask.clone();
      } else {
        cv::resize(result.frames[i].mask, mask, cond[i].size(), 0, 0,
                   cv::INTER_NEAREST);
      }
      for (const auto& seq : boxes.instances) {
        const BoxFrame* bf = seq.Find(i);
        if (!bf || !bf->box_2d) continue;
        const Box2d b = bf->box_2d->Clipped(opt.width, opt.height);
        if (b.Area() <= 0) continue;
        cv::rectangle(mask,
                      cv::Rect(cv::Point(static_cast<int>(b.xmin) - 4,
                                         static_cast<int>(b.ymin) - 4),
                               cv::Point(static_cast<int>(b.xmax) + 5,
                                         static_cast<int>(b.ymax) + 5)),
                      cv::Scalar(0), cv::FILLED);
      }
      meta.quality.psnr_static.push_back(MaskedPsnr(cond[i], gt[i], mask));
    }
  });
  meta.quality.coverage = coverage;

  // 5. Encode and write the pair folder.
  timer.Run("encode", [&] {
    H264Options vo;
    vo.fps = opt.fps;
    vo.preset = opt.video_preset;
    vo.crf = opt.video_crf;
    WriteH264Mp4(tmp_dir + "/gt.mp4", gt, vo);
    WriteH264Mp4(tmp_dir + "/cond.mp4", cond, vo);
    if (opt.lossless_frames) {
      WritePngSequence(tmp_dir + "/gt_frames", "frame_", gt);
      WritePngSequence(tmp_dir + "/cond_frames", "frame_", cond);
      meta.files["gt_frames"] = "gt_frames";
      meta.files["cond_frames"] = "cond_frames";
    }
    WriteImageRgb(tmp_dir + "/first_frame.png", gt.front());
    ContactSheetOptions co;
    co.columns = 9;
    co.thumb_width = 160;
    std::vector<cv::Mat> gt_sel, cond_sel;
    for (int i = 0; i < n; i += 3)
      gt_sel.push_back(gt[i]), cond_sel.push_back(cond[i]);
    WriteImageRgb(tmp_dir + "/preview.png",
                  MakeContactSheet(cond_sel, gt_sel, co));
    WriteBoxesJson(tmp_dir + "/boxes.json", boxes);
    meta.files["gt"] = "gt.mp4";
    meta.files["cond"] = "cond.mp4";
    meta.files["first_frame"] = "first_frame.png";
    meta.files["preview"] = "preview.png";
    meta.files["boxes"] = "boxes.json";
    meta.files["meta"] = "meta.json";
    WriteFileAtomic(tmp_dir + "/meta.json", PairMetaToJson(meta));
  });
  return meta;
}

std::string ShardSuffix(int index, int count) {
  return count == 1 ? ""
                    : ".shard-" + std::to_string(index) + "-of-" +
                          std::to_string(count);
}

double Mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? 0.0 : s / v.size();
}

ManifestEntry EntryFromMeta(const PairMeta& meta) {
  return {meta.clip_id,
          "pairs/" + meta.clip_id,
          meta.scene_name,
          static_cast<int>(meta.frames.size()),
          meta.geometry_source,
          meta.pose_units,
          std::min(1.0, std::max(0.0, Mean(meta.quality.coverage))),
          meta.options_hash};
}

// Rebuilds manifest.jsonl (from pair folders) and failures.jsonl (last failure
// per clip without a pair, from all failure logs) sorted by clip id. Returns
// the number of pairs.
int RewriteLogs(const std::string& out) {
  std::vector<std::string> ids;
  if (fs::is_directory(out + "/pairs")) {
    for (const auto& e : fs::directory_iterator(out + "/pairs")) {
      const std::string name = e.path().filename().string();
      if (e.is_directory() && name.rfind(".tmp-", 0) != 0 &&
          fs::exists(e.path() / "meta.json")) {
        ids.push_back(name);
      }
    }
  }
  std::sort(ids.begin(), ids.end());
  std::string manifest;
  for (const auto& id : ids) {
    manifest +=
        ManifestEntryToJson(EntryFromMeta(ReadPairMeta(out + "/pairs/" + id))) +
        "\n";
  }
  WriteFileAtomic(out + "/manifest.jsonl", manifest);
  std::map<std::string, FailureEntry> failures;
  std::vector<std::string> logs;
  for (const auto& e : fs::directory_iterator(out)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("failures", 0) == 0 && name.size() > 6 &&
        name.substr(name.size() - 6) == ".jsonl") {
      logs.push_back(e.path().string());
    }
  }
  std::sort(logs.begin(), logs.end());
  for (const auto& log : logs) {
    for (const auto& f : ReadFailures(log)) failures[f.clip_id] = f;
  }
  const std::set<std::string> built(ids.begin(), ids.end());
  std::string text;
  for (const auto& [id, f] : failures) {
    if (!built.count(id)) text += FailureEntryToJson(f) + "\n";
  }
  WriteFileAtomic(out + "/failures.jsonl", text);
  return static_cast<int>(ids.size());
}

}  // namespace

BuildDatasetSummary BuildDataset(BuildDatasetOptions opt) {
  opt.Check();
  const auto t_start = std::chrono::steady_clock::now();
  BuildDatasetSummary summary;
  fs::create_directories(opt.out + "/pairs");

  NuscenesOptions no;
  no.dataroot = opt.dataroot;
  no.version = opt.version;
  const Nuscenes nusc(no);
  ClipOptions co;
  co.num_frames = opt.clip_frames;
  co.stride = opt.clip_stride;
  std::vector<Clip> clips = SelectClips(nusc, co);
  if (!opt.clips.empty()) {
    const std::set<std::string> wanted(opt.clips.begin(), opt.clips.end());
    std::set<std::string> found;
    std::vector<Clip> kept;
    for (auto& c : clips) {
      if (wanted.count(c.id)) found.insert(c.id), kept.push_back(std::move(c));
    }
    for (const auto& id : wanted) {
      GEODRIVE_CHECK_INPUT(
          found.count(id), "build-dataset: clip '", id,
          "' is not a clip of this dataset (see `geodrive nuscenes-info`)");
    }
    clips = std::move(kept);
  }
  ClipContext ctx;
  ctx.nusc = &nusc;
  ctx.options = &opt;
  ctx.source = ParseGeometrySource(opt.geometry);
  ctx.has_lidar = nusc.FindSensor("LIDAR_TOP") != kNoIndex;
  if (ctx.source == GeometrySource::kMonst3r) {
    std::vector<Clip> kept;
    for (auto& c : clips) {
      if (fs::is_directory(opt.monst3r_root + "/" + c.id)) {
        kept.push_back(std::move(c));
      } else if (opt.clips.empty()) {
        ++summary.skipped_no_monst3r;
      } else {
        kept.push_back(std::move(
            c));  // asked for explicitly: a missing folder is a failure
      }
    }
    clips = std::move(kept);
  }
  std::vector<Clip> mine;
  for (size_t i = 0; i < clips.size(); ++i) {
    if (static_cast<int>(i % opt.shard_count) == opt.shard_index)
      mine.push_back(clips[i]);
  }
  if (opt.max_clips > 0 && static_cast<int>(mine.size()) > opt.max_clips)
    mine.resize(opt.max_clips);
  summary.clips_total = static_cast<int>(mine.size());

  // Stale temporary folders of a killed run are removed (only this shard's own
  // clips: other shards or MPI ranks may be writing theirs right now); finished
  // pairs are skipped.
  for (const auto& c : mine) {
    std::error_code ec;
    fs::remove_all(opt.out + "/pairs/.tmp-" + c.id, ec);
  }
  std::vector<const Clip*> pending;
  for (const auto& c : mine) {
    if (fs::exists(opt.out + "/pairs/" + c.id + "/meta.json")) {
      ++summary.skipped_existing;
    } else {
      pending.push_back(&c);
    }
  }
  const std::string suffix = ShardSuffix(opt.shard_index, opt.shard_count);
  JsonlAppender manifest(opt.out + "/manifest" + suffix + ".jsonl");
  JsonlAppender failures(opt.out + "/failures" + suffix + ".jsonl");
  ProgressReporter progress("build-dataset", pending.size(), 10.0, opt.quiet);
  std::mutex mutex;
  std::atomic<size_t> next{0};
  auto worker = [&] {
    std::map<std::string, double> local_seconds;
    while (!StopRequested()) {
      const size_t k = next.fetch_add(1);
      if (k >= pending.size()) break;
      const Clip& clip = *pending[k];
      const std::string tmp = opt.out + "/pairs/.tmp-" + clip.id;
      const std::string final_dir = opt.out + "/pairs/" + clip.id;
      std::string stage = "setup", error;
      try {
        fs::remove_all(tmp);
        fs::create_directories(tmp);
        const PairMeta meta = BuildPair(ctx, clip, tmp, &local_seconds);
        stage = "commit";
        CommitDirectory(tmp, final_dir);
        manifest.Append(ManifestEntryToJson(EntryFromMeta(meta)));
      } catch (const StageError& e) {
        stage = e.stage;
        error = e.what();
      } catch (const std::exception& e) {
        error = e.what();
      }
      std::lock_guard<std::mutex> lock(mutex);
      if (error.empty()) {
        ++summary.built;
      } else {
        std::error_code ec;
        fs::remove_all(tmp, ec);
        ++summary.failed;
        ++summary.failures_by_stage[stage];
        failures.Append(FailureEntryToJson({clip.id, stage, error}));
        if (!opt.quiet)
          std::cerr << "build-dataset: " << clip.id << " failed at " << stage
                    << ": " << error << "\n";
      }
      progress.Advance(1, clip.id);
    }
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& [s, t] : local_seconds) summary.seconds_by_stage[s] += t;
  };
  std::vector<std::thread> pool;
  for (int t = 0;
       t < std::min<int>(opt.threads, std::max<size_t>(1, pending.size())); ++t) {
    pool.emplace_back(worker);
  }
  for (auto& th : pool) th.join();
  progress.Finish();
  summary.interrupted = StopRequested() && next.load() < pending.size();
  summary.seconds_total =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start)
          .count();
  if (opt.shard_count == 1) {
    RewriteLogs(opt.out);
    WriteBuildReport(opt.out, &summary);
  }
  return summary;
}

int MergeBuildOutputs(const std::string& out) {
  GEODRIVE_CHECK_INPUT(fs::is_directory(out + "/pairs"), out,
                       ": not a build-dataset output (no pairs/)");
  const int n = RewriteLogs(out);
  WriteBuildReport(out, nullptr);
  return n;
}

namespace {

std::string Html(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '<':
        o += "&lt;";
        break;
      case '>':
        o += "&gt;";
        break;
      case '&':
        o += "&amp;";
        break;
      case '"':
        o += "&quot;";
        break;
      default:
        o += c;
    }
  }
  return o;
}

// An inline SVG histogram of `values` over [lo, hi] with `bins` bins.
std::string SvgHistogram(const std::vector<double>& values,
                         double lo,
                         double hi,
                         int bins,
                         const std::string& label) {
  std::vector<int> counts(bins, 0);
  for (double v : values) {
    if (!std::isfinite(v)) continue;
    int b = static_cast<int>((v - lo) / (hi - lo) * bins);
    counts[std::clamp(b, 0, bins - 1)]++;
  }
  const int maxc = std::max(1, *std::max_element(counts.begin(), counts.end()));
  std::ostringstream os;
  const int w = 360, h = 140;
  os << "<svg width='" << w << "' height='" << h + 30
     << "' style='background:#fafafa'>";
  for (int b = 0; b < bins; ++b) {
    const double bh = static_cast<double>(counts[b]) / maxc * h;
    os << "<rect x='" << b * w / bins + 1 << "' y='" << h - bh << "' width='"
       << w / bins - 2 << "' height='" << bh << "' fill='#4a7fb5'><title>"
       << counts[b] << "</title></rect>";
  }
  os << "<text x='0' y='" << h + 14 << "' font-size='11'>" << lo
     << "</text><text x='" << w - 30 << "' y='" << h + 14 << "' font-size='11'>"
     << hi << "</text><text x='120' y='" << h + 27 << "' font-size='12'>"
     << Html(label) << "</text></svg>";
  return os.str();
}

}  // namespace

void WriteBuildReport(const std::string& out,
                      const BuildDatasetSummary* summary) {
  std::vector<ManifestEntry> entries;
  if (fs::exists(out + "/manifest.jsonl"))
    entries = ReadManifest(out + "/manifest.jsonl");
  std::vector<FailureEntry> fails;
  if (fs::exists(out + "/failures.jsonl"))
    fails = ReadFailures(out + "/failures.jsonl");
  std::vector<double> coverage, scales, psnr;
  for (const auto& e : entries) {
    coverage.push_back(e.mean_coverage);
    try {
      const PairMeta m = ReadPairMeta(out + "/" + e.pair_dir);
      if (m.scale_source == "lidar") scales.push_back(m.scale);
      for (double p : m.quality.psnr_static)
        if (std::isfinite(p)) psnr.push_back(p);
    } catch (const std::exception&) {
    }
  }
  std::ostringstream os;
  os << "<!DOCTYPE html><html><head><meta charset='utf-8'><title>geodrive "
        "build-dataset report"
        "</"
        "title><style>body{font-family:sans-serif;margin:24px}td,th{padding:"
        "2px 8px;text-align:"
        "left}img{width:100%;max-width:900px;border:1px solid "
        "#ccc}.grid{display:grid;grid-"
        "template-columns:repeat(auto-fill,minmax(420px,1fr));gap:12px}</"
        "style></head><body>";
  os << "<h1>Dataset build report</h1><p>Output: <code>"
     << Html(fs::absolute(out).string()) << "</code> &middot; geodrive "
     << GEODRIVE_VERSION << "</p>";
  os << "<h2>Counts</h2><table><tr><th>pairs</th><td>" << entries.size()
     << "</td></tr><tr><th>failed clips</th><td>" << fails.size()
     << "</td></tr>";
  if (summary) {
    os << "<tr><th>built in the last run</th><td>" << summary->built
       << "</td></tr><tr><th>skipped (already built)</th><td>"
       << summary->skipped_existing
       << "</td></tr><tr><th>skipped (no MonST3R folder)</th><td>"
       << summary->skipped_no_monst3r
       << "</td></tr><tr><th>run time (s)</th><td>" << summary->seconds_total
       << "</td></tr>";
  }
  os << "</table>";
  if (summary && !summary->seconds_by_stage.empty()) {
    os << "<h2>Time per stage (s, summed over clips)</h2><table>";
    for (const auto& [s, t] : summary->seconds_by_stage) {
      os << "<tr><th>" << Html(s) << "</th><td>" << t << "</td></tr>";
    }
    os << "</table>";
  }
  os << "<h2>Quality</h2>"
     << SvgHistogram(coverage, 0, 1, 20, "mean coverage per pair") << " "
     << SvgHistogram(psnr, 5, 45, 20, "static-region PSNR per frame (dB)");
  if (!scales.empty()) {
    const double lo = *std::min_element(scales.begin(), scales.end());
    const double hi = *std::max_element(scales.begin(), scales.end());
    os << " "
       << SvgHistogram(scales, lo * 0.9, hi * 1.1 + 1e-9, 20,
                       "LiDAR scale (metres per MonST3R unit)");
  }
  if (!fails.empty()) {
    os << "<h2>Failures</h2><table><tr><th>clip</th><th>stage</th><th>error</"
          "th></tr>";
    for (const auto& f : fails) {
      os << "<tr><td>" << Html(f.clip_id) << "</td><td>" << Html(f.stage)
         << "</td><td>" << Html(f.error) << "</td></tr>";
    }
    os << "</table>";
  }
  os << "<h2>Previews (GT above condition)</h2><div class='grid'>";
  size_t shown = 0;
  for (const auto& e : entries) {
    if (++shown > 60) break;
    os << "<figure><img src='" << Html(e.pair_dir)
       << "/preview.png' loading='lazy'><figcaption>" << Html(e.clip_id)
       << " &middot; coverage " << e.mean_coverage << "</figcaption></figure>";
  }
  os << "</div></body></html>\n";
  WriteFileAtomic(out + "/report.html", os.str());
}

}  // namespace geodrive

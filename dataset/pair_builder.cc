// The steps of one pair (dataset/internal/pair_builder.h): clip -> frames ->
// scene -> boxes -> condition render -> pair folder.

#include "dataset/internal/pair_builder.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "dataset/frame_decode.h"
#include "dataset/internal/pair_png.h"
#include "geodrive_version.h"
#include "geometry/image_io.h"
#include "geometry/util/files.h"
#include "geometry/util/hash.h"
#include "geometry/util/simd.h"
#include "geometry/util/status.h"
#include "render/dynamic_edit.h"
#include "render/presets.h"
#include "render/renderer.h"
#include "render/video/h264.h"
#include "render/video/video.h"

namespace geodrive {
namespace internal {
namespace {

bool IsVehicle(const std::string& category) {
  return category.rfind("vehicle.", 0) == 0;
}

ImageResizeSpec OutputSpec(const PinholeCamera& cam,
                           const BuildDatasetOptions& opt) {
  return ComputeResizeSpec(cam.width, cam.height, opt.width, opt.height,
                           opt.resize_mode);
}

// Static-region agreement with GT: rendered pixels outside every vehicle (box
// grown 4 px).
std::optional<double> StaticPsnr(const cv::Mat& cond,
                                 const cv::Mat& gt,
                                 const cv::Mat& render_mask,
                                 const BoxSequences& boxes,
                                 int frame,
                                 const BuildDatasetOptions& opt) {
  cv::Mat mask;
  if (render_mask.size() == cond.size()) {
    mask = render_mask.clone();
  } else {
    cv::resize(render_mask, mask, cond.size(), 0, 0, cv::INTER_NEAREST);
  }
  for (const auto& seq : boxes.instances) {
    const BoxFrame* bf = seq.Find(frame);
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
  return MaskedPsnr(cond, gt, mask);
}

}  // namespace

// An AVX2 clone (geometry/util/simd.h): integer sums, the same value in both.
GEODRIVE_AVX2_CLONES std::optional<double> MaskedPsnr(const cv::Mat& a,
                                                      const cv::Mat& b,
                                                      const cv::Mat& mask) {
  int64_t se = 0;
  int64_t n = 0;
  // The mask spread to the row's bytes (0 or 1 per byte), so that the sum
  // runs over contiguous bytes. Under callgrind (the frames of
  // BuildDataset.MaskedPsnrIsTheFormula): 26 instructions a pixel with the
  // mask inside a per-pixel loop (9 M a 720x480 frame, 5 % of
  // build-dataset's), 24 with these loops in SSE2 (the spread's stride-3
  // stores stay scalar), 5 in the AVX2 clone.
  std::vector<uint8_t> spread(3 * static_cast<size_t>(a.cols));
  for (int y = 0; y < a.rows; ++y) {
    const uint8_t* pa = a.ptr<uint8_t>(y);
    const uint8_t* pb = b.ptr<uint8_t>(y);
    const uint8_t* pm = mask.ptr<uint8_t>(y);
    int row_n = 0;
    for (int x = 0; x < a.cols; ++x) {
      const uint8_t m = pm[x] != 0;
      spread[3 * x] = spread[3 * x + 1] = spread[3 * x + 2] = m;
      row_n += m;
    }
    const int bytes = 3 * a.cols;
    // Frames are at most 16384 wide (BuildDatasetOptions::Check): a row sums
    // to under 3 * 16384 * 255^2 < 2^32.
    uint32_t row_se = 0;
    for (int i = 0; i < bytes; ++i) {
      const int d = (pa[i] - pb[i]) * spread[i];
      row_se += static_cast<uint32_t>(d * d);
    }
    se += row_se;
    n += 3 * row_n;
  }
  if (n == 0) return std::nullopt;
  const double mse = static_cast<double>(se) / n;
  return mse <= 0 ? 100.0 : 10.0 * std::log10(255.0 * 255.0 / mse);
}

ClipFrames ReadClipFrames(const DriveClip& clip,
                          const BuildDatasetOptions& opt,
                          int full_size_images) {
  GEODRIVE_CHECK_INPUT(!clip.frames.empty(), clip.id, ": clip has no frames");
  const PinholeCamera& cam = clip.frames.front().camera;
  const ImageResizeSpec spec = OutputSpec(cam, opt);
  const int n = clip.num_frames();
  ClipFrames out;
  out.first_frame_path = clip.frames.front().image_path;
  const int full = full_size_images < 0 ? n : std::min(n, full_size_images);
  out.gt.resize(n);
  out.full.resize(full);
  const JpegScale scale = FrameDecodeScale(cam.width, cam.height, spec);
  const bool full_scale = scale.num == scale.denom;
  for (int i = 0; i < n; ++i) {
    const std::string& path = clip.frames[i].image_path;
    if (i >= full) {  // DCT-scaled decode straight to the output size
      out.gt[i] = ReadFrameAtOutputSize(path, cam.width, cam.height, spec);
      continue;
    }
    out.full[i] = ReadImageRgb(path);
    GEODRIVE_CHECK_INPUT(
        out.full[i].cols == cam.width && out.full[i].rows == cam.height, path,
        ": image is ", out.full[i].cols, "x", out.full[i].rows,
        " but the dataset says ", cam.width, "x", cam.height);
    // The same output as ReadFrameAtOutputSize (the ground truth must not
    // depend on the scene source): from this decode where that path decodes
    // at full size too, else the scaled decode again (cheaper than resizing
    // the full image).
    out.gt[i] = full_scale
                    ? FullFrameToOutput(out.full[i], spec)
                    : ReadFrameAtOutputSize(path, cam.width, cam.height, spec);
  }
  return out;
}

ConditionScene BuildClipScene(const DriveClip& clip,
                              const std::vector<cv::Mat>& images,
                              const std::string& path,
                              const BuildDatasetOptions& opt) {
  const std::string name = opt.SceneSourceName();
  SceneInputs in;
  in.clip = &clip;
  if (!images.empty()) in.clip_images = &images;
  if (CreateSceneSource(name)->Traits().needs_path) {
    GEODRIVE_CHECK_INPUT(!path.empty(), clip.id,
                         ": no input folder for scene "
                         "source ",
                         name, " under ", opt.monst3r_root);
    in.path = path;
  }
  SceneSourceOptions so;
  so.filter = PointmapFilter::kPaper;
  so.min_confidence = opt.min_confidence;
  so.min_depth_m = opt.min_depth_m;
  so.max_depth_m = opt.max_depth_m;
  so.lidar_window_before_s = opt.lidar_window_before_s;
  so.lidar_window_after_s = opt.lidar_window_after_s;
  so.dense_window = opt.lidar_dense_window;
  so.dense_objects = opt.lidar_dense_objects;
  so.dense_width = opt.lidar_dense_width;
  so.refine_poses = opt.refine_poses;
  ConditionScene scene = BuildConditionScene(name, in, so);
  GEODRIVE_CHECK_INPUT(scene.trajectory.size() == clip.frames.size(), clip.id,
                       ": scene source ", name, " gave ",
                       scene.trajectory.size(), " poses for ",
                       clip.frames.size(), " frames");
  return scene;
}

BoxSequences ClipVehicleBoxes(const DriveClip& clip,
                              bool metric,
                              const BuildDatasetOptions& opt) {
  return ClipVehicleBoxes(clip, metric, opt,
                          clip.frames.front().world_from_cam.Inverse());
}

BoxSequences ClipVehicleBoxes(const DriveClip& clip,
                              bool metric,
                              const BuildDatasetOptions& opt,
                              const Rigid3d& scene_from_world) {
  const int n = clip.num_frames();
  BoxSequences boxes;
  boxes.image_width = opt.width;
  boxes.image_height = opt.height;
  boxes.num_frames = n;
  boxes.units = metric ? "metres" : "monst3r";
  const PinholeCamera& cam_full = clip.frames.front().camera;
  const PinholeCamera true_cam_out =
      ApplyResizeSpec(cam_full, OutputSpec(cam_full, opt));
  std::map<std::string, BoxSequence> by_instance;
  for (int i = 0; i < n; ++i) {
    const Rigid3d cam_from_world = clip.frames[i].world_from_cam.Inverse();
    for (const ClipBox& b : clip.frames[i].boxes) {
      if (b.category.empty() || !IsVehicle(b.category)) continue;
      const auto box2d =
          ProjectBox3d(b.box, true_cam_out, cam_from_world, /*near=*/0.1);
      BoxFrame frame;
      frame.frame = i;
      if (box2d) frame.box_2d = box2d;
      if (metric) frame.box_3d = b.box.Transformed(scene_from_world);
      if (!frame.box_2d && !frame.box_3d) continue;
      BoxSequence& seq = by_instance[b.instance_id];
      seq.id = b.instance_id;
      seq.category = b.category;
      seq.frames.push_back(frame);
    }
  }
  for (auto& [id, seq] : by_instance) boxes.instances.push_back(std::move(seq));
  boxes.Check("clip boxes");
  return boxes;
}

ConditionRender RenderCondition(const ConditionScene& scene,
                                const BoxSequences& boxes,
                                const std::vector<cv::Mat>& gt,
                                const BuildDatasetOptions& opt,
                                const RenderKeep& keep) {
  ViewToRender view;
  view.cloud = &scene.cloud;
  view.camera = scene.camera;
  view.scene_from_cam = scene.trajectory.world_from_cam;
  view.metric = scene.metric();
  view.dynamic_mask = scene.dynamic_mask;
  return RenderConditionView(view, boxes, gt, opt, keep);
}

ConditionRender RenderConditionView(const ViewToRender& view,
                                    const BoxSequences& boxes,
                                    const std::vector<cv::Mat>& gt,
                                    const BuildDatasetOptions& opt,
                                    const RenderKeep& keep) {
  const PointCloud& cloud = *view.cloud;
  const int n = static_cast<int>(view.scene_from_cam.size());
  const RenderPreset preset = opt.preset;
  std::vector<Rigid3d> cam_from_cam0(n);
  for (int i = 0; i < n; ++i)
    cam_from_cam0[i] = view.scene_from_cam[i].Inverse();
  RenderOptions ro = PresetRenderOptions(preset);
  PinholeCamera cam_render = ApplyResizeSpec(
      view.camera, ComputeResizeSpec(view.camera.width, view.camera.height,
                                     opt.width, opt.height, opt.resize_mode));
  if (preset != RenderPreset::kGeodriveCompat) {  // the z-buffer presets
    ro.width = opt.width;
    ro.height = opt.height;
    // The footprint preset sizes every point from its footprint.
    if (preset == RenderPreset::kPaper) ro.radius_px = opt.splat_radius_px;
    if (!view.metric) {  // a depth range in metres is meaningless then
      ro.near = 1e-6;
      ro.far = std::numeric_limits<double>::infinity();
    }
  } else {
    cam_render = ResizeCamera(cam_render, ro.width, ro.height);
  }
  ro.num_threads = opt.threads > 1 ? 1 : 0;
  RenderResult result;
  if (opt.edit_mode == PairEditMode::kNone || boxes.instances.empty()) {
    result = RenderFrames(cloud, {cam_render}, cam_from_cam0, ro);
  } else {
    DynamicEditOptions eo;
    eo.mode =
        opt.edit_mode == PairEditMode::k2d ? EditMode::k2d : EditMode::k3d;
    eo.frame0_image = gt.front();
    if (!view.dynamic_mask.empty()) eo.dynamic_mask = view.dynamic_mask;
    eo.num_threads = ro.num_threads;
    if (!view.metric) eo.box_margin = 0.0;
    // Removals of instances this clip has (every camera of a rig gets the
    // same list: the instance goes from all views at once).
    std::vector<ObjectEdit> edits;
    for (const std::string& id : opt.remove_instances) {
      for (const BoxSequence& seq : boxes.instances) {
        if (seq.id != id) continue;
        ObjectEdit e;
        e.kind = ObjectEditKind::kRemove;
        e.instance = id;
        edits.push_back(e);
      }
    }
    DynamicEditResult edited = RenderWithDynamicEdits(
        cloud, {cam_render}, cam_from_cam0, boxes, edits, eo, ro);
    result.frames = std::move(edited.frames);
  }
  ConditionRender out;
  out.depth0 = result.frames.front().depth;
  for (int i = 0; i < n; ++i)
    out.coverage.push_back(result.frames[i].coverage());
  out.frames = FinalFrames(
      result, preset,
      preset == RenderPreset::kGeodriveCompat ? gt.front() : cv::Mat());
  // Shared, not copied: a frame resized below is replaced, never written.
  if (keep.native_frames) out.native_frames = out.frames;
  if (keep.depth) {
    for (int i = 0; i < n; ++i) {
      const RenderedFrame& r = result.frames[i];
      cv::Mat depth = r.depth, drawn = r.mask != kMaskInvalid;
      if (depth.cols != opt.width || depth.rows != opt.height) {
        const cv::Size size(opt.width, opt.height);
        cv::resize(r.depth, depth, size, 0, 0, cv::INTER_NEAREST);
        cv::resize(drawn, drawn, size, 0, 0, cv::INTER_NEAREST);
      }
      out.depth.push_back(depth);
      out.drawn.push_back(drawn);
    }
  }
  for (auto& f : out.frames) {
    if (f.cols != opt.width || f.rows != opt.height) {
      cv::Mat r;
      cv::resize(f, r, cv::Size(opt.width, opt.height), 0, 0, cv::INTER_AREA);
      f = r;
    }
  }
  for (int i = 0; i < n; ++i) {
    out.psnr_static.push_back(
        StaticPsnr(out.frames[i], gt[i], result.frames[i].mask, boxes, i, opt));
  }
  return out;
}

PairMeta MakePairMeta(const DriveClip& clip,
                      const ConditionScene& scene,
                      const BuildDatasetOptions& opt) {
  PairMeta meta;
  meta.clip_id = clip.id;
  meta.scene_name = clip.scene_name;
  meta.scene_token = clip.scene_id;
  for (const DriveFrame& f : clip.frames)
    meta.frames.push_back({f.frame_id, f.timestamp_us, f.relative_path});
  meta.frame_source = ToString(clip.frame_source);
  meta.frame_interval_s = clip.FrameIntervalSeconds();
  meta.fps = opt.fps;
  meta.resize_mode = ToString(opt.resize_mode);
  meta.geometry_source = opt.SceneSourceName();
  meta.preset = ToString(opt.preset);
  meta.edit_mode = ToString(opt.edit_mode);
  // The options with the inputs' identity; the hash covers the options only.
  const std::string content_options = opt.ContentOptionsJson();
  nlohmann::json options = nlohmann::json::parse(content_options);
  options["inputs"] = nlohmann::json::parse(opt.InputsJson());
  meta.options_json = options.dump();
  meta.options_hash = StableHash64(content_options);
  meta.tool_version = GEODRIVE_VERSION;
  meta.scale = scene.scale.scale;
  meta.scale_source = scene.scale.source;
  meta.scale_report = scene.scale.report;
  if (scene.scale.inlier_fraction)
    meta.quality.scale_inlier_fraction = *scene.scale.inlier_fraction;
  meta.quality.reprojection_rms_px_before = scene.reprojection_rms_px_before;
  meta.quality.reprojection_rms_px_after = scene.reprojection_rms_px_after;
  if (scene.completion) {
    meta.quality.supported_fraction = scene.completion->supported_fraction;
    meta.quality.coverage_of_supported =
        scene.completion->coverage_of_supported;
  }
  if (const auto& a = scene.completion_accuracy) {
    PairQuality::HoldOut h;
    h.held_out = a->held_out;
    h.covered = a->covered;
    h.mae_m = a->mae_m;
    h.rmse_m = a->rmse_m;
    h.within_5_percent = a->within_5_percent;
    h.within_10_percent = a->within_10_percent;
    meta.quality.completion_holdout = h;
  }
  meta.pose_units = scene.metric() ? "metres" : "monst3r";
  meta.world_from_cam = scene.trajectory.world_from_cam;
  meta.intrinsics = scene.CameraAt(opt.width, opt.height, opt.resize_mode);
  return meta;
}

namespace {

// Inverse depth in [1/80, 1/2] 1/m -> turbo colours; black where depth is 0.
cv::Mat ColorizeDepth(const cv::Mat& depth) {
  cv::Mat level(depth.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < depth.rows; ++y) {
    const float* d = depth.ptr<float>(y);
    uint8_t* l = level.ptr<uint8_t>(y);
    for (int x = 0; x < depth.cols; ++x) {
      if (!(d[x] > 0)) continue;
      const double t = (1.0 / d[x] - 1.0 / 80) / (1.0 / 2 - 1.0 / 80);
      l[x] = static_cast<uint8_t>(std::lround(255 * std::clamp(t, 0.0, 1.0)));
    }
  }
  cv::Mat bgr, rgb;
  cv::applyColorMap(level, bgr, cv::COLORMAP_TURBO);
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  rgb.setTo(cv::Scalar::all(0), depth <= 0);
  return rgb;
}

cv::Mat Labelled(const cv::Mat& rgb, const std::string& label) {
  cv::Mat tile;
  const int w = 400;
  const int h = std::max(1, rgb.rows * w / std::max(1, rgb.cols));
  cv::resize(rgb, tile, cv::Size(w, h), 0, 0, cv::INTER_AREA);
  cv::putText(tile, label, cv::Point(6, 18), cv::FONT_HERSHEY_SIMPLEX, 0.5,
              cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  return tile;
}

}  // namespace

cv::Mat CompletionPreview(const ConditionScene& scene) {
  if (scene.completion_sparse.empty() || scene.completion_dense.empty() ||
      scene.frame0_rgb.empty())
    return cv::Mat();
  // Returns drawn 3x3 (the nearest wins) so that they survive the resize.
  cv::Mat sparse = scene.completion_sparse.clone();
  sparse.setTo(std::numeric_limits<float>::infinity(), sparse <= 0);
  cv::erode(sparse, sparse, cv::Mat::ones(3, 3, CV_8U));
  sparse.setTo(0, sparse == std::numeric_limits<float>::infinity());
  std::vector<cv::Mat> tiles = {
      Labelled(scene.frame0_rgb, "frame 0"),
      Labelled(ColorizeDepth(sparse), "LiDAR returns"),
      Labelled(ColorizeDepth(scene.completion_dense), "completed depth")};
  cv::Mat row;
  cv::hconcat(tiles, row);
  return row;
}

void WritePairFolder(const std::string& dir,
                     const ClipFrames& frames,
                     const ConditionRender& cond,
                     const BoxSequences& boxes,
                     const BuildDatasetOptions& opt,
                     PairMeta* meta,
                     const std::vector<std::unique_ptr<ClipExport>>& exports) {
  const std::vector<cv::Mat>& gt = frames.gt;
  meta->quality.coverage = cond.coverage;
  meta->quality.psnr_static = cond.psnr_static;
  H264Options vo;
  vo.fps = opt.fps;
  vo.preset = opt.video_preset;
  vo.crf = opt.video_crf;
  WriteH264Mp4(dir + "/gt.mp4", gt, vo);
  WriteH264Mp4(dir + "/cond.mp4", cond.frames, vo);
  if (opt.lossless_frames) {
    WritePngSequence(dir + "/gt_frames", "frame_", gt);
    WritePngSequence(dir + "/cond_frames", "frame_", cond.frames);
    meta->files["gt_frames"] = "gt_frames";
    meta->files["cond_frames"] = "cond_frames";
  }
  WritePairPng(dir + "/first_frame.png", gt.front());
  ContactSheetOptions co;
  co.columns = 9;
  co.thumb_width = 160;
  std::vector<cv::Mat> gt_sel, cond_sel;
  for (size_t i = 0; i < gt.size(); i += 3)
    gt_sel.push_back(gt[i]), cond_sel.push_back(cond.frames[i]);
  WritePairPng(dir + "/preview.png", MakeContactSheet(cond_sel, gt_sel, co));
  WriteBoxesJson(dir + "/boxes.json", boxes);
  if (!cond.completion_preview.empty()) {
    WritePairPng(dir + "/completion.png", cond.completion_preview);
    meta->files["completion_preview"] = "completion.png";
  }
  for (const auto& x : exports) {
    if (x->clip.images == &gt) x->clip.images_video = dir + "/gt.mp4";
    x->exporter->WriteClip(x->clip, dir, meta);
  }
  meta->files["gt"] = "gt.mp4";
  meta->files["cond"] = "cond.mp4";
  meta->files["first_frame"] = "first_frame.png";
  meta->files["preview"] = "preview.png";
  meta->files["boxes"] = "boxes.json";
  meta->files["meta"] = "meta.json";
  for (const auto& [role, name] : meta->files) {
    const std::string path = dir + "/" + name;
    std::error_code ec;
    if (name != "meta.json" && std::filesystem::is_regular_file(path, ec))
      meta->file_sizes[name] = std::filesystem::file_size(path, ec);
  }
  WriteFileAtomic(dir + "/meta.json", PairMetaToJson(*meta));
}

void CheckClipForExports(const ClipContext& ctx, const DriveClip& clip) {
  if (!ctx.exporters) return;
  for (const auto& e : *ctx.exporters) e->CheckClip(clip.id, clip.num_frames());
}

std::vector<ExportSweep> ClipSweeps(const DriveClip& clip,
                                    int step,
                                    const Rigid3d& scene_from_world,
                                    const std::string& format) {
  GEODRIVE_CHECK_INPUT(clip.lidar && !clip.lidar->Sweeps().empty(), clip.id,
                       ": ", format, " needs LiDAR sweeps; the dataset (",
                       clip.dataset, ") has none");
  const LidarProvider& lidar = *clip.lidar;
  std::vector<ExportSweep> sweeps;
  for (int i = 0; i < clip.num_frames(); i += std::max(1, step)) {
    const DriveFrame& f = clip.frames[i];
    const std::optional<size_t> index =
        f.keyframe_sweep ? f.keyframe_sweep : lidar.Nearest(f.timestamp_us);
    GEODRIVE_CHECK_INPUT(index.has_value(), clip.id,
                         ": no LiDAR sweep for "
                         "frame ",
                         i);
    const LidarSweepInfo& info = lidar.Sweeps()[*index];
    const PointCloud points = lidar.Load(*index);
    ExportSweep s;
    s.frame = i;
    s.timestamp_us = info.timestamp_us;
    s.world_from_sensor = scene_from_world * info.WorldFromSensor();
    s.xyzi.reserve(4 * points.size());
    for (size_t k = 0; k < points.size(); ++k) {
      const Eigen::Vector3f& p = points.positions[k];
      s.xyzi.insert(s.xyzi.end(),
                    {p.x(), p.y(), p.z(),
                     points.HasIntensity() ? points.intensity[k] : 0.0f});
    }
    sweeps.push_back(std::move(s));
  }
  return sweeps;
}

std::vector<std::vector<ExportObject>> ClipObjects(
    const DriveClip& clip, const Rigid3d& scene_from_world) {
  const int n = clip.num_frames();
  // Each track's (frame, centre in the world) in frame order, for speeds.
  std::map<std::string, std::vector<std::pair<int, Eigen::Vector3d>>> tracks;
  for (int i = 0; i < n; ++i) {
    for (const ClipBox& b : clip.frames[i].boxes)
      tracks[b.instance_id].emplace_back(i, b.box.center);
  }
  const auto speed = [&](const std::string& id, int frame) {
    const auto& t = tracks.at(id);
    if (t.size() < 2) return 0.0;
    size_t k = 0;
    while (k < t.size() && t[k].first != frame) ++k;
    const size_t a = k == 0 ? 0 : k - 1;
    const size_t b = std::min(k + 1, t.size() - 1);
    const double dt =
        1e-6 * static_cast<double>(clip.frames[t[b].first].timestamp_us -
                                   clip.frames[t[a].first].timestamp_us);
    return dt > 0 ? (t[b].second - t[a].second).norm() / dt : 0.0;
  };
  std::vector<std::vector<ExportObject>> objects(n);
  for (int i = 0; i < n; ++i) {
    for (const ClipBox& b : clip.frames[i].boxes) {
      ExportObject o;
      o.track_id = b.instance_id;
      o.category = b.category;
      o.world_from_box = scene_from_world * b.box.WorldFromBox();
      o.lwh = Eigen::Vector3d(b.box.size.y(), b.box.size.x(), b.box.size.z());
      o.speed_mps = speed(b.instance_id, i);
      objects[i].push_back(std::move(o));
    }
  }
  return objects;
}

namespace {

// True when `req` is served by the pair's own frames and render.
bool AtPairSize(const ExportRequirements& req, const BuildDatasetOptions& opt) {
  return (req.width == 0 && req.height == 0) ||
         (req.width == opt.width && req.height == opt.height &&
          opt.resize_mode == ResizeMode::kCenterCrop);
}

}  // namespace

void SetExportClipSource(const ClipContext& ctx,
                         const std::string& clip_id,
                         const std::string& scene_name,
                         const DriveClip& frames,
                         ExportClip* ec) {
  ec->clip_id = clip_id;
  ec->scene_name = scene_name;
  if (ctx.clip_index) {
    const auto it = ctx.clip_index->find(clip_id);
    if (it != ctx.clip_index->end()) ec->clip_index = it->second;
  }
  for (const DriveFrame& df : frames.frames) {
    ec->image_paths.push_back(df.image_path);
    ec->timestamps_us.push_back(df.timestamp_us);
  }
  ec->video_preset = ctx.options->video_preset;
  ec->video_crf = ctx.options->video_crf;
}

ClipFrames ExportFrames(const DriveClip& clip,
                        const ClipFrames& pair,
                        const BuildDatasetOptions& eopt) {
  const PinholeCamera& cam = clip.frames.front().camera;
  const ImageResizeSpec spec = OutputSpec(cam, eopt);
  ClipFrames out;
  out.first_frame_path = pair.first_frame_path;
  out.gt.resize(clip.frames.size());
  for (size_t i = 0; i < clip.frames.size(); ++i) {
    if (i < pair.full.size()) {
      const bool unchanged = spec.resized_width == cam.width &&
                             spec.resized_height == cam.height &&
                             spec.width == cam.width &&
                             spec.height == cam.height;
      // The pair's own decode, shared (exporters only read it).
      out.gt[i] =
          unchanged ? pair.full[i] : FullFrameToOutput(pair.full[i], spec);
      continue;
    }
    const std::string& path = clip.frames[i].image_path;
    const cv::Mat full = ReadImageRgb(path);
    GEODRIVE_CHECK_INPUT(full.cols == cam.width && full.rows == cam.height,
                         path, ": image is ", full.cols, "x", full.rows,
                         " but the dataset says ", cam.width, "x", cam.height);
    out.gt[i] = FullFrameToOutput(full, spec);
  }
  return out;
}

RenderKeep ExportRenderKeep(const ClipContext& ctx,
                            const BuildDatasetOptions& opt) {
  RenderKeep keep;
  if (!ctx.exporters) return keep;
  for (const auto& e : *ctx.exporters) {
    const ExportRequirements req = e->Requirements();
    if (!req.frames || !AtPairSize(req, opt)) continue;
    keep.native_frames |= req.native_condition;
    keep.depth |= req.depth;
  }
  return keep;
}

std::vector<std::unique_ptr<ClipExport>> PrepareClipExports(
    const ClipContext& ctx,
    const DriveClip& clip,
    const ConditionScene& scene,
    const ClipFrames& frames,
    const ConditionRender& cond,
    const BoxSequences& boxes) {
  std::vector<std::unique_ptr<ClipExport>> exports;
  if (!ctx.exporters) return exports;
  const BuildDatasetOptions& opt = *ctx.options;
  // LiDAR (by frame step) and objects, read once for the exporters that ask.
  const Rigid3d scene_from_world = clip.frames.front().world_from_cam.Inverse();
  std::map<int, std::shared_ptr<const std::vector<ExportSweep>>> sweeps;
  std::shared_ptr<const std::vector<std::vector<ExportObject>>> objects;
  for (const auto& e : *ctx.exporters) {
    const ExportRequirements req = e->Requirements();
    auto x = std::make_unique<ClipExport>();
    x->exporter = e.get();
    const ClipFrames* f = &frames;
    const ConditionRender* c = &cond;
    const BoxSequences* b = &boxes;
    BuildDatasetOptions eopt = opt;
    if (req.lidar_frame_step > 0 || req.objects) {
      // The dataset's LiDAR and boxes are in metres: they place only in a
      // metric scene (camera 0's frame, as the vehicle boxes).
      GEODRIVE_CHECK_INPUT(scene.metric(), clip.id, ": ", ToString(e->Format()),
                           " needs metric geometry (LiDAR and boxes in "
                           "metres); this scene is in ",
                           scene.units, " units");
    }
    if (req.lidar_frame_step > 0) {
      auto& s = sweeps[req.lidar_frame_step];
      if (!s) {
        s = std::make_shared<const std::vector<ExportSweep>>(
            ClipSweeps(clip, req.lidar_frame_step, scene_from_world,
                       ToString(e->Format())));
      }
      x->lidar = s;
    }
    if (req.objects) {
      if (!objects) {
        objects =
            std::make_shared<const std::vector<std::vector<ExportObject>>>(
                ClipObjects(clip, scene_from_world));
      }
      x->objects = objects;
    }
    if (!req.frames) {
      // Cameras, poses, LiDAR and objects only: nothing to decode or render.
      eopt.width = req.width > 0 ? req.width : opt.width;
      eopt.height = req.height > 0 ? req.height : opt.height;
      eopt.resize_mode =
          req.width > 0 ? ResizeMode::kCenterCrop : opt.resize_mode;
      f = nullptr;
      c = nullptr;
    } else if (!AtPairSize(req, opt)) {
      // The trainer's size: the frames decoded and the condition rendered at
      // it, centre-cropped to its aspect (never a resize of our frames).
      eopt.width = req.width;
      eopt.height = req.height;
      eopt.resize_mode = ResizeMode::kCenterCrop;
      x->frames = ExportFrames(clip, frames, eopt);
      x->boxes = ClipVehicleBoxes(clip, scene.metric(), eopt);
      f = &x->frames;
      b = &x->boxes;
      c = nullptr;
      if (req.condition) {
        RenderKeep keep;
        keep.depth = req.depth;
        x->cond = RenderCondition(scene, x->boxes, x->frames.gt, eopt, keep);
        c = &x->cond;
      }
    }
    ExportClip& ec = x->clip;
    const PinholeCamera& source = clip.frames.front().camera;
    ec.images_are_source = f != nullptr && eopt.width == source.width &&
                           eopt.height == source.height;
    SetExportClipSource(ctx, clip.id, clip.scene_name, clip, &ec);
    if (f) ec.images = &f->gt;
    ec.scene_cloud = &scene.cloud;
    if (c) ec.condition = &c->frames;
    if (req.depth && c) {
      ec.depth = &c->depth;
      ec.drawn = &c->drawn;
    }
    if (req.native_condition) ec.native_condition = &cond.native_frames;
    if (!frames.full.empty()) ec.first_frame_full = frames.full.front();
    ec.first_frame_path = frames.first_frame_path;
    ec.camera = scene.CameraAt(eopt.width, eopt.height, eopt.resize_mode);
    ec.world_from_cam = scene.trajectory.world_from_cam;
    ec.world_up = scene_from_world.rotation * Eigen::Vector3d::UnitZ();
    ec.metric = scene.metric();
    ec.boxes = b;
    ec.lidar = x->lidar.get();
    ec.objects = x->objects.get();
    exports.push_back(std::move(x));
  }
  return exports;
}

PairMeta BuildPair(const ClipContext& ctx,
                   const std::string& clip_id,
                   const std::string& tmp_dir,
                   std::map<std::string, double>* stage_seconds) {
  const BuildDatasetOptions& opt = *ctx.options;
  if (!opt.cameras.empty())
    return BuildRigPair(ctx, clip_id, tmp_dir, stage_seconds);
  // A novel-view pair: its source clip, rendered along a shifted trajectory.
  const PairNovelView* novel = NovelViewOf(ctx, clip_id);
  const std::string& source_id = novel ? novel->source_clip_id : clip_id;
  StageTimer timer(stage_seconds);
  const DriveClip clip =
      timer.Run("clip", [&] { return ctx.dataset->LoadClip(source_id); });
  const bool exporting = ctx.exporters && !ctx.exporters->empty();
  if (exporting) timer.Run("export", [&] { CheckClipForExports(ctx, clip); });
  // Full-size frames only as many as the source colours from (the LiDAR
  // sources: all, or frame 0); the others get the ground truth alone.
  const int full_size_images =
      CreateSceneSource(opt.SceneSourceName())->Traits().full_size_images;
  const ClipFrames frames = timer.Run(
      "gt", [&] { return ReadClipFrames(clip, opt, full_size_images); });
  const std::string path =
      ctx.folders ? ctx.folders->Find(source_id).value_or("") : std::string();
  ConditionScene scene = timer.Run("geometry", [&] {
    const auto build = [&] {
      return BuildClipScene(clip, frames.full, path, opt);
    };
    return novel && ctx.novel_scenes ? ctx.novel_scenes->Get(source_id, build)
                                     : build();
  });
  if (novel) timer.Run("geometry", [&] { ShiftScene(clip, *novel, &scene); });
  for (const auto& [step, s] : scene.seconds) {  // e.g. the LiDAR scale fit
    (*stage_seconds)[step] += s;
    (*stage_seconds)["geometry"] -= s;
  }
  const BoxSequences boxes = timer.Run(
      "boxes", [&] { return ClipVehicleBoxes(clip, scene.metric(), opt); });
  ConditionRender cond = timer.Run("render", [&] {
    return RenderCondition(scene, boxes, frames.gt, opt,
                           ExportRenderKeep(ctx, opt));
  });
  cond.completion_preview = CompletionPreview(scene);
  PairMeta meta = MakePairMeta(clip, scene, opt);
  if (novel) MarkNovelView(clip_id, *novel, &cond, &meta);
  std::vector<std::unique_ptr<ClipExport>> exports;
  if (exporting) {
    exports = timer.Run("export", [&] {
      return PrepareClipExports(ctx, clip, scene, frames, cond, boxes);
    });
  }
  timer.Run("encode", [&] {
    WritePairFolder(tmp_dir, frames, cond, boxes, opt, &meta, exports);
  });
  return meta;
}

}  // namespace internal
}  // namespace geodrive

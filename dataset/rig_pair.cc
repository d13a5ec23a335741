// Surround-view pairs (build-dataset --cameras; dataset/rig.h): one scene per
// clip, rendered into every camera of the rig.
//
// Per clip: the clip with every selected camera; per camera its frames
// (stage gt) and its scene from the run's scene source (stage geometry; the
// LiDAR sweeps are read once and shared by the cameras); the views fused into
// one cloud (stage fuse); per camera its vehicle boxes in the shared scene
// frame (stage boxes), its condition along its own poses (stage render); the
// seam check on the conditions' frame-0 depth (stage seams); the folder
// (stage encode):
//
//   gt_<CAM>.mp4, cond_<CAM>.mp4, boxes_<CAM>.json   per camera
//   gt.mp4, cond.mp4, boxes.json                      the reference camera's
//   first_frame.png                                   reference frame 0
//   preview.png      frame 0 of every camera in the rig's layout (front row
//                    FL F FR, back row BL B BR), GT above condition
//   meta.json        the reference camera's fields, plus views[] and seams[]

#include <algorithm>
#include <filesystem>
#include <mutex>
#include <opencv2/imgproc.hpp>

#include "dataset/drive_dataset.h"
#include "dataset/internal/pair_builder.h"
#include "dataset/internal/pair_png.h"
#include "dataset/rig.h"
#include "geometry/util/files.h"
#include "geometry/util/names.h"
#include "geometry/util/status.h"
#include "render/presets.h"
#include "render/renderer.h"
#include "render/video/h264.h"

namespace geodrive {
namespace internal {
namespace {

// The scene's sweeps for every camera of the rig, read once: Load() and the
// static returns in the world (StaticInWorld: the box test) memoised, so each
// camera's scene source only moves them into its own frame. Thread-safe for
// concurrent const calls, as the interface requires.
class SharedSweeps : public LidarProvider {
 public:
  explicit SharedSweeps(std::shared_ptr<const LidarProvider> base)
      : base_(std::move(base)),
        cache_(base_->Sweeps().size()),
        static_cache_(base_->Sweeps().size()) {}
  const std::vector<LidarSweepInfo>& Sweeps() const override {
    return base_->Sweeps();
  }
  PointCloud Load(size_t index) const override {
    std::lock_guard<std::mutex> lock(mutex_);
    std::shared_ptr<const PointCloud>& slot = cache_.at(index);
    if (!slot) slot = std::make_shared<const PointCloud>(base_->Load(index));
    return *slot;
  }
  std::vector<ClipBox> Boxes(size_t index) const override {
    return base_->Boxes(index);
  }
  std::shared_ptr<const std::vector<Eigen::Vector3d>> StaticInWorld(
      size_t index) const override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (const auto& slot = static_cache_.at(index)) return slot;
    }
    // Computed outside the lock (it loads through Load, which locks).
    auto points = LidarProvider::StaticInWorld(index);
    std::lock_guard<std::mutex> lock(mutex_);
    auto& slot = static_cache_.at(index);
    if (!slot) slot = std::move(points);
    return slot;
  }

 private:
  std::shared_ptr<const LidarProvider> base_;
  mutable std::mutex mutex_;
  mutable std::vector<std::shared_ptr<const PointCloud>> cache_;
  mutable std::vector<std::shared_ptr<const std::vector<Eigen::Vector3d>>>
      static_cache_;
};

// Everything one camera of the pair needs between the stages.
struct ViewWork {
  DriveClip clip;
  ClipFrames frames;
  BoxSequences boxes;
  ConditionRender cond;
  std::string file_stem;  // the channel as a path component
};

// `drawn` (sorted indices) with every point inside a vehicle box at frame 0
// (grown 1 m): the 3D editor moves those along their boxes, into view or
// out of it.
std::vector<size_t> WithPointsInBoxes(const PointCloud& cloud,
                                      const BoxSequences& boxes,
                                      std::vector<size_t> drawn) {
  // Box3d::Contains(p, 1.0) per box, its rotation taken once: the point in
  // box axes within the half extents grown 1 m; a sphere around the box
  // rejects most points first.
  struct Grown {
    Eigen::Vector3d center, half;
    Eigen::Matrix3d box_from_scene;
    double reach2;
  };
  std::vector<Grown> frame0;
  for (const BoxSequence& seq : boxes.instances) {
    if (const BoxFrame* f = seq.Find(0); f && f->box_3d) {
      const Box3d& b = *f->box_3d;
      const Eigen::Vector3d half = b.HalfExtents() + Eigen::Vector3d::Ones();
      frame0.push_back({b.center, half,
                        b.rotation.normalized().conjugate().toRotationMatrix(),
                        half.squaredNorm()});
    }
  }
  if (frame0.empty()) return drawn;
  std::vector<char> keep(cloud.size(), 0);
  for (size_t i : drawn) keep[i] = 1;
  // Groups of consecutive points whose bounding box is farther than every
  // sphere's reach from its centre (with a centimetre to spare over the
  // float box) hold no point of a box and are skipped whole.
  constexpr size_t kGroup = 256;
  for (size_t g0 = 0; g0 < cloud.size(); g0 += kGroup) {
    const size_t g1 = std::min(cloud.size(), g0 + kGroup);
    Eigen::Vector3f lo, hi;
    bool near_a_box = !PointGroupBounds(cloud, g0, g1, &lo, &hi);
    for (size_t b = 0; b < frame0.size() && !near_a_box; ++b) {
      const Eigen::Vector3d& c = frame0[b].center;
      const Eigen::Vector3d d =
          (lo.cast<double>() - c).cwiseMax(c - hi.cast<double>()).cwiseMax(0);
      const double reach = std::sqrt(frame0[b].reach2) + 0.01;
      near_a_box = d.squaredNorm() <= reach * reach;
    }
    if (!near_a_box) continue;
    for (size_t i = g0; i < g1; ++i) {
      if (keep[i]) continue;
      const Eigen::Vector3d p = cloud.positions[i].cast<double>();
      for (const Grown& b : frame0) {
        const Eigen::Vector3d d = p - b.center;
        if (d.squaredNorm() > b.reach2) continue;
        const Eigen::Vector3d q = b.box_from_scene * d;
        if (std::abs(q.x()) <= b.half.x() && std::abs(q.y()) <= b.half.y() &&
            std::abs(q.z()) <= b.half.z()) {
          keep[i] = 1;
          break;
        }
      }
    }
  }
  drawn.clear();
  for (size_t i = 0; i < cloud.size(); ++i)
    if (keep[i]) drawn.push_back(i);
  return drawn;
}

// Frame 0 of every camera in the rig's layout: GT above condition, labelled,
// 320 px wide tiles; cameras outside NuscenesRigLayout() in rows below.
cv::Mat RigMosaic(const std::vector<ViewWork>& views) {
  const int tile_w = 320;
  const auto tile_of = [&](const ViewWork& v) {
    const cv::Mat& gt = v.frames.gt.front();
    const int tile_h = std::max(1, gt.rows * tile_w / std::max(1, gt.cols));
    cv::Mat a, b, tile;
    cv::resize(gt, a, cv::Size(tile_w, tile_h), 0, 0, cv::INTER_AREA);
    cv::resize(v.cond.frames.front(), b, cv::Size(tile_w, tile_h), 0, 0,
               cv::INTER_AREA);
    cv::vconcat(a, b, tile);
    cv::putText(tile, v.clip.channel, cv::Point(6, 18),
                cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(255, 255, 255), 1,
                cv::LINE_AA);
    return tile;
  };
  const std::vector<std::string>& layout = NuscenesRigLayout();
  std::vector<int> slot(views.size());
  int next_free = static_cast<int>(layout.size());
  for (size_t k = 0; k < views.size(); ++k) {
    const auto it =
        std::find(layout.begin(), layout.end(), views[k].clip.channel);
    slot[k] = it != layout.end() ? static_cast<int>(it - layout.begin())
                                 : next_free++;
  }
  const int rows = (*std::max_element(slot.begin(), slot.end())) / 3 + 1;
  const cv::Mat first = tile_of(views.front());
  cv::Mat mosaic(first.rows * rows, tile_w * 3, CV_8UC3, cv::Scalar::all(0));
  for (size_t k = 0; k < views.size(); ++k) {
    cv::Mat tile = k == 0 ? first : tile_of(views[k]);
    if (tile.rows != first.rows)
      cv::resize(tile, tile, first.size(), 0, 0, cv::INTER_AREA);
    tile.copyTo(
        mosaic(cv::Rect((slot[k] % 3) * tile_w, (slot[k] / 3) * first.rows,
                        tile_w, first.rows)));
  }
  return mosaic;
}

// The seam check of every overlapping pair of cameras on their conditions'
// frame-0 depth (the z-buffer presets render at the output size). The
// released pipeline's preset renders at its own size: the frame-0 depth of
// the static scene is then rendered here at the output size.
std::vector<PairSeam> SeamCheck(const RigScene& rig,
                                const std::vector<ViewWork>& works,
                                const BuildDatasetOptions& opt) {
  if (rig.views.size() < 2) return {};  // no pair of cameras
  std::vector<std::string> channels;
  std::vector<PinholeCamera> cameras;
  std::vector<Rigid3d> poses;
  std::vector<cv::Mat> depth;
  RenderOptions ro = PresetRenderOptions(RenderPreset::kPaper);
  ro.width = opt.width;
  ro.height = opt.height;
  ro.radius_px = opt.splat_radius_px;
  ro.num_threads = opt.threads > 1 ? 1 : 0;
  for (size_t k = 0; k < rig.views.size(); ++k) {
    const RigView& v = rig.views[k];
    const PinholeCamera cam =
        v.source.CameraAt(opt.width, opt.height, opt.resize_mode);
    const cv::Mat& own = works[k].cond.depth0;
    if (own.cols == opt.width && own.rows == opt.height) {
      depth.push_back(own);
    } else {
      const PointCloud drawn = rig.cloud.Select(
          PointsInViewOfAny(rig.cloud, cam, {v.scene_from_cam.front()}, ro.near,
                            ro.far, ro.radius_px));
      depth.push_back(
          RenderFrames(drawn, {cam}, {v.scene_from_cam.front().Inverse()}, ro)
              .frames.front()
              .depth);
    }
    channels.push_back(v.channel);
    cameras.push_back(cam);
    poses.push_back(v.scene_from_cam.front());
  }
  std::vector<PairSeam> out;
  for (const SeamAgreement& s :
       RigSeamAgreement(channels, cameras, poses, depth))
    out.push_back({s.camera_a, s.camera_b, s.overlap_pixels, s.fraction()});
  return out;
}

PairView MakePairView(const ViewWork& w,
                      const RigView& rv,
                      const BuildDatasetOptions& opt) {
  PairView v;
  v.channel = rv.channel;
  for (const DriveFrame& f : w.clip.frames)
    v.frames.push_back({f.frame_id, f.timestamp_us, f.relative_path});
  v.intrinsics = rv.source.CameraAt(opt.width, opt.height, opt.resize_mode);
  v.world_from_cam = rv.scene_from_cam;
  v.coverage = w.cond.coverage;
  v.psnr_static = w.cond.psnr_static;
  if (rv.source.completion) {
    v.supported_fraction = rv.source.completion->supported_fraction;
    v.coverage_of_supported = rv.source.completion->coverage_of_supported;
  }
  v.points_built = rv.points_built;
  v.points_kept = rv.points_kept;
  v.files = {{"gt", "gt_" + w.file_stem + ".mp4"},
             {"cond", "cond_" + w.file_stem + ".mp4"},
             {"boxes", "boxes_" + w.file_stem + ".json"}};
  return v;
}

// Per exporter, its view of every camera of the rig (the reference camera
// first): the frames at the exporter's size resized from the view's own
// full-size decode, the camera's poses in the rig's scene frame, the fused
// cloud, and the LiDAR sweeps and objects (read once, placed in the scene
// frame, shared by the cameras). Only exporters that render no condition
// serve a rig (Exporter::WritesRigs; build-dataset refuses the others).
std::vector<std::vector<std::unique_ptr<ClipExport>>> PrepareRigExports(
    const ClipContext& ctx,
    const DriveClip& clip,
    const RigScene& rig,
    const std::vector<ViewWork>& views) {
  const BuildDatasetOptions& opt = *ctx.options;
  const Rigid3d scene_from_world = rig.world_from_scene.Inverse();
  const DriveClip& reference = views.front().clip;
  std::vector<std::vector<std::unique_ptr<ClipExport>>> out;
  for (const auto& e : *ctx.exporters) {
    const ExportRequirements req = e->Requirements();
    const std::string format = ToString(e->Format());
    GEODRIVE_CHECK_INPUT(e->WritesRigs() && !(req.frames && req.condition),
                         clip.id, ": ", format,
                         " is single-camera; drop --cameras");
    auto lidar = std::make_shared<const std::vector<ExportSweep>>();
    if (req.lidar_frame_step > 0) {
      lidar = std::make_shared<const std::vector<ExportSweep>>(ClipSweeps(
          reference, req.lidar_frame_step, scene_from_world, format));
    }
    auto objects =
        std::make_shared<const std::vector<std::vector<ExportObject>>>();
    if (req.objects) {
      objects = std::make_shared<const std::vector<std::vector<ExportObject>>>(
          ClipObjects(reference, scene_from_world));
    }
    BuildDatasetOptions eopt = opt;
    if (req.width > 0) {
      eopt.width = req.width;
      eopt.height = req.height;
      eopt.resize_mode = ResizeMode::kCenterCrop;
    }
    std::vector<std::unique_ptr<ClipExport>> cameras;
    for (size_t k = 0; k < views.size(); ++k) {
      const ViewWork& w = views[k];
      const RigView& rv = rig.views[k];
      auto x = std::make_unique<ClipExport>();
      x->exporter = e.get();
      x->lidar = lidar;
      x->objects = objects;
      if (req.frames) x->frames = ExportFrames(w.clip, w.frames, eopt);
      ExportClip& ec = x->clip;
      SetExportClipSource(ctx, clip.id, clip.scene_name, w.clip, &ec);
      ec.channel = rv.channel;
      if (req.frames) ec.images = &x->frames.gt;
      const PinholeCamera& source = w.clip.frames.front().camera;
      ec.images_are_source = req.frames && eopt.width == source.width &&
                             eopt.height == source.height;
      ec.scene_cloud = &rig.cloud;
      ec.camera = rv.source.CameraAt(eopt.width, eopt.height, eopt.resize_mode);
      ec.world_from_cam = rv.scene_from_cam;
      ec.world_up = scene_from_world.rotation * Eigen::Vector3d::UnitZ();
      ec.metric = rig.metric();
      ec.boxes = &w.boxes;
      if (req.lidar_frame_step > 0) ec.lidar = x->lidar.get();
      if (req.objects) ec.objects = x->objects.get();
      cameras.push_back(std::move(x));
    }
    out.push_back(std::move(cameras));
  }
  return out;
}

void WriteRigPairFolder(
    const std::string& dir,
    const std::vector<ViewWork>& views,
    const BuildDatasetOptions& opt,
    const std::vector<std::vector<std::unique_ptr<ClipExport>>>& exports,
    PairMeta* meta) {
  for (const auto& cameras : exports) {
    std::vector<ExportClip> clips;
    for (const auto& x : cameras) clips.push_back(x->clip);
    cameras.front()->exporter->WriteRig(clips, dir, meta);
  }
  H264Options vo;
  vo.fps = opt.fps;
  vo.preset = opt.video_preset;
  vo.crf = opt.video_crf;
  for (size_t k = 0; k < views.size(); ++k) {
    const ViewWork& w = views[k];
    const PairView& pv = meta->views[k];
    WriteH264Mp4(dir + "/" + pv.files.at("gt"), w.frames.gt, vo);
    WriteH264Mp4(dir + "/" + pv.files.at("cond"), w.cond.frames, vo);
    WriteBoxesJson(dir + "/" + pv.files.at("boxes"), w.boxes);
    for (const auto& [role, name] : pv.files)
      meta->files[role + ":" + pv.channel] = name;
  }
  // The reference camera under the single-camera names too: every reader of
  // single-camera pairs reads a rig pair's reference view.
  namespace fs = std::filesystem;
  for (const char* role : {"gt", "cond", "boxes"}) {
    const std::string name = meta->views.front().files.at(role);
    const std::string plain =
        std::string(role) + (role[0] == 'b' ? ".json" : ".mp4");
    // A second name of the same file (a copy where links are refused).
    std::error_code ec;
    fs::remove(dir + "/" + plain, ec);
    fs::create_hard_link(dir + "/" + name, dir + "/" + plain, ec);
    if (ec)
      fs::copy_file(dir + "/" + name, dir + "/" + plain,
                    fs::copy_options::overwrite_existing);
    meta->files[role] = plain;
  }
  WritePairPng(dir + "/first_frame.png", views.front().frames.gt.front());
  WritePairPng(dir + "/preview.png", RigMosaic(views));
  meta->files["first_frame"] = "first_frame.png";
  meta->files["preview"] = "preview.png";
  meta->files["meta"] = "meta.json";
  for (const auto& [role, name] : meta->files) {
    std::error_code ec;
    if (name != "meta.json" && fs::is_regular_file(dir + "/" + name, ec))
      meta->file_sizes[name] = fs::file_size(dir + "/" + name, ec);
  }
  WriteFileAtomic(dir + "/meta.json", PairMetaToJson(*meta));
}

}  // namespace

PairMeta BuildRigPair(const ClipContext& ctx,
                      const std::string& clip_id,
                      const std::string& tmp_dir,
                      std::map<std::string, double>* stage_seconds) {
  const BuildDatasetOptions& opt = *ctx.options;
  StageTimer timer(stage_seconds);
  DriveClip clip =
      timer.Run("clip", [&] { return ctx.dataset->LoadClip(clip_id); });
  GEODRIVE_CHECK_INPUT(!clip.rig.empty(), clip_id,
                       ": the dataset gave a single-camera clip for --cameras");
  if (clip.lidar) clip.lidar = std::make_shared<SharedSweeps>(clip.lidar);
  const int full_size_images =
      CreateSceneSource(opt.SceneSourceName())->Traits().full_size_images;
  std::vector<ViewWork> views(clip.num_views());
  std::vector<ConditionScene> scenes;
  for (int k = 0; k < clip.num_views(); ++k) {
    ViewWork& w = views[k];
    w.clip = clip.View(k);
    w.file_stem = PathComponentFromName(w.clip.channel, "camera channel");
    w.frames = timer.Run(
        "gt", [&] { return ReadClipFrames(w.clip, opt, full_size_images); });
    scenes.push_back(timer.Run("geometry", [&] {
      return BuildClipScene(w.clip, w.frames.full, "", opt);
    }));
  }
  const RigScene rig =
      timer.Run("fuse", [&] { return FuseRigScenes(clip, std::move(scenes)); });
  const Rigid3d scene_from_world = rig.world_from_scene.Inverse();
  for (int k = 0; k < clip.num_views(); ++k) {
    ViewWork& w = views[k];
    const RigView& rv = rig.views[k];
    w.boxes = timer.Run("boxes", [&] {
      return ClipVehicleBoxes(w.clip, true, opt, scene_from_world);
    });
    // The points this camera can draw in some frame (the others cost the
    // renderer and the dynamic editor time for nothing); the z-buffer
    // presets only (a soft splat's reach is in NDC).
    PointCloud visible;
    const RenderOptions ro = PresetRenderOptions(opt.preset);
    if (ro.mode == RenderMode::kZBuffer) {
      timer.Run("render", [&] {
        const double margin =
            std::max(opt.splat_radius_px, ro.max_footprint_magnification / 2);
        std::vector<size_t> drawn = PointsInViewOfAny(
            rig.cloud,
            rv.source.CameraAt(opt.width, opt.height, opt.resize_mode),
            rv.scene_from_cam, ro.near, ro.far, margin);
        if (opt.edit_mode == PairEditMode::k3d)
          drawn = WithPointsInBoxes(rig.cloud, w.boxes, std::move(drawn));
        visible = rig.cloud.Select(drawn);
      });
    }
    ViewToRender view;
    view.cloud = ro.mode == RenderMode::kZBuffer ? &visible : &rig.cloud;
    view.camera = rv.source.camera;
    view.scene_from_cam = rv.scene_from_cam;
    view.metric = true;
    view.dynamic_mask = rv.source.dynamic_mask;
    w.cond = timer.Run("render", [&] {
      return RenderConditionView(view, w.boxes, w.frames.gt, opt);
    });
  }
  // The reference camera's fields as a single-camera pair has them.
  const ConditionScene& reference = rig.views.front().source;
  PairMeta meta = MakePairMeta(views.front().clip, reference, opt);
  meta.quality.coverage = views.front().cond.coverage;
  meta.quality.psnr_static = views.front().cond.psnr_static;
  for (int k = 0; k < clip.num_views(); ++k)
    meta.views.push_back(MakePairView(views[k], rig.views[k], opt));
  meta.seams = timer.Run("seams", [&] { return SeamCheck(rig, views, opt); });
  std::vector<std::vector<std::unique_ptr<ClipExport>>> exports;
  if (ctx.exporters && !ctx.exporters->empty()) {
    exports = timer.Run("export", [&] {
      for (const ViewWork& w : views) CheckClipForExports(ctx, w.clip);
      return PrepareRigExports(ctx, clip, rig, views);
    });
  }
  timer.Run("encode",
            [&] { WriteRigPairFolder(tmp_dir, views, opt, exports, &meta); });
  return meta;
}

}  // namespace internal
}  // namespace geodrive

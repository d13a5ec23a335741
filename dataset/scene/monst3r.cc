// Scene source "monst3r": a MonST3R output folder (geometry/monst3r.h); and,
// through the same code, every other reconstruction tool's output read by
// geometry/reconstruction.h (sources "vggt", "da3", "cut3r", "megasam",
// "npz": dataset/scene/reconstruction_source.h).
//
// kPaper (the data engine, `build-dataset`): frame 0's pointmap filtered by
// confidence (tau) and depth range, made metric by a robust LiDAR depth fit
// when the clip has LiDAR (dataset/lidar_alignment.h), expressed in camera
// 0's frame with every frame's cam0_from_cam. kReleased (`render`,
// `generate`, as the released scripts): every pixel of frame 0's depth, in
// MonST3R's world and units, along pred_traj.txt.

#include <chrono>
#include <cmath>
#include <limits>

#include "dataset/lidar_alignment.h"
#include "dataset/scene/define.h"
#include "dataset/scene/reconstruction_source.h"
#include "geometry/image_io.h"
#include "geometry/pointmap.h"
#include "geometry/pose_refinement.h"
#include "geometry/util/status.h"
#include "render/video/video.h"

namespace geodrive {
namespace {

// The metric scale of the folder from the clip's LiDAR, or why there is none.
SceneScale FitScale(const SceneInputs& in,
                    const SceneSourceOptions& options,
                    const Monst3rFolder& folder,
                    std::map<std::string, double>* seconds) {
  SceneScale scale;
  if (!in.clip || !in.clip->lidar || !options.lidar_scale) {
    if (folder.units() == "metres") {
      scale.source = "given";
      scale.report = folder.format() + " states metric depth (no LiDAR fit)";
      return scale;
    }
    scale.source = "none";
    scale.report = "no LiDAR in the dataset: poses and depth stay in " +
                   folder.format() + " units";
    return scale;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const ClipScaleReport report =
      FitClipLidarScale(*in.clip, folder, LidarScaleOptions());
  (*seconds)["scale"] +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
          .count();
  if (report.success) {
    scale.scale = report.clip_fit.scale;
    scale.source = "lidar";
    scale.report = report.BriefReport();
    scale.inlier_fraction = report.clip_fit.inlier_fraction;
  } else {
    scale.source = "none";
    scale.report = report.message;
  }
  return scale;
}

// The folder's poses refined by reprojection over static confident pixels
// (geometry/pose_refinement.h, independent frames); the RMS before and after
// pooled over every frame's sampled pixels.
Trajectory RefinePoses(const Monst3rFolder& folder,
                       const SceneSourceOptions& options,
                       ConditionScene* scene) {
  const auto t0 = std::chrono::steady_clock::now();
  PointmapFilterOptions filter;
  filter.min_confidence = options.min_confidence;
  filter.min_depth = 0.0;
  filter.max_depth = std::numeric_limits<double>::infinity();
  filter.selection = PixelSelection::kStaticOnly;
  std::vector<int> frames(folder.num_frames());
  for (int i = 0; i < folder.num_frames(); ++i) frames[i] = i;
  const std::vector<PoseRefinementInput> inputs =
      PoseRefinementInputs(folder, frames, filter);
  PoseRefinementOptions ro;  // seeded sampling: deterministic
  const std::vector<PoseRefinementResult> results =
      RefineClipPoses(inputs, ro, /*joint=*/false);
  Trajectory refined;
  double before = 0, after = 0;
  int64_t n = 0;
  for (size_t k = 0; k < results.size(); ++k) {
    const PoseRefinementSummary& s = results[k].summary;
    refined.Add(folder.trajectory().timestamps[k],
                s.usable ? results[k].world_from_cam
                         : folder.trajectory().world_from_cam[k]);
    if (s.skipped || s.num_residuals == 0) continue;
    before += s.initial_rms_px * s.initial_rms_px * s.num_residuals;
    after += (s.usable ? s.final_rms_px : s.initial_rms_px) *
             (s.usable ? s.final_rms_px : s.initial_rms_px) * s.num_residuals;
    n += s.num_residuals;
  }
  if (n > 0) {
    scene->reprojection_rms_px_before = std::sqrt(before / n);
    scene->reprojection_rms_px_after = std::sqrt(after / n);
  }
  scene->seconds["refine"] +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
          .count();
  return refined;
}

// ConditionScene::units of a reconstruction without a metric scale.
std::string RelativeUnits(const Monst3rFolder& folder) {
  return folder.format() == "MonST3R" ? "monst3r" : "unknown";
}

ConditionScene BuildPaper(const SceneInputs& in,
                          const SceneSourceOptions& options,
                          const Monst3rFolder& folder) {
  const std::string& dir = in.path;
  ConditionScene scene;
  const Trajectory trajectory = options.refine_poses
                                    ? RefinePoses(folder, options, &scene)
                                    : folder.trajectory();
  scene.scale = FitScale(in, options, folder, &scene.seconds);
  const bool metric =
      scene.scale.source == "lidar" || scene.scale.source == "given";
  const double scale = scene.scale.scale;
  Monst3rLoadOptions load;
  load.init_confidence = false;
  const Monst3rFrame frame0 = folder.LoadFrame(0, load);
  scene.dynamic_mask = frame0.enlarged_dynamic_mask.empty()
                           ? frame0.dynamic_mask
                           : frame0.enlarged_dynamic_mask;
  scene.frame0_rgb = frame0.rgb;
  Pointmap pm = BuildPointmap(frame0, scale);
  PointmapFilterOptions filter;
  filter.min_confidence = options.min_confidence;
  filter.min_depth = metric ? options.min_depth_m : 0.0;
  filter.max_depth =
      metric ? options.max_depth_m : std::numeric_limits<double>::infinity();
  // Dynamic objects are kept: the editor handles them.
  filter.selection = PixelSelection::kAll;
  const cv::Mat valid = ComputeValidMask(pm, filter);
  const PointCloud in_world = ExtractPoints(pm, valid);
  GEODRIVE_CHECK_INPUT(!in_world.empty(), dir,
                       ": no frame-0 pixel passes the filters");
  // Everything in camera 0's frame (MonST3R world = its first camera, up to
  // noise).
  Rigid3d world_from_cam0 = trajectory.world_from_cam.front();
  world_from_cam0.translation *= scale;
  const Rigid3d cam0_from_world = world_from_cam0.Inverse();
  scene.cloud = in_world;
  for (auto& p : scene.cloud.positions)
    p = (cam0_from_world * p.cast<double>()).cast<float>();
  for (int i = 0; i < folder.num_frames(); ++i) {
    Rigid3d w = trajectory.world_from_cam[i];
    w.translation *= scale;
    scene.trajectory.Add(trajectory.timestamps[i], cam0_from_world * w);
  }
  scene.camera = folder.cameras().front();
  scene.units = metric ? "metres" : RelativeUnits(folder);
  scene.description = folder.format() + " " + dir + " frame 0 (paper filters)";
  return scene;
}

ConditionScene BuildReleased(const SceneInputs& in,
                             const Monst3rFolder& folder) {
  Monst3rLoadOptions lo;
  lo.confidence = lo.dynamic_masks = lo.enlarged_dynamic_masks = false;
  lo.reject_all_invalid_confidence = false;
  lo.rgb = folder.has_rgb();
  const Monst3rFrame f0 = folder.LoadFrame(0, lo);
  cv::Mat image = in.image;
  if (image.empty() && !in.image_path.empty())
    image = ReadImageRgb(in.image_path);
  if (image.empty()) image = f0.rgb;
  GEODRIVE_CHECK_INPUT(!image.empty(), in.path,
                       folder.in_memory()
                           ? ": no images in the file (needed for colours; "
                             "pass --image)"
                           : ": frame_0000.png is missing (needed for "
                             "colours; or pass --image)");
  const cv::Mat colours =
      f0.rgb.empty() || f0.rgb.size() != f0.depth.size()
          ? ResizeBilinear(image, f0.depth.cols, f0.depth.rows)
          : f0.rgb;
  ConditionScene scene;
  // The released pipeline: frame-0 pointmap, no confidence threshold.
  scene.cloud = CloudFromDepth(f0.depth, colours, f0.camera, f0.world_from_cam);
  scene.trajectory = folder.trajectory();
  scene.anchor = TrajectoryAnchor::kFirstFrame;
  scene.scene_from_cam0 = f0.world_from_cam;
  scene.camera = f0.camera;
  scene.frame0_rgb = image;
  if (folder.has_rgb() && !folder.in_memory()) {
    for (int i = 0; i < folder.num_frames(); ++i)
      scene.frame_image_paths.push_back(folder.RgbPath(i));
  }
  scene.units = folder.units() == "metres" ? "metres" : RelativeUnits(folder);
  scene.scale.source = folder.units() == "metres" ? "given" : "none";
  scene.scale.report = folder.units() == "metres"
                           ? folder.format() + " states metric depth"
                           : folder.format() + " units (no metric scale)";
  scene.description = folder.format() + " " + in.path + " frame 0";
  return scene;
}

}  // namespace

SceneSourceTraits ReconstructionSceneSource::Traits() const {
  const auto reader = CreateReconstructionReader(format_);
  const ReconstructionConventions c = reader->Conventions();
  SceneSourceTraits t;
  t.needs_path = true;
  t.help = format_ == ReconstructionFormat::kMonst3r
               ? "a MonST3R output folder (pred_traj.txt, "
                 "pred_intrinsics.txt, frame_NNNN.npy, conf_N.npy, masks)"
               : reader->ToolName() + " output (" + c.pose + "; " +
                     c.confidence + ")";
  t.folder_marker =
      format_ == ReconstructionFormat::kMonst3r ? "pred_traj.txt" : "";
  return t;
}

ConditionScene ReconstructionSceneSource::Build(
    const SceneInputs& in, const SceneSourceOptions& options) const {
  const Monst3rFolder folder = ReadReconstruction(format_, in.path);
  const std::string& tool = folder.format();
  // A single-image tool (MoGe) takes the clip's camera trajectory.
  const bool single = in.clip && folder.num_frames() == 1 &&
                      in.clip->num_frames() > 1 &&
                      format_ == ReconstructionFormat::kMoge;
  if (in.clip && !single && folder.num_frames() != in.clip->num_frames()) {
    ThrowInputError(in.path, tool, " output has ", folder.num_frames(),
                    " frames but the clip has ", in.clip->num_frames());
  }
  if (in.clip) {  // the tool's resize of the clip's images
    const PinholeCamera& cam = in.clip->frames.front().camera;
    const ImageResizeSpec spec = folder.SourceToGrid(cam.width, cam.height);
    if (spec.width != folder.width() || spec.height != folder.height()) {
      ThrowInputError(in.path, tool, " images are ", folder.width(), "x",
                      folder.height(), " but the clip's ", cam.width, "x",
                      cam.height, " images map to ", spec.width, "x",
                      spec.height, " (", ToString(folder.grid_resize()),
                      "): not this clip's output");
    }
    // A resize of the whole image keeps its aspect ratio up to the tools'
    // rounding of each side (DA3: multiples of 14, up to 5 %).
    const double aspect = double(folder.width()) / folder.height();
    const double source = double(cam.width) / cam.height;
    if (folder.grid_resize() == GridResize::kStretch &&
        std::abs(aspect / source - 1) > 0.06) {
      ThrowInputError(in.path, tool, " images are ", folder.width(), "x",
                      folder.height(), " (aspect ", aspect, ") but the clip's ",
                      cam.width, "x", cam.height, " (aspect ", source,
                      "): not a resize of this clip's images (crop first)");
    }
  }
  if (!single) {
    ConditionScene scene = options.filter == PointmapFilter::kPaper
                               ? BuildPaper(in, options, folder)
                               : BuildReleased(in, folder);
    scene.has_camera = true;
    return scene;
  }
  // Frame 0 from the image (its scale from frame 0's LiDAR), every frame's
  // pose from the clip: cam0_from_cam_i = inverse(world_from_cam_0) *
  // world_from_cam_i, metric.
  DriveClip first = *in.clip;
  first.frames.resize(1);
  SceneInputs in0 = in;
  in0.clip = &first;
  ConditionScene scene = BuildPaper(in0, options, folder);
  GEODRIVE_CHECK_INPUT(scene.metric(), in.path, ": ", tool,
                       " depth is up to scale and could not be made metric "
                       "for the clip's metric trajectory (",
                       scene.scale.report, ")");
  const Trajectory clip_traj = CameraTrajectory(*in.clip);
  const Rigid3d cam0_from_world = clip_traj.world_from_cam.front().Inverse();
  scene.trajectory = Trajectory();
  for (size_t i = 0; i < clip_traj.size(); ++i)
    scene.trajectory.Add(static_cast<double>(i),  // frame index, as above
                         cam0_from_world * clip_traj.world_from_cam[i]);
  scene.description += " with the clip's camera trajectory";
  scene.has_camera = true;
  return scene;
}

}  // namespace geodrive

GEODRIVE_DEFINE_SCENE_SOURCE(monst3r, geodrive::Monst3rSceneSource)

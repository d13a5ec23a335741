// Dynamic editing, 3D mode: the edited scene (segmented objects with per-frame
// poses, removals, insertions; BuildDynamicScene), its per-frame composition
// and the rendering of the clip with the edits (RenderWithDynamicEdits, which
// also dispatches the 2D mode).

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <set>
#include <string>
#include <utility>

#include "geometry/util/status.h"
#include "render/dynamic_edit.h"
#include "render/footprint.h"
#include "render/internal/dynamic_edit_internal.h"

namespace geodrive {
namespace {

using dynamic_edit_internal::AddNote;
using dynamic_edit_internal::BuildTrack;
using dynamic_edit_internal::CameraOf;
using dynamic_edit_internal::CheckClip;
using dynamic_edit_internal::EditPlan;
using dynamic_edit_internal::FindGroundPlane;
using dynamic_edit_internal::Frame0Projection;
using dynamic_edit_internal::FrameList;
using dynamic_edit_internal::LiftTranslation;
using dynamic_edit_internal::NeedsGroundPlane;
using dynamic_edit_internal::PixelBox;
using dynamic_edit_internal::PlanEdits;
using dynamic_edit_internal::ProjectFrame0;
using dynamic_edit_internal::Render2d;
using dynamic_edit_internal::Segment;
using dynamic_edit_internal::Segmentation;
using dynamic_edit_internal::SegmentInstances;
using dynamic_edit_internal::StripForRender;
using dynamic_edit_internal::Track;

// Poses of an object along `track`.
std::vector<std::optional<ObjectPose>> TrackPoses(
    const Segment& seg,
    const Track& track,
    const std::string& id,
    const BoxSequences& boxes,
    const std::vector<PinholeCamera>& cameras,
    const std::vector<Rigid3d>& cam_from_world,
    const std::optional<Eigen::Vector4d>& plane,
    double min_box_area_px,
    DynamicEditSummary* summary,
    int* shown) {
  const int n = static_cast<int>(cam_from_world.size());
  std::vector<std::optional<ObjectPose>> poses(n);
  std::vector<int> hidden, unlifted, skipped;
  *shown = 0;
  const PinholeCamera& camera0 = CameraOf(cameras, 0);
  for (int f = 0; f < n; ++f) {
    if (seg.box0 && track.box_3d[f]) {
      const Box3d& b = *track.box_3d[f];
      ObjectPose pose;
      pose.world_from_object = b.WorldFromBox();
      pose.scale = b.HalfExtents().cwiseQuotient(seg.box0->HalfExtents());
      poses[f] = pose;
    } else {
      const PinholeCamera& camera = CameraOf(cameras, f);
      const std::optional<Box2d> box =
          PixelBox(track, f, boxes, camera, cam_from_world[f]);
      if (!box) {
        hidden.push_back(f);
        continue;
      }
      if (box->Clipped(camera.width, camera.height).Area() <
          std::max(min_box_area_px, 1e-9)) {
        skipped.push_back(f);
        continue;
      }
      const std::optional<Eigen::Vector3d> t =
          LiftTranslation(seg.lift, *box, camera, cam_from_world[f], camera0,
                          cam_from_world[0], plane);
      if (!t) {
        unlifted.push_back(f);
        continue;
      }
      ObjectPose pose;
      if (seg.box0) {
        // Object frame = frame-0 box frame, translated.
        pose.world_from_object = seg.box0->WorldFromBox();
        pose.world_from_object.translation += *t;
      } else {
        pose.world_from_object = Rigid3d(Eigen::Quaterniond::Identity(), *t);
      }
      poses[f] = pose;
    }
    ++*shown;
  }
  if (!hidden.empty())
    AddNote(summary, id, -1,
            "not drawn in frames without a box: " + FrameList(hidden));
  if (!skipped.empty())
    AddNote(summary, id, -1,
            "2D box empty or outside the image, not drawn in frames: " +
                FrameList(skipped));
  if (!unlifted.empty())
    AddNote(summary, id, -1,
            "2D box could not be lifted to 3D (no ground hit, no depth) in "
            "frames: " +
                FrameList(unlifted));
  if (!track.interpolated.empty())
    AddNote(summary, id, -1,
            "boxes interpolated in frames: " + FrameList(track.interpolated));
  return poses;
}

// world_from_object with the object's scale: x_world = R (s .* x) + t.
Matrix3x4d AffineOf(const ObjectPose& pose) {
  Matrix3x4d a;
  a.leftCols<3>() =
      pose.world_from_object.rotation.normalized().toRotationMatrix() *
      pose.scale.asDiagonal();
  a.col(3) = pose.world_from_object.translation;
  return a;
}

// The scene's objects as moving point sets (their points are moved out), in
// object order (so depth ties keep object order).
std::vector<MovingPointSet> MovingSets(DynamicScene&& scene) {
  std::vector<MovingPointSet> sets;
  for (DynamicObject& object : scene.objects) {
    MovingPointSet set;
    set.points = std::move(object.points_in_object);
    set.instance_id = object.render_id;
    set.world_from_set.resize(scene.num_frames);
    for (size_t f = 0;
         f < object.poses.size() && f < static_cast<size_t>(scene.num_frames);
         ++f) {
      if (object.poses[f]) set.world_from_set[f] = AffineOf(*object.poses[f]);
    }
    sets.push_back(std::move(set));
  }
  return sets;
}

// Appends the objects drawn in `frame`, mapped to the world, to `out` (which
// already holds the background).
void AppendObjects(const DynamicScene& scene, int frame, PointCloud* out) {
  for (const DynamicObject& object : scene.objects) {
    if (frame >= static_cast<int>(object.poses.size()) || !object.poses[frame])
      continue;
    const ObjectPose& pose = *object.poses[frame];
    const PointCloud& points = object.points_in_object;
    const Matrix3x4d a = AffineOf(pose);
    const Eigen::Matrix3f linear = a.leftCols<3>().cast<float>();
    const Eigen::Vector3f t = a.col(3).cast<float>();
    const bool colors = out->HasColors() || out->empty();
    for (const Eigen::Vector3f& p : points.positions)
      out->positions.push_back(linear * p + t);
    if (colors && points.HasColors())
      out->colors.insert(out->colors.end(), points.colors.begin(),
                         points.colors.end());
    out->instance_ids.insert(out->instance_ids.end(), points.size(),
                             object.render_id);
    // Footprints grow with the largest axis scale, surface axes map through
    // the linear part (as the renderer does for moving sets); none = 0.
    const float scale =
        static_cast<float>(a.leftCols<3>().colwise().norm().maxCoeff());
    const bool axes = !points.footprint_u.empty();
    for (size_t i = 0; i < points.size(); ++i) {
      out->footprints.push_back(
          points.HasFootprints() ? points.footprints[i] * scale : 0.0f);
      out->footprint_u.push_back(
          axes ? Eigen::Vector3f(linear * points.footprint_u[i])
               : Eigen::Vector3f::Zero());
      out->footprint_v.push_back(
          axes ? Eigen::Vector3f(linear * points.footprint_v[i])
               : Eigen::Vector3f::Zero());
    }
  }
}

// The inputs of BuildDynamicScene that its steps share.
struct SceneInputs {
  const PointCloud& cloud_in_world;
  const std::vector<PinholeCamera>& cameras;
  const std::vector<Rigid3d>& cam_from_world;
  const BoxSequences& boxes;
  const DynamicEditOptions& options;
};

// The object of segment `seg` (its points in the object frame: the frame-0
// box's frame, or the world without a 3D box), no poses yet.
DynamicObject MakeObject(const PointCloud& cloud_in_world,
                         const Segment& seg,
                         const std::string& id,
                         const std::string& source,
                         int32_t render_id) {
  DynamicObject object;
  object.id = id;
  object.source_id = source;
  object.render_id = render_id;
  object.points_in_object = StripForRender(cloud_in_world, seg.indices);
  // Footprints are set in the object's frame (SetFootprints).
  object.points_in_object.footprints.clear();
  object.points_in_object.footprint_u.clear();
  object.points_in_object.footprint_v.clear();
  const Rigid3d object_from_world =
      seg.box0 ? seg.box0->WorldFromBox().Inverse() : Rigid3d();
  const Eigen::Matrix3d object_r =
      object_from_world.rotation.toRotationMatrix();
  const Eigen::Vector3d object_t = object_from_world.translation;
  for (Eigen::Vector3f& p : object.points_in_object.positions)
    p = (object_r * p.cast<double>() + object_t).cast<float>();
  return object;
}

// The points' frame-0 pixel footprints (render/footprint.h: camera-0 depth /
// sqrt(fx fy)), unless magnification is off.
void SetFootprints(const SceneInputs& in,
                   const Segment& seg,
                   DynamicObject* object) {
  if (!(in.options.max_magnification > 1)) return;
  const Rigid3d world_from_object0 =
      seg.box0 ? seg.box0->WorldFromBox() : Rigid3d();
  // Camera-facing footprints (no surface axes): an object is small and
  // mostly seen face-on, and its points are projected every frame.
  SetCaptureFootprints(CameraOf(in.cameras, 0),
                       in.cam_from_world[0] * world_from_object0,
                       &object->points_in_object, /*surface_axes=*/false);
}

// The object of `seg` (render id: the next in `scene`) following `track`:
// its poses (notes go to `summary`) and footprints.
DynamicObject MakeMovingObject(const SceneInputs& in,
                               const Segment& seg,
                               const Track& track,
                               const std::string& id,
                               const std::string& source,
                               const std::optional<Eigen::Vector4d>& plane,
                               const DynamicScene& scene,
                               DynamicEditSummary* summary,
                               int* frames_shown) {
  DynamicObject object = MakeObject(in.cloud_in_world, seg, id, source,
                                    static_cast<int32_t>(scene.objects.size()));
  object.poses =
      TrackPoses(seg, track, id, in.boxes, in.cameras, in.cam_from_world, plane,
                 in.options.min_box_area_px, summary, frames_shown);
  SetFootprints(in, seg, &object);
  return object;
}

// The instances of the boxes file, in file order: removed (their points
// dropped), moved (along the edit's boxes) or animated (along their own).
void AddInstanceObjects(const SceneInputs& in,
                        const EditPlan& plan,
                        const std::vector<Track>& tracks,
                        const Segmentation& segmentation,
                        const std::optional<Eigen::Vector4d>& plane,
                        DynamicScene* scene,
                        DynamicEditSummary* summary) {
  const BoxSequences& boxes = in.boxes;
  for (size_t k = 0; k < boxes.instances.size(); ++k) {
    const BoxSequence& s = boxes.instances[k];
    const bool removed = plan.removed.count(s.id) > 0;
    const auto moved = plan.moved.find(s.id);
    AppliedEdit applied;
    applied.kind =
        removed ? "remove" : (moved != plan.moved.end() ? "move" : "animate");
    applied.instance = s.id;
    if (!segmentation.segments[k]) {
      if (removed || moved != plan.moved.end())
        AddNote(summary, s.id, -1,
                applied.kind + " skipped: no points segmented");
      continue;
    }
    const Segment& seg = *segmentation.segments[k];
    applied.num_points = static_cast<int64_t>(seg.indices.size());
    if (removed) {
      summary->removed_points += applied.num_points;
      summary->edits.push_back(applied);
      continue;
    }
    const Track track = moved != plan.moved.end()
                            ? BuildTrack(*moved->second, scene->num_frames,
                                         in.options.interpolate_missing)
                            : tracks[k];
    DynamicObject object =
        MakeMovingObject(in, seg, track, s.id, "", plane, *scene, summary,
                         &applied.frames_shown);
    summary->object_points += applied.num_points;
    scene->objects.push_back(std::move(object));
    summary->edits.push_back(applied);
  }
}

// The inserted copies, in edit order: the source instance's points along the
// edit's boxes.
void AddInsertedObjects(const SceneInputs& in,
                        const EditPlan& plan,
                        const Segmentation& segmentation,
                        const std::optional<Eigen::Vector4d>& plane,
                        DynamicScene* scene,
                        DynamicEditSummary* summary) {
  const BoxSequences& boxes = in.boxes;
  for (const ObjectEdit* e : plan.inserts) {
    size_t k = 0;
    while (boxes.instances[k].id != e->instance) ++k;
    AppliedEdit applied;
    applied.kind = "insert";
    applied.instance = e->sequence.id;
    applied.source = e->instance;
    if (!segmentation.segments[k]) {
      AddNote(summary, e->sequence.id, -1,
              "insert skipped: source '" + e->instance +
                  "' has no segmented points");
      continue;
    }
    const Segment& seg = *segmentation.segments[k];
    const Track track = BuildTrack(e->sequence, scene->num_frames,
                                   in.options.interpolate_missing);
    DynamicObject object =
        MakeMovingObject(in, seg, track, e->sequence.id, e->instance, plane,
                         *scene, summary, &applied.frames_shown);
    applied.num_points = static_cast<int64_t>(seg.indices.size());
    summary->object_points += applied.num_points;
    scene->objects.push_back(std::move(object));
    summary->edits.push_back(applied);
  }
}

// RenderWithDynamicEdits for EditMode::k3d, after the checks.
DynamicEditResult Render3d(const PointCloud& cloud_in_world,
                           const std::vector<PinholeCamera>& cameras,
                           const std::vector<Rigid3d>& cam_from_world,
                           const BoxSequences& boxes,
                           const std::vector<ObjectEdit>& edits,
                           const DynamicEditOptions& options,
                           const RenderOptions& render_options) {
  DynamicEditResult result;
  RenderOptions ro = render_options;
  ro.num_threads = options.num_threads > 0 ? options.num_threads
                                           : (render_options.num_threads > 0
                                                  ? render_options.num_threads
                                                  : omp_get_max_threads());
  ro.max_footprint_magnification =
      std::min(ro.max_footprint_magnification, options.max_magnification);
  DynamicEditOptions build_options = options;
  build_options.num_threads = ro.num_threads;
  DynamicScene scene =
      BuildDynamicScene(cloud_in_world, cameras, cam_from_world, boxes, edits,
                        build_options, &result.summary);
  for (const DynamicObject& o : scene.objects)
    result.render_ids.push_back(o.id);
  const std::vector<size_t> hidden = std::move(scene.hidden);
  // One depth test per frame over the background and that frame's moved
  // objects, so objects and background occlude each other correctly. Each
  // object is packed once in its own frame and only projected per frame; its
  // footprints make it a footprint splat where it is magnified.
  RenderResult rendered;
  // Background pixels get instance -1: the input cloud's own instance ids
  // (if any) are dropped when the instance map is asked for.
  PointCloud without_ids;
  const PointCloud* background = &cloud_in_world;
  if (ro.output_instance && cloud_in_world.HasInstanceIds()) {
    without_ids.positions = cloud_in_world.positions;
    without_ids.colors = cloud_in_world.colors;
    background = &without_ids;
  }
  RenderFramesWithMovingSets(*background, MovingSets(std::move(scene)), cameras,
                             cam_from_world, ro, &rendered, hidden);
  result.frames = std::move(rendered.frames);
  return result;
}

}  // namespace

PointCloud DynamicScene::ComposeFrame(const PointCloud& cloud_in_world,
                                      int frame) const {
  PointCloud out;
  const bool colors = cloud_in_world.HasColors();
  size_t h = 0;
  for (size_t i = 0; i < cloud_in_world.size(); ++i) {
    if (h < hidden.size() && hidden[h] == i) {
      ++h;
      continue;
    }
    out.positions.push_back(cloud_in_world.positions[i]);
    if (colors) out.colors.push_back(cloud_in_world.colors[i]);
    out.footprints.push_back(
        cloud_in_world.HasFootprints() ? cloud_in_world.footprints[i] : 0.0f);
    const bool axes = !cloud_in_world.footprint_u.empty();
    out.footprint_u.push_back(axes ? cloud_in_world.footprint_u[i]
                                   : Eigen::Vector3f::Zero());
    out.footprint_v.push_back(axes ? cloud_in_world.footprint_v[i]
                                   : Eigen::Vector3f::Zero());
  }
  out.instance_ids.assign(out.size(), -1);
  AppendObjects(*this, frame, &out);
  return out;
}

DynamicScene BuildDynamicScene(const PointCloud& cloud_in_world,
                               const std::vector<PinholeCamera>& cameras,
                               const std::vector<Rigid3d>& cam_from_world,
                               const BoxSequences& boxes,
                               const std::vector<ObjectEdit>& edits,
                               const DynamicEditOptions& options,
                               DynamicEditSummary* summary) {
  options.Check();
  CheckClip(cameras, cam_from_world, boxes);
  cloud_in_world.Check("dynamic edit: point cloud");
  const EditPlan plan = PlanEdits(boxes, edits);
  const int num_frames = static_cast<int>(cam_from_world.size());
  summary->mode = EditMode::k3d;
  summary->num_frames = num_frames;
  const PinholeCamera& camera0 = CameraOf(cameras, 0);
  const Rigid3d& pose0 = cam_from_world[0];

  DynamicScene scene;
  scene.num_frames = num_frames;
  const SceneInputs in{cloud_in_world, cameras, cam_from_world, boxes, options};

  // Frame-0 tracks of the instances.
  std::vector<Track> tracks;
  for (const BoxSequence& s : boxes.instances)
    tracks.push_back(BuildTrack(s, num_frames, options.interpolate_missing));

  // Ground plane: given, or RANSAC over points outside every frame-0 box.
  const bool need_2d_seg =
      std::any_of(tracks.begin(), tracks.end(),
                  [](const Track& t) { return !t.box_3d[0] && t.box_2d[0]; });
  Frame0Projection proj;
  if (need_2d_seg) proj = ProjectFrame0(cloud_in_world, camera0, pose0);
  const bool need_plane = NeedsGroundPlane(need_2d_seg, boxes, edits);
  std::optional<Eigen::Vector4d> plane = options.ground_plane;
  if (!plane && need_plane) {
    plane = FindGroundPlane(cloud_in_world, camera0, pose0, boxes, tracks, proj,
                            need_2d_seg, options, summary);
  }
  summary->ground_plane = plane;

  // Segment every instance in frame 0; the background is everything not
  // segmented.
  Segmentation segmentation =
      SegmentInstances(cloud_in_world, camera0, pose0, boxes, tracks, proj,
                       plane, need_plane, options, summary);
  scene.hidden = std::move(segmentation.hidden);

  AddInstanceObjects(in, plan, tracks, segmentation, plane, &scene, summary);
  AddInsertedObjects(in, plan, segmentation, plane, &scene, summary);
  summary->num_objects = static_cast<int>(scene.objects.size());
  return scene;
}

DynamicEditResult RenderWithDynamicEdits(
    const PointCloud& cloud_in_world,
    const std::vector<PinholeCamera>& cameras,
    const std::vector<Rigid3d>& cam_from_world,
    const BoxSequences& boxes,
    const std::vector<ObjectEdit>& edits,
    const DynamicEditOptions& options,
    const RenderOptions& render_options) {
  const auto start = std::chrono::steady_clock::now();
  options.Check();
  render_options.Check();
  CheckClip(cameras, cam_from_world, boxes);
  GEODRIVE_CHECK_INPUT(!cloud_in_world.empty(),
                       "dynamic edit: the point cloud is empty");
  DynamicEditResult result;
  if (options.mode == EditMode::k2d) {
    cloud_in_world.Check("dynamic edit: point cloud");
    result = Render2d(cloud_in_world, cameras, cam_from_world, boxes, edits,
                      options, render_options);
  } else {
    result = Render3d(cloud_in_world, cameras, cam_from_world, boxes, edits,
                      options, render_options);
  }
  result.summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  RenderSummary& rs = result.render_summary;
  rs.num_frames = static_cast<int>(result.frames.size());
  rs.num_points = static_cast<int64_t>(cloud_in_world.size());
  rs.min_coverage = 1.0;
  double sum = 0;
  for (size_t f = 0; f < result.frames.size(); ++f) {
    const double c = result.frames[f].coverage();
    sum += c;
    rs.min_coverage = std::min(rs.min_coverage, c);
    rs.max_coverage = std::max(rs.max_coverage, c);
    if (result.frames[f].num_valid == 0)
      rs.empty_frames.push_back(static_cast<int>(f));
  }
  rs.mean_coverage = result.frames.empty() ? 0 : sum / result.frames.size();
  rs.seconds = result.summary.seconds;
  return result;
}

}  // namespace geodrive

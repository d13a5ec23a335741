#pragma once
// Internal to geodrive_render (not installed; include only from render/*.cc):
// what the dynamic-edit translation units share. dynamic_edit.cc holds the
// options, summaries, box tracks and edit validation; dynamic_edit_ground.cc
// the ground plane and the lifting of 2D boxes; dynamic_edit_segment.cc the
// frame-0 segmentation (points of boxes); dynamic_edit_2d.cc the upstream 2D
// crop-and-paste mode; dynamic_edit_3d.cc the 3D scene and rendering;
// dynamic_edit_cli.cc the CLI edit arguments.

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <map>
#include <opencv2/core.hpp>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/point_cloud.h"
#include "geometry/rigid3.h"
#include "render/boxes.h"
#include "render/dynamic_edit.h"
#include "render/renderer.h"

namespace geodrive {
namespace dynamic_edit_internal {

// ---- Clip, tracks and edits (dynamic_edit.cc).

inline const PinholeCamera& CameraOf(const std::vector<PinholeCamera>& cameras,
                                     int frame) {
  return cameras.size() == 1 ? cameras[0] : cameras[frame];
}

// Per-frame boxes of one instance after gap interpolation (boxes in the file's
// coordinates).
struct Track {
  std::vector<std::optional<Box2d>> box_2d;
  std::vector<std::optional<Box3d>> box_3d;
  std::vector<int> interpolated;  // frames filled by interpolation
};

Track BuildTrack(const BoxSequence& seq, int num_frames, bool interpolate);

// Pixel box of frame f in an image of width x height seen by `camera` (already
// at that size): the file's 2D box scaled, or the projected 3D box. `shift` is
// added to projected coordinates
// (-0.5 when the image uses kPixelCenter).
std::optional<Box2d> PixelBox(const Track& track,
                              int f,
                              const BoxSequences& boxes,
                              const PinholeCamera& camera,
                              const Rigid3d& cam_from_world,
                              double shift = 0.0);

// Integer pixel window of a box, as upstream: [floor(xmin), floor(xmax)) x
// [floor(ymin), floor(ymax)) clamped to the image.
cv::Rect PixelWindow(const Box2d& b, int width, int height);

inline bool InWindow(const cv::Rect& w, int u, int v) {
  return u >= w.x && u < w.x + w.width && v >= w.y && v < w.y + w.height;
}

void AddNote(DynamicEditSummary* summary,
             const std::string& instance,
             int frame,
             const std::string& message);

// "1,2,5".
std::string FrameList(const std::vector<int>& frames);

// Validates edits against the instances; returns per-instance edit kinds.
struct EditPlan {
  std::set<std::string> removed;
  std::map<std::string, const BoxSequence*> moved;
  std::vector<const ObjectEdit*> inserts;
};

EditPlan PlanEdits(const BoxSequences& boxes,
                   const std::vector<ObjectEdit>& edits);

// Throws InputError unless the cameras, poses and boxes describe one clip.
void CheckClip(const std::vector<PinholeCamera>& cameras,
               const std::vector<Rigid3d>& cam_from_world,
               const BoxSequences& boxes);

// Keeps only positions, colours and instance ids (all -1).
PointCloud StripForRender(const PointCloud& cloud,
                          const std::vector<size_t>& keep);

// ---- Frame-0 segmentation (dynamic_edit_segment.cc).

// Frame-0 pixel (rounded) and depth of every point, in camera 0 at its own
// size.
struct Frame0Projection {
  std::vector<int> u, v;  // -1 when not in front / outside
  std::vector<float> z;
};

Frame0Projection ProjectFrame0(const PointCloud& cloud,
                               const PinholeCamera& camera,
                               const Rigid3d& cam_from_world);

// Fast point-in-box test in float (the box grown by `margin`).
struct FastBox {
  Eigen::Matrix3f box_from_world;
  Eigen::Vector3f center, half;
  Eigen::Vector3f extent;  // half-size of the world-axis-aligned bounding box
  float bottom;            // box-frame z of the bottom face (no margin)
  float radius2;
  FastBox(const Box3d& box, double margin) {
    box_from_world =
        box.rotation.normalized().conjugate().toRotationMatrix().cast<float>();
    center = box.center.cast<float>();
    half = (box.HalfExtents().array() + margin).matrix().cast<float>();
    radius2 = half.squaredNorm() * 1.0001f + 1e-6f;
    bottom = static_cast<float>(-0.5 * box.size[2]);
    // Row i of world_from_box is column i of box_from_world; padded for the
    // float rounding of Contains().
    extent = (box_from_world.transpose().cwiseAbs() * half).array() * 1.0001f +
             1e-5f;
  }
  bool Contains(const Eigen::Vector3f& p) const {
    const Eigen::Vector3f d = p - center;
    if (d.squaredNorm() > radius2) return false;
    const Eigen::Vector3f q = box_from_world * d;
    return std::abs(q.x()) <= half.x() && std::abs(q.y()) <= half.y() &&
           std::abs(q.z()) <= half.z();
  }
  // Height of a point above the box's bottom face (box z is up).
  float HeightAboveBottom(const Eigen::Vector3f& p) const {
    return (box_from_world.row(2).dot(p - center)) - bottom;
  }
};

// ---- Ground plane and lifting (dynamic_edit_ground.cc).

// Signed distance of a point to the plane (n, d).
inline double PlaneDistance(const Eigen::Vector4d& plane,
                            const Eigen::Vector3d& p) {
  return plane.head<3>().dot(p) + plane[3];
}

// Reference of a lifted object in frame 0: its 2D box (native camera-0 pixels),
// ground point of the box's bottom centre, and depth.
struct LiftReference {
  Box2d box0;
  std::optional<Eigen::Vector3d> ground0;
  double depth0 = 0;  // median camera-0 z of the object's points
};

// Whether the 3D edit needs a ground plane: for 2D-box segmentation
// (`need_2d_seg`) or to lift frames that have a 2D box and no 3D box.
bool NeedsGroundPlane(bool need_2d_seg,
                      const BoxSequences& boxes,
                      const std::vector<ObjectEdit>& edits);

// RANSAC ground plane over a subsample of the points outside every frame-0
// box (3D boxes, and with `need_2d_seg` the 2D boxes' windows in `proj`).
// Sets summary->ground_plane_estimated; without a plane adds a note.
std::optional<Eigen::Vector4d> FindGroundPlane(
    const PointCloud& cloud_in_world,
    const PinholeCamera& camera0,
    const Rigid3d& pose0,
    const BoxSequences& boxes,
    const std::vector<Track>& tracks,
    const Frame0Projection& proj,
    bool need_2d_seg,
    const DynamicEditOptions& options,
    DynamicEditSummary* summary);

// Intersection of the ray through `pixel` (kIntegerIndex, camera at its own
// size) with the plane, in front of the camera.
std::optional<Eigen::Vector3d> GroundHit(const PinholeCamera& camera,
                                         const Rigid3d& cam_from_world,
                                         const Eigen::Vector2d& pixel,
                                         const Eigen::Vector4d& plane);

// Translation that moves the object from frame 0 to the pixel box `box_f` of
// frame f, or nullopt.
std::optional<Eigen::Vector3d> LiftTranslation(
    const LiftReference& ref,
    const Box2d& box_f,
    const PinholeCamera& camera_f,
    const Rigid3d& cam_from_world_f,
    const PinholeCamera& camera0,
    const Rigid3d& cam_from_world0,
    const std::optional<Eigen::Vector4d>& plane);

// ---- Segmentation result (dynamic_edit_segment.cc).

// Segmented source object (3D mode).
struct Segment {
  std::vector<size_t> indices;
  std::optional<Box3d> box0;  // frame-0 3D box when the segmentation used it
  LiftReference lift;
};

struct Segmentation {
  // Per instance of the boxes file; nullopt: left static (with a note).
  std::vector<std::optional<Segment>> segments;
  // Every segmented point (the objects' source points), ascending.
  std::vector<size_t> hidden;
};

// Segments every instance in frame 0: the points inside its frame-0 3D box,
// or inside its 2D box (above the ground, in the dynamic mask, the dominant
// depth cluster), each point given to the first instance that takes it; sets
// the lift references (for frames with only a 2D box, `need_plane`).
Segmentation SegmentInstances(const PointCloud& cloud_in_world,
                              const PinholeCamera& camera0,
                              const Rigid3d& pose0,
                              const BoxSequences& boxes,
                              const std::vector<Track>& tracks,
                              const Frame0Projection& proj,
                              const std::optional<Eigen::Vector4d>& plane,
                              bool need_plane,
                              const DynamicEditOptions& options,
                              DynamicEditSummary* summary);

// ---- 2D mode (dynamic_edit_2d.cc).

// RenderWithDynamicEdits for EditMode::k2d, after the checks.
DynamicEditResult Render2d(const PointCloud& cloud_in_world,
                           const std::vector<PinholeCamera>& cameras,
                           const std::vector<Rigid3d>& cam_from_world,
                           const BoxSequences& boxes,
                           const std::vector<ObjectEdit>& edits,
                           const DynamicEditOptions& options,
                           RenderOptions render_options);

}  // namespace dynamic_edit_internal
}  // namespace geodrive

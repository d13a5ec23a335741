#pragma once
// Surround view: one condition scene for every camera of a clip's rig
// (DriveClip::rig), built once per clip and rendered into each camera.
//
// The scene frame is the reference camera (the rig's first) at frame 0. Each
// view's scene is built by the run's scene source from that camera's clip
// (DriveClip::View), moved into the scene frame through the world poses, and
// the views are fused under one ownership rule:
//
//   a point p built by view k is dropped when another view j sees p more
//   frontally (cos of the angle between j's optical axis and the ray to p,
//   at frame 0, is larger than k's) and j has that surface itself: p
//   projects inside j's frame-0 image into a 4x4-pixel cell whose nearest
//   point of j is within 5 % of p's depth in j.
//
// So a surface that two cameras see is kept once, with the points and colours
// of the camera that sees it most frontally; a surface only one camera has
// (another camera's view of it is occluded, or has no depth there) keeps that
// camera's points.
//
// Footprints: each view's points get their capture footprints from that
// view's frame-0 camera (render/footprint.h) before the fusion, so the
// footprint preset draws every point over the pixel that captured it,
// whichever camera renders it.
//
// Poses: view k's camera at frame i is scene_from_cam[k][i] = scene_from_world
// * world_from_cam of that camera's own frame (its own timestamp and ego pose).
// An edited reference trajectory moves the whole rig rigidly (RigFollowEdit).

#include <optional>
#include <string>
#include <vector>

#include "dataset/drive_clip.h"
#include "dataset/scene_source.h"
#include "geometry/camera.h"
#include "geometry/point_cloud.h"
#include "geometry/rigid3.h"

namespace geodrive {

// One camera of a rig scene.
struct RigView {
  // Camera channel, e.g. "CAM_BACK".
  std::string channel;
  // Frame-0 camera on the view source's pixel grid (ConditionScene::camera).
  PinholeCamera camera;
  // Per frame: the camera's pose in the scene frame.
  std::vector<Rigid3d> scene_from_cam;
  // The view's scene as its source built it (cloud moved out: `cloud` of
  // the RigScene holds the fused points); its completion report, frame-0
  // image and dynamic mask.
  ConditionScene source;
  // Points the view's source built, and how many the fusion kept.
  int64_t points_built = 0;
  int64_t points_kept = 0;
};

struct RigScene {
  // The fused cloud in the scene frame (the reference camera at frame 0).
  PointCloud cloud;
  std::vector<RigView> views;
  // The scene frame in the dataset's world.
  Rigid3d world_from_scene;
  // Units and scale of the views (every view metric, or the rig is refused).
  std::string units = "metres";
  // One line: points per view built and kept.
  std::string BriefReport() const;
  bool metric() const { return units == "metres"; }
};

// Fuses per-view scenes (view k built from clip.View(k), in its frame-0 camera
// frame) into one rig scene under the ownership rule above. Throws InputError
// when a view is not metric or its trajectory does not match its frames.
RigScene FuseRigScenes(const DriveClip& clip,
                       std::vector<ConditionScene> views);

// Indices of the points a z-buffer render of `camera` at the poses can draw:
// in some pose near < z < far and the projection within `margin_px` of the
// image (margin_px at least the largest splat half-extent: radius_px, or
// max_footprint_magnification / 2 for footprint splats). Drawing only these
// gives the same frames as drawing the whole cloud; a camera renders its
// view of the shared cloud from this subset.
std::vector<size_t> PointsInViewOfAny(
    const PointCloud& cloud,
    const PinholeCamera& camera,
    const std::vector<Rigid3d>& scene_from_cam,
    double near,
    double far,
    double margin_px);

// Bounding box of the points [begin, end) of `cloud` (begin < end); false when
// a coordinate is not finite (lo and hi are then not a box). The rig tests
// groups of consecutive points by it before their points one by one.
bool PointGroupBounds(const PointCloud& cloud,
                      size_t begin,
                      size_t end,
                      Eigen::Vector3f* lo,
                      Eigen::Vector3f* hi);

// The rig's poses along an edited reference trajectory: per frame the world
// side motion D(i) = edited_reference[i] * inverse(reference[i]) of the
// reference camera is applied to every camera, scene_from_cam'[k][i] = D(i) *
// scene_from_cam[k][i] (a shifted or rotated ego moves the rig rigidly).
// Returns [view][frame]; edited_reference has one pose per frame.
std::vector<std::vector<Rigid3d>> RigFollowEdit(
    const RigScene& scene, const std::vector<Rigid3d>& edited_reference);

// Cross-view depth agreement of two overlapping cameras at frame 0: a pixel
// of one camera with a rendered depth whose 3D point falls inside the other
// camera's image on a pixel with a rendered depth is an overlap pixel (both
// directions counted); it agrees when the other camera's rendered depth is
// within 1 % of the point's depth there.
struct SeamAgreement {
  std::string camera_a, camera_b;
  int64_t overlap_pixels = 0;
  int64_t agreeing_pixels = 0;
  double fraction() const {
    return overlap_pixels > 0
               ? static_cast<double>(agreeing_pixels) / overlap_pixels
               : 0.0;
  }
};
// Agreement of every pair of views with overlap pixels. `depth[k]` is view
// k's rendered frame-0 depth (CV_32F, metres, 0 = none) for `cameras[k]` at
// pose `scene_from_cam[k]`.
std::vector<SeamAgreement> RigSeamAgreement(
    const std::vector<std::string>& channels,
    const std::vector<PinholeCamera>& cameras,
    const std::vector<Rigid3d>& scene_from_cam,
    const std::vector<cv::Mat>& depth);

}  // namespace geodrive

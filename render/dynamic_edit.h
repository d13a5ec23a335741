#pragma once
// Dynamic editing of the conditioning render: vehicles follow box sequences,
// and can be removed, inserted (a copy along a new box sequence) or given a new
// trajectory.
//
// Two modes:
//  - k2d (upstream GeoDrive `prepare_data_edit.py`, compatible with the
//  released model's training
//    data): delete the cloud points whose frame-0 projection falls inside an
//    instance's frame-0 box (upstream sets them to XYZ = 0, which leaves a
//    stray splat; we delete them), render the static scene, then paste the
//    frame-0 crop of each instance into its box in every frame: crop = frame-0
//    image[floor(ymin):floor(ymax), floor(xmin):floor(xmax)] clamped to the
//    image; bilinear resize (cv::INTER_LINEAR) to the frame-t box size
//    (trunc(xmax) - trunc(xmin), ..., unclamped), cut to the image, alpha-blend
//    with ones(h, w) convolved with the 5x5 binomial kernel [1 4 6 4 1]^T [1 4
//    6 4 1] / 256 with zero padding (edge 0.6875, second row 0.9375, corner
//    0.4727), the alpha made for the part inside the image. Instances in file
//    order, later ones on top. No depth order.
//  - k3d (ours): segment each instance's points in frame 0 (inside its 3D box
//  when given; otherwise
//    inside its 2D box, minus road points near the ground plane, restricted to
//    the dynamic mask when one is given, and reduced to the dominant depth
//    cluster), move them rigidly frame by frame (x_t = world_from_box_t *
//    box_from_world_0 * x_0; without 3D boxes, translated by the motion of the
//    2D box's bottom-centre lifted onto the ground plane) and render objects
//    and background in one z-buffer pass per frame: mutual occlusion,
//    perspective and scale follow from geometry.
//
// Bad input: boxes that leave the image are clipped; frames whose box is
// zero-area or entirely outside the image are skipped; frames missing inside an
// instance's annotated range are interpolated (option), outside it the object
// is hidden; an instance without a frame-0 box or with fewer than
// `min_object_points` segmented points is left static with a note; an edit
// naming an unknown instance, or boxes whose frame count differs from the clip,
// is rejected with InputError. Every skip is listed in
// DynamicEditSummary::notes.
//
// The CLI glue (--boxes, --edit-mode, --remove, --insert, --move) is in
// render/dynamic_edit_cli.h.

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/point_cloud.h"
#include "geometry/rigid3.h"
#include "render/boxes.h"
#include "render/renderer.h"

namespace geodrive {

enum class EditMode { k2d, k3d };
std::string ToString(EditMode mode);  // "2d" / "3d"
// Parses "2d" or "3d"; throws InputError otherwise.
EditMode ParseEditMode(const std::string& text);

enum class ObjectEditKind { kRemove, kInsert, kMove };
std::string ToString(ObjectEditKind kind);  // "remove" / "insert" / "move"

// One user edit.
struct ObjectEdit {
  ObjectEditKind kind = ObjectEditKind::kRemove;
  // The instance removed, moved, or copied (insert).
  std::string instance;
  // kInsert: the copy's box sequence (its `id` names the copy and must be new).
  // kMove: the instance's new box sequence (its `id` is ignored).
  BoxSequence sequence;
};

struct DynamicEditOptions {
  EditMode mode = EditMode::k3d;
  // Frames missing between two annotated frames of an instance get interpolated
  // boxes (3D: lerp + slerp; 2D: lerp). Otherwise the object is hidden (3D) /
  // not pasted (2D) there.
  bool interpolate_missing = true;
  // Frames whose 2D box, scaled to the image and clipped, has less than this
  // area (pixels) are skipped with a note.
  double min_box_area_px = 1.0;

  // ---- 2D mode.
  // The image the frame-0 crops come from (RGB CV_8UC3, any size; resized
  // bilinearly to the render size). Upstream uses the real frame 0. Empty: the
  // unedited frame-0 render.
  cv::Mat frame0_image;

  // ---- 3D mode (lengths in the units of the cloud).
  // 3D boxes are grown by this on every side when selecting points.
  double box_margin = 0.05;
  // Points closer than this to the ground plane (or below it) are road, never
  // object. Instances segmented by a 3D box use the box's bottom face as the
  // ground when no plane is given or needed.
  double ground_margin = 0.15;
  // World ground plane n . x + d = 0 as (n, d), n a unit normal pointing up
  // (towards the camera). When not given, estimated by RANSAC from the cloud
  // (subsampled, seeded) if something needs it: an instance with only a 2D box
  // in frame 0, or a frame with a 2D box and no 3D box (lifting).
  std::optional<Eigen::Vector4d> ground_plane;
  // RANSAC: candidate normals within this angle of camera 0's up axis (-y);
  // inlier distance is `ground_margin`.
  double ground_max_tilt_deg = 25.0;
  // At most this many hypotheses; fewer once an all-inlier sample has been
  // drawn with probability `ground_ransac_confidence` (adaptive stop).
  int ground_ransac_iterations = 200;
  double ground_ransac_confidence = 0.999;
  int ground_ransac_samples =
      4000;  // points scored per hypothesis (deterministic subsample)
  // Optional frame-0 dynamic mask (CV_8U, nonzero = dynamic; any size, sampled
  // at the scaled pixel). Used only for instances without a 3D box, and ignored
  // (with a note) when it would leave fewer than `min_object_points`.
  cv::Mat dynamic_mask;
  // Depth clustering of 2D-box candidates (frame-0 camera z): sorted depths are
  // split where consecutive values differ by more than depth_gap_abs +
  // depth_gap_rel * depth; the cluster with the most points is the object.
  double depth_gap_abs = 0.3;
  double depth_gap_rel = 0.03;
  // Instances with fewer segmented points are left static (with a note).
  int min_object_points = 10;
  // Close range: an object drawn larger than in frame 0 (approached, scaled up,
  // or rendered at a higher resolution than camera 0) would show gaps through
  // which the background bleeds. Its points carry their frame-0 pixel
  // footprints and are drawn as footprint splats (render/footprint.h, the
  // renderer's one mechanism), capped at the render's
  // max_footprint_magnification (3 by default, 8 in the footprint preset)
  // and at this value: 1 = off (one pixel per point), in [1, 16].
  double max_magnification = 16.0;
  // Threads for the per-frame renders (0 = OpenMP default); the output does not
  // depend on it.
  int num_threads = 0;

  // Throws InputError on invalid values.
  void Check() const;
};

// An applied edit (including the implicit "animate": an instance following its
// own boxes).
struct AppliedEdit {
  std::string kind;      // "animate", "remove", "insert", "move"
  std::string instance;  // the instance (for insert: the new copy)
  std::string source;    // insert: the instance copied; otherwise empty
  int64_t num_points =
      0;  // 3D mode: object points moved / removed / inserted (2D: 0)
  int frames_shown = 0;  // frames where the object is drawn (2D: pasted)
};

struct EditNote {
  std::string instance;
  int frame = -1;  // -1 = the whole instance
  std::string message;
};

struct DynamicEditSummary {
  EditMode mode = EditMode::k3d;
  int num_frames = 0;
  int num_objects =
      0;  // objects drawn (3D: moved point sets; 2D: pasted instances)
  int64_t object_points = 0;   // 3D: points in moving objects
  int64_t removed_points = 0;  // points deleted from the static cloud
  std::optional<Eigen::Vector4d> ground_plane;  // used (3D mode), (n, d)
  bool ground_plane_estimated = false;
  std::vector<AppliedEdit> edits;
  std::vector<EditNote> notes;
  double seconds = 0;

  std::string BriefReport() const;
  // A JSON object {"mode", "edits": [...], "notes": [...], ...} for
  // render.json.
  std::string ToJson() const;
};

// Pose of an object in one frame: x_in_world = world_from_object * (scale .*
// x_in_object).
struct ObjectPose {
  Rigid3d world_from_object;
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
};

// A rigid object of the 3D edit.
struct DynamicObject {
  std::string id;         // instance id (for an inserted copy: the new id)
  std::string source_id;  // the instance whose points these are
  int32_t render_id =
      0;  // written to instance_ids / the per-pixel instance image
  // Colours and positions in the object frame; footprints (frame-0 pixel
  // footprints, render/footprint.h) unless max_magnification is 1.
  PointCloud points_in_object;
  std::vector<std::optional<ObjectPose>>
      poses;  // per frame; nullopt = not drawn
};

// The 3D edit before rendering: the input cloud less the segmented objects'
// points is the static background; objects have per-frame poses.
struct DynamicScene {
  int num_frames = 0;
  // Input-cloud points that are not background (every segmented object's
  // points: moved, removed or copied), ascending.
  std::vector<size_t> hidden;
  std::vector<DynamicObject> objects;

  size_t NumBackgroundPoints(const PointCloud& cloud_in_world) const {
    return cloud_in_world.size() - hidden.size();
  }
  // The background (positions and colours of the input cloud's points not in
  // `hidden`, instance id -1) followed by every object drawn in `frame`
  // mapped to the world (instance_ids = render_id): the cloud the frame shows.
  PointCloud ComposeFrame(const PointCloud& cloud_in_world, int frame) const;
};

// Builds the 3D edit: segmentation, poses, removals and insertions. `cameras`
// holds one camera for all frames or one per pose (frame 0's is used for
// segmentation); `boxes.num_frames` must equal cam_from_world.size(). Notes and
// applied edits go to `summary` (required). The objects' points carry their
// frame-0 footprints; the renderer computes each frame's magnification.
DynamicScene BuildDynamicScene(const PointCloud& cloud_in_world,
                               const std::vector<PinholeCamera>& cameras,
                               const std::vector<Rigid3d>& cam_from_world,
                               const BoxSequences& boxes,
                               const std::vector<ObjectEdit>& edits,
                               const DynamicEditOptions& options,
                               DynamicEditSummary* summary);

// ---- 2D building blocks (upstream-compatible).

// The 5x5 binomial-feathered alpha of a width x height paste (CV_32F): ones
// convolved with [1 4 6 4 1]^T [1 4 6 4 1] / 256, zero padding.
cv::Mat FeatherAlpha(int width, int height);
// Pastes the crop `source_box` of `source` (RGB CV_8UC3) into `target_box` of
// `*target` (RGB CV_8UC3) as upstream does (see the file comment); both boxes
// in the pixel coordinates of their images. Where alpha >= 0.5, `*instance`
// (CV_32S, optional) is set to `id`. Returns false (and changes nothing) when
// the source crop or the visible target region is empty.
bool PasteFeathered(const cv::Mat& source,
                    const Box2d& source_box,
                    const Box2d& target_box,
                    cv::Mat* target,
                    cv::Mat* instance = nullptr,
                    int32_t id = 0);

// ---- Render with edits.

struct DynamicEditResult {
  // Per frame. With RenderOptions::output_instance, `instance` holds the render
  // id per pixel (3D: the front-most point's object; 2D: the pasted instance
  // where alpha >= 0.5), -1 elsewhere; without it `instance` is empty.
  std::vector<RenderedFrame> frames;
  std::vector<std::string> render_ids;  // render id -> instance id
  DynamicEditSummary summary;
  RenderSummary render_summary;  // coverage of the edited frames
  // The frames and render_summary as a RenderResult (e.g. for FinalFrames).
  RenderResult ToRenderResult() &&;
};

// Renders the clip with the edits applied (mode from `options`). Set
// `render_options.output_instance` for the per-pixel object ids. Throws
// InputError on bad input (see the file comment).
DynamicEditResult RenderWithDynamicEdits(
    const PointCloud& cloud_in_world,
    const std::vector<PinholeCamera>& cameras,
    const std::vector<Rigid3d>& cam_from_world,
    const BoxSequences& boxes,
    const std::vector<ObjectEdit>& edits,
    const DynamicEditOptions& options,
    const RenderOptions& render_options);

}  // namespace geodrive

#include "render/dynamic_edit.h"

#include <omp.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <exception>
#include <functional>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <set>
#include <sstream>

#include "geometry/util/status.h"

namespace geodrive {
namespace {

using json = nlohmann::json;

const PinholeCamera& CameraOf(const std::vector<PinholeCamera>& cameras,
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

Track BuildTrack(const BoxSequence& seq, int num_frames, bool interpolate) {
  Track track;
  track.box_2d.resize(num_frames);
  track.box_3d.resize(num_frames);
  for (const BoxFrame& f : seq.frames) {
    if (f.frame < 0 || f.frame >= num_frames) continue;
    track.box_2d[f.frame] = f.box_2d;
    track.box_3d[f.frame] = f.box_3d;
  }
  if (!interpolate) return track;
  for (size_t k = 0; k + 1 < seq.frames.size(); ++k) {
    const BoxFrame& a = seq.frames[k];
    const BoxFrame& b = seq.frames[k + 1];
    if (b.frame - a.frame < 2 || b.frame > num_frames) continue;
    for (int f = a.frame + 1; f < b.frame; ++f) {
      const double t = double(f - a.frame) / (b.frame - a.frame);
      bool any = false;
      if (a.box_3d && b.box_3d) {
        track.box_3d[f] = Interpolate(*a.box_3d, *b.box_3d, t);
        any = true;
      }
      if (a.box_2d && b.box_2d) {
        track.box_2d[f] = Interpolate(*a.box_2d, *b.box_2d, t);
        any = true;
      }
      if (any) track.interpolated.push_back(f);
    }
  }
  return track;
}

// Pixel box of frame f in an image of width x height seen by `camera` (already
// at that size): the file's 2D box scaled, or the projected 3D box. `shift` is
// added to projected coordinates
// (-0.5 when the image uses kPixelCenter).
std::optional<Box2d> PixelBox(const Track& track,
                              int f,
                              const BoxSequences& boxes,
                              const PinholeCamera& camera,
                              const Rigid3d& cam_from_world,
                              double shift = 0.0) {
  if (track.box_2d[f]) {
    return track.box_2d[f]->Scaled(double(camera.width) / boxes.image_width,
                                   double(camera.height) / boxes.image_height);
  }
  if (track.box_3d[f]) {
    std::optional<Box2d> b =
        ProjectBox3d(*track.box_3d[f], camera, cam_from_world);
    if (b) {
      b->xmin += shift;
      b->xmax += shift;
      b->ymin += shift;
      b->ymax += shift;
    }
    return b;
  }
  return std::nullopt;
}

// Integer pixel window of a box, as upstream: [floor(xmin), floor(xmax)) x
// [floor(ymin), floor(ymax)) clamped to the image.
cv::Rect PixelWindow(const Box2d& b, int width, int height) {
  const int x0 = std::clamp(static_cast<int>(std::floor(b.xmin)), 0, width);
  const int y0 = std::clamp(static_cast<int>(std::floor(b.ymin)), 0, height);
  const int x1 = std::clamp(static_cast<int>(std::floor(b.xmax)), 0, width);
  const int y1 = std::clamp(static_cast<int>(std::floor(b.ymax)), 0, height);
  return cv::Rect(x0, y0, std::max(0, x1 - x0), std::max(0, y1 - y0));
}

// 1 if the sign bit of v is set (v < 0 or -0), else 0; branch-free.
inline uint64_t SignBit(double v) {
  uint64_t u;
  std::memcpy(&u, &v, sizeof u);
  return u >> 63;
}
inline uint32_t SignBit(float v) {
  uint32_t u;
  std::memcpy(&u, &v, sizeof u);
  return u >> 31;
}

// Signed distance of a point to the plane (n, d).
inline double PlaneDistance(const Eigen::Vector4d& plane,
                            const Eigen::Vector3d& p) {
  return plane.head<3>().dot(p) + plane[3];
}

// RANSAC ground plane over `candidates` (indices into positions), normal within
// max_tilt of `up`.
std::optional<Eigen::Vector4d> EstimateGroundPlane(
    const std::vector<Eigen::Vector3f>& positions,
    const std::vector<size_t>& candidates,
    const Eigen::Vector3d& up,
    const DynamicEditOptions& options) {
  if (candidates.size() < 3) return std::nullopt;
  std::vector<Eigen::Vector3d> sample;
  const size_t stride = std::max<size_t>(
      1, candidates.size() / std::max(3, options.ground_ransac_samples));
  for (size_t k = 0; k < candidates.size(); k += stride)
    sample.push_back(positions[candidates[k]].cast<double>());
  // Structure of arrays for the scoring loop (it vectorises).
  const size_t m = sample.size();
  std::vector<double> sx(m), sy(m), sz(m);
  for (size_t k = 0; k < m; ++k) {
    sx[k] = sample[k].x();
    sy[k] = sample[k].y();
    sz[k] = sample[k].z();
  }
  const double cos_tilt = std::cos(options.ground_max_tilt_deg * M_PI / 180.0);
  std::mt19937 rng(12345);
  std::uniform_int_distribution<size_t> pick(0, sample.size() - 1);
  Eigen::Vector4d best_plane = Eigen::Vector4d::Zero();
  uint64_t best_count = 0;
  // Adaptive stop (as in COLMAP's RANSAC): after the best hypothesis so far
  // has inlier ratio w, an all-inlier triple has been drawn with probability
  // >= confidence once 1 - (1 - w^3)^it >= confidence.
  int max_iterations = options.ground_ransac_iterations;
  for (int it = 0; it < max_iterations; ++it) {
    const Eigen::Vector3d& a = sample[pick(rng)];
    const Eigen::Vector3d& b = sample[pick(rng)];
    const Eigen::Vector3d& c = sample[pick(rng)];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-12) continue;
    n.normalize();
    if (n.dot(up) < 0) n = -n;
    if (n.dot(up) < cos_tilt) continue;
    const Eigen::Vector4d plane(n.x(), n.y(), n.z(), -n.dot(a));
    const double nx = n.x(), ny = n.y(), nz = n.z(), d = plane[3];
    const double margin = options.ground_margin;
    // |distance| < margin <=> the sign bit of |distance| - margin (a float
    // compare would keep the loop from vectorising under -ftrapping-math).
    uint64_t count = 0;
    for (size_t k = 0; k < m; ++k)
      count +=
          SignBit(std::abs(nx * sx[k] + ny * sy[k] + nz * sz[k] + d) - margin);
    if (count > best_count) {
      best_count = count;
      best_plane = plane;
      const double w = double(count) / double(m);
      const double miss = 1.0 - w * w * w;
      if (miss <= 0.0) break;
      const double needed = std::ceil(
          std::log(1.0 - options.ground_ransac_confidence) / std::log(miss));
      if (needed < max_iterations)
        max_iterations = std::max(it + 1, static_cast<int>(needed));
    }
  }
  if (best_count < std::max<size_t>(3, sample.size() / 20)) return std::nullopt;
  // Least-squares refinement on the inliers.
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> inliers;
  for (const Eigen::Vector3d& p : sample) {
    if (std::abs(PlaneDistance(best_plane, p)) < options.ground_margin) {
      inliers.push_back(p);
      mean += p;
    }
  }
  mean /= double(inliers.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : inliers)
    cov += (p - mean) * (p - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(cov);
  Eigen::Vector3d n = solver.eigenvectors().col(0).normalized();
  if (n.dot(up) < 0) n = -n;
  if (n.dot(up) < cos_tilt) n = best_plane.head<3>();
  return Eigen::Vector4d(n.x(), n.y(), n.z(), -n.dot(mean));
}

// Intersection of the ray through `pixel` (kIntegerIndex, camera at its own
// size) with the plane, in front of the camera.
std::optional<Eigen::Vector3d> GroundHit(const PinholeCamera& camera,
                                         const Rigid3d& cam_from_world,
                                         const Eigen::Vector2d& pixel,
                                         const Eigen::Vector4d& plane) {
  const Rigid3d world_from_cam = cam_from_world.Inverse();
  const Eigen::Vector3d dir =
      world_from_cam.rotation *
      camera.Unproject(pixel, 1.0);  // z = 1 in the camera
  const Eigen::Vector3d origin = world_from_cam.translation;
  const double denom = plane.head<3>().dot(dir);
  if (std::abs(denom) < 1e-12) return std::nullopt;
  const double s = -PlaneDistance(plane, origin) / denom;
  if (!(s > 0) || !std::isfinite(s)) return std::nullopt;
  return origin + s * dir;
}

// World point on the ray through `pixel` at camera depth z.
Eigen::Vector3d PointAtDepth(const PinholeCamera& camera,
                             const Rigid3d& cam_from_world,
                             const Eigen::Vector2d& pixel,
                             double z) {
  return cam_from_world.Inverse() * camera.Unproject(pixel, z);
}

// Reference of a lifted object in frame 0: its 2D box (native camera-0 pixels),
// ground point of the box's bottom centre, and depth.
struct LiftReference {
  Box2d box0;
  std::optional<Eigen::Vector3d> ground0;
  double depth0 = 0;  // median camera-0 z of the object's points
};

// Translation that moves the object from frame 0 to the pixel box `box_f` of
// frame f, or nullopt.
std::optional<Eigen::Vector3d> LiftTranslation(
    const LiftReference& ref,
    const Box2d& box_f,
    const PinholeCamera& camera_f,
    const Rigid3d& cam_from_world_f,
    const PinholeCamera& camera0,
    const Rigid3d& cam_from_world0,
    const std::optional<Eigen::Vector4d>& plane) {
  if (plane && ref.ground0) {
    const Eigen::Vector2d bottom(0.5 * (box_f.xmin + box_f.xmax), box_f.ymax);
    const std::optional<Eigen::Vector3d> hit =
        GroundHit(camera_f, cam_from_world_f, bottom, *plane);
    if (hit) return *hit - *ref.ground0;
  }
  // Fallback: depth from the box height (pinhole scale), along the box-centre
  // rays.
  if (box_f.height() <= 0 || ref.box0.height() <= 0 || ref.depth0 <= 0)
    return std::nullopt;
  const double depth_f = ref.depth0 *
                         (ref.box0.height() * camera_f.fy / camera0.fy) /
                         box_f.height();
  const Eigen::Vector2d c0(0.5 * (ref.box0.xmin + ref.box0.xmax),
                           0.5 * (ref.box0.ymin + ref.box0.ymax));
  const Eigen::Vector2d cf(0.5 * (box_f.xmin + box_f.xmax),
                           0.5 * (box_f.ymin + box_f.ymax));
  return PointAtDepth(camera_f, cam_from_world_f, cf, depth_f) -
         PointAtDepth(camera0, cam_from_world0, c0, ref.depth0);
}

// Segmented source object (3D mode).
struct Segment {
  std::vector<size_t> indices;
  std::optional<Box3d> box0;  // frame-0 3D box when the segmentation used it
  LiftReference lift;
};

void AddNote(DynamicEditSummary* summary,
             const std::string& instance,
             int frame,
             const std::string& message) {
  summary->notes.push_back(EditNote{instance, frame, message});
}

std::string FrameList(const std::vector<int>& frames) {
  std::ostringstream os;
  for (size_t i = 0; i < frames.size(); ++i) os << (i ? "," : "") << frames[i];
  return os.str();
}

// Validates edits against the instances; returns per-instance edit kinds.
struct EditPlan {
  std::set<std::string> removed;
  std::map<std::string, const BoxSequence*> moved;
  std::vector<const ObjectEdit*> inserts;
};

EditPlan PlanEdits(const BoxSequences& boxes,
                   const std::vector<ObjectEdit>& edits) {
  EditPlan plan;
  std::set<std::string> ids;
  for (const BoxSequence& s : boxes.instances) ids.insert(s.id);
  for (const ObjectEdit& e : edits) {
    const std::string what = ToString(e.kind) + " '" + e.instance + "'";
    GEODRIVE_CHECK_INPUT(boxes.Find(e.instance) != nullptr, "edit ", what,
                         ": no instance with this id in the boxes file");
    switch (e.kind) {
      case ObjectEditKind::kRemove:
        GEODRIVE_CHECK_INPUT(!plan.moved.count(e.instance) &&
                                 plan.removed.insert(e.instance).second,
                             "edit ", what,
                             ": the instance is already removed or moved");
        break;
      case ObjectEditKind::kMove:
        GEODRIVE_CHECK_INPUT(
            !plan.removed.count(e.instance) && !plan.moved.count(e.instance),
            "edit ", what, ": the instance is already removed or moved");
        plan.moved[e.instance] = &e.sequence;
        break;
      case ObjectEditKind::kInsert:
        GEODRIVE_CHECK_INPUT(
            !e.sequence.id.empty(), "edit ", what,
            ": the inserted copy needs an id (its box sequence's id)");
        GEODRIVE_CHECK_INPUT(ids.insert(e.sequence.id).second, "edit ", what,
                             ": id '", e.sequence.id,
                             "' of the copy is already used");
        plan.inserts.push_back(&e);
        break;
    }
    if (e.kind != ObjectEditKind::kRemove) {
      BoxSequences one;
      one.image_width = boxes.image_width;
      one.image_height = boxes.image_height;
      one.num_frames = boxes.num_frames;
      one.instances.push_back(e.sequence);
      if (one.instances[0].id.empty()) one.instances[0].id = e.instance;
      one.Check("edit " + what);
    }
  }
  return plan;
}

void CheckClip(const std::vector<PinholeCamera>& cameras,
               const std::vector<Rigid3d>& cam_from_world,
               const BoxSequences& boxes) {
  GEODRIVE_CHECK_INPUT(!cam_from_world.empty(),
                       "dynamic edit: no camera poses given");
  GEODRIVE_CHECK_INPUT(
      cameras.size() == 1 || cameras.size() == cam_from_world.size(),
      "dynamic edit: ", cameras.size(), " cameras for ", cam_from_world.size(),
      " poses (need 1 or one per pose)");
  GEODRIVE_CHECK_INPUT(
      boxes.num_frames == static_cast<int>(cam_from_world.size()),
      "dynamic edit: the boxes file has num_frames ", boxes.num_frames,
      " but the clip has ", cam_from_world.size(), " frames");
  for (size_t f = 0; f < cam_from_world.size(); ++f) {
    CheckPose(cam_from_world[f], "dynamic edit: frame " + std::to_string(f));
  }
  for (const PinholeCamera& c : cameras) c.Check("dynamic edit: camera");
  boxes.Check("dynamic edit: boxes");
}

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

// The object's points in its own frame with each point drawn as k x k
// samples over its frame-0 pixel footprint (k = 1: the points themselves).
PointCloud FootprintSamples(const DynamicObject& object, int k) {
  const PointCloud& src = object.points_in_object;
  const size_t n = src.size();
  if (k <= 1 || object.footprint_u.size() != n) return src;
  const size_t kk = static_cast<size_t>(k) * k;
  float offsets[16];
  for (int a = 0; a < k; ++a) offsets[a] = (a + 0.5f) / k - 0.5f;
  PointCloud out;
  out.positions.resize(n * kk);
  if (src.HasColors()) out.colors.resize(n * kk);
  for (size_t i = 0; i < n; ++i) {
    Eigen::Vector3f* o = out.positions.data() + i * kk;
    for (int b = 0; b < k; ++b) {
      const Eigen::Vector3f row =
          src.positions[i] + offsets[b] * object.footprint_v[i];
      for (int a = 0; a < k; ++a)
        *o++ = row + offsets[a] * object.footprint_u[i];
    }
    if (src.HasColors())
      std::fill_n(out.colors.begin() + i * kk, kk, src.colors[i]);
  }
  return out;
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

// The scene's objects as moving point sets (their points are moved out): one
// set per object and footprint sampling k it uses, in object order (so depth
// ties keep object order; an object never shows two k in one frame).
std::vector<MovingPointSet> MovingSets(DynamicScene&& scene) {
  std::vector<MovingPointSet> sets;
  for (DynamicObject& object : scene.objects) {
    std::set<int, std::greater<int>> ks;  // k = 1 last: it takes the points
    for (const std::optional<ObjectPose>& pose : object.poses)
      if (pose) ks.insert(std::max(1, pose->subsamples));
    for (int k : ks) {
      MovingPointSet set;
      set.points = k == 1 ? std::move(object.points_in_object)
                          : FootprintSamples(object, k);
      set.instance_id = object.render_id;
      set.world_from_set.resize(scene.num_frames);
      for (size_t f = 0;
           f < object.poses.size() && f < static_cast<size_t>(scene.num_frames);
           ++f) {
        const std::optional<ObjectPose>& pose = object.poses[f];
        if (pose && std::max(1, pose->subsamples) == k)
          set.world_from_set[f] = AffineOf(*pose);
      }
      sets.push_back(std::move(set));
    }
  }
  return sets;
}

// Sets ObjectPose::subsamples from the object's magnification in each frame.
void SetSubsamples(const std::vector<PinholeCamera>& cameras,
                   const std::vector<Rigid3d>& cam_from_world,
                   const Rigid3d& world_from_object0,
                   int output_width,
                   int max_subsamples,
                   DynamicObject* object) {
  if (object->points_in_object.empty()) return;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3f& p : object->points_in_object.positions)
    centroid += p.cast<double>();
  centroid /= double(object->points_in_object.size());
  const PinholeCamera& camera0 = CameraOf(cameras, 0);
  const double z0 = (cam_from_world[0] * (world_from_object0 * centroid)).z();
  if (!(z0 > 0)) return;
  for (size_t f = 0; f < object->poses.size(); ++f) {
    if (!object->poses[f]) continue;
    ObjectPose& pose = *object->poses[f];
    const Eigen::Vector3d w =
        pose.world_from_object * pose.scale.cwiseProduct(centroid);
    const double zt = (cam_from_world[f] * w).z();
    const PinholeCamera& camera = CameraOf(cameras, f);
    const double ft =
        camera.fx *
        (output_width > 0 ? double(output_width) / camera.width : 1.0);
    if (!(zt > 0)) continue;
    const double m = (z0 / zt) * (ft / camera0.fx) * pose.scale.maxCoeff();
    pose.subsamples = std::clamp(static_cast<int>(std::ceil(m - 0.05)), 1,
                                 std::max(1, max_subsamples));
  }
}

// Appends the objects drawn in `frame`, mapped to the world, to `out` (which
// already holds the background).
void AppendObjects(const DynamicScene& scene, int frame, PointCloud* out) {
  for (const DynamicObject& object : scene.objects) {
    if (frame >= static_cast<int>(object.poses.size()) || !object.poses[frame])
      continue;
    const ObjectPose& pose = *object.poses[frame];
    const PointCloud samples = FootprintSamples(object, pose.subsamples);
    const Matrix3x4d a = AffineOf(pose);
    const Eigen::Matrix3f linear = a.leftCols<3>().cast<float>();
    const Eigen::Vector3f t = a.col(3).cast<float>();
    const bool colors = out->HasColors() || out->empty();
    for (const Eigen::Vector3f& p : samples.positions)
      out->positions.push_back(linear * p + t);
    if (colors && samples.HasColors())
      out->colors.insert(out->colors.end(), samples.colors.begin(),
                         samples.colors.end());
    out->instance_ids.insert(out->instance_ids.end(), samples.size(),
                             object.render_id);
  }
}

// Keeps only positions, colours and instance ids (all -1).
PointCloud StripForRender(const PointCloud& cloud,
                          const std::vector<size_t>& keep) {
  PointCloud out;
  out.positions.reserve(keep.size());
  for (size_t i : keep) out.positions.push_back(cloud.positions[i]);
  if (cloud.HasColors()) {
    out.colors.reserve(keep.size());
    for (size_t i : keep) out.colors.push_back(cloud.colors[i]);
  }
  out.instance_ids.assign(keep.size(), -1);
  return out;
}

RenderedFrame EmptyFrame(const RenderOptions& options) {
  RenderedFrame frame;
  frame.rgb = cv::Mat::zeros(options.height, options.width, CV_8UC3);
  frame.depth = cv::Mat::zeros(options.height, options.width, CV_32F);
  frame.mask = cv::Mat::zeros(options.height, options.width, CV_8U);
  if (options.output_index)
    frame.index = cv::Mat(options.height, options.width, CV_32S, -1);
  frame.instance = cv::Mat(options.height, options.width, CV_32S, -1);
  if (options.output_float_rgb)
    frame.rgb_float = cv::Mat::zeros(options.height, options.width, CV_32FC3);
  return frame;
}

// Frame-0 pixel (rounded) and depth of every point, in camera 0 at its own
// size.
struct Frame0Projection {
  std::vector<int> u, v;  // -1 when not in front / outside
  std::vector<float> z;
};

Frame0Projection ProjectFrame0(const PointCloud& cloud,
                               const PinholeCamera& camera,
                               const Rigid3d& cam_from_world) {
  Frame0Projection p;
  const size_t n = cloud.size();
  p.u.assign(n, -1);
  p.v.assign(n, -1);
  p.z.assign(n, 0.f);
  const Eigen::Matrix3f r =
      cam_from_world.rotation.normalized().toRotationMatrix().cast<float>();
  const Eigen::Vector3f t = cam_from_world.translation.cast<float>();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f q = r * cloud.positions[i] + t;
    if (!(q.z() > 0)) continue;
    const double u = camera.fx * q.x() / q.z() + camera.cx;
    const double v = camera.fy * q.y() / q.z() + camera.cy;
    const double ui = std::floor(u + 0.5), vi = std::floor(v + 0.5);
    if (ui < 0 || vi < 0 || ui >= camera.width || vi >= camera.height) continue;
    p.u[i] = static_cast<int>(ui);
    p.v[i] = static_cast<int>(vi);
    p.z[i] = q.z();
  }
  return p;
}

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

// For each box, the indices (ascending) of the points inside it. One pass
// over the points: a coarse grid over the boxes' bounding region (x, y) holds
// per cell a bit mask of the boxes whose bounding box overlaps it, so a point
// far from every box costs a few compares and only points in marked cells get
// the exact tests. Boxes are taken 64 at a time (one mask bit each).
std::vector<std::vector<size_t>> PointsInBoxes(
    const std::vector<Eigen::Vector3f>& positions,
    const std::vector<FastBox>& boxes,
    int num_threads) {
  std::vector<std::vector<size_t>> inside(boxes.size());
  constexpr int kGrid = 64;
  for (size_t first = 0; first < boxes.size(); first += 64) {
    const size_t last = std::min(boxes.size(), first + 64);
    // World-axis-aligned bounding box of each box, and their union.
    std::vector<Eigen::Vector3f> lo(last - first), hi(last - first);
    Eigen::Vector3f ulo = Eigen::Vector3f::Constant(
                        std::numeric_limits<float>::infinity()),
                    uhi = -ulo;
    for (size_t k = first; k < last; ++k) {
      lo[k - first] = boxes[k].center - boxes[k].extent;
      hi[k - first] = boxes[k].center + boxes[k].extent;
      ulo = ulo.cwiseMin(lo[k - first]);
      uhi = uhi.cwiseMax(hi[k - first]);
    }
    // Cell of a coordinate; monotonic in it, so a point inside a bounding box
    // falls in one of that box's cells.
    const float sx = kGrid / std::max(uhi.x() - ulo.x(), 1e-6f);
    const float sy = kGrid / std::max(uhi.y() - ulo.y(), 1e-6f);
    auto cell = [](float c, float origin, float scale) {
      return std::clamp(static_cast<int>((c - origin) * scale), 0, kGrid - 1);
    };
    std::vector<uint64_t> mask(kGrid * kGrid, 0);
    for (size_t k = first; k < last; ++k) {
      const size_t j = k - first;
      const int x0 = cell(lo[j].x(), ulo.x(), sx),
                x1 = cell(hi[j].x(), ulo.x(), sx);
      const int y0 = cell(lo[j].y(), ulo.y(), sy),
                y1 = cell(hi[j].y(), ulo.y(), sy);
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) mask[y * kGrid + x] |= uint64_t{1} << j;
    }
    // Contiguous chunks of points per thread, merged in chunk order (so the
    // lists stay ascending whatever the thread count).
    const size_t n = positions.size();
    const int chunks = static_cast<int>(
        std::clamp<size_t>(n / 32768, 1, std::max(1, num_threads)));
    std::vector<std::vector<std::vector<size_t>>> found(
        chunks, std::vector<std::vector<size_t>>(last - first));
#pragma omp parallel for num_threads(chunks) schedule(static, 1)
    for (int c = 0; c < chunks; ++c) {
      const size_t begin = n * c / chunks, end = n * (c + 1) / chunks;
      for (size_t i = begin; i < end; ++i) {
        const Eigen::Vector3f& p = positions[i];
        if (!(p.x() >= ulo.x() && p.x() <= uhi.x() && p.y() >= ulo.y() &&
              p.y() <= uhi.y() && p.z() >= ulo.z() && p.z() <= uhi.z()))
          continue;
        uint64_t m =
            mask[cell(p.y(), ulo.y(), sy) * kGrid + cell(p.x(), ulo.x(), sx)];
        while (m) {
          const int j = __builtin_ctzll(m);
          m &= m - 1;
          if (boxes[first + j].Contains(p)) found[c][j].push_back(i);
        }
      }
    }
    for (size_t j = 0; j < last - first; ++j)
      for (int c = 0; c < chunks; ++c)
        inside[first + j].insert(inside[first + j].end(), found[c][j].begin(),
                                 found[c][j].end());
  }
  return inside;
}

bool InWindow(const cv::Rect& w, int u, int v) {
  return u >= w.x && u < w.x + w.width && v >= w.y && v < w.y + w.height;
}

}  // namespace

std::string ToString(EditMode mode) {
  return mode == EditMode::k2d ? "2d" : "3d";
}

EditMode ParseEditMode(const std::string& text) {
  if (text == "2d") return EditMode::k2d;
  if (text == "3d") return EditMode::k3d;
  ThrowInputError("edit mode", "'", text, "' is not one of 2d, 3d");
}

std::string ToString(ObjectEditKind kind) {
  switch (kind) {
    case ObjectEditKind::kRemove:
      return "remove";
    case ObjectEditKind::kInsert:
      return "insert";
    case ObjectEditKind::kMove:
      return "move";
  }
  return "?";
}

void DynamicEditOptions::Check() const {
  GEODRIVE_CHECK_INPUT(std::isfinite(min_box_area_px) && min_box_area_px >= 0,
                       "dynamic edit options: min_box_area_px must be >= 0");
  GEODRIVE_CHECK_INPUT(
      frame0_image.empty() || frame0_image.type() == CV_8UC3,
      "dynamic edit options: frame0_image must be RGB CV_8UC3");
  GEODRIVE_CHECK_INPUT(std::isfinite(box_margin) && box_margin >= 0,
                       "dynamic edit options: box_margin must be >= 0");
  GEODRIVE_CHECK_INPUT(std::isfinite(ground_margin) && ground_margin > 0,
                       "dynamic edit options: ground_margin must be > 0");
  if (ground_plane) {
    GEODRIVE_CHECK_INPUT(
        ground_plane->allFinite() &&
            std::abs(ground_plane->head<3>().norm() - 1.0) < 1e-6,
        "dynamic edit options: ground_plane needs a finite unit normal");
  }
  GEODRIVE_CHECK_INPUT(
      ground_max_tilt_deg > 0 && ground_max_tilt_deg < 90,
      "dynamic edit options: ground_max_tilt_deg must be in (0, 90)");
  GEODRIVE_CHECK_INPUT(
      ground_ransac_iterations >= 1 && ground_ransac_samples >= 3,
      "dynamic edit options: need ground_ransac_iterations >= 1 and "
      "ground_ransac_samples >= 3");
  GEODRIVE_CHECK_INPUT(
      ground_ransac_confidence > 0 && ground_ransac_confidence < 1,
      "dynamic edit options: ground_ransac_confidence must be in (0, 1)");
  GEODRIVE_CHECK_INPUT(dynamic_mask.empty() || dynamic_mask.type() == CV_8U,
                       "dynamic edit options: dynamic_mask must be CV_8U");
  GEODRIVE_CHECK_INPUT(std::isfinite(depth_gap_abs) && depth_gap_abs >= 0 &&
                           std::isfinite(depth_gap_rel) && depth_gap_rel >= 0,
                       "dynamic edit options: depth gaps must be >= 0");
  GEODRIVE_CHECK_INPUT(min_object_points >= 1,
                       "dynamic edit options: min_object_points must be >= 1");
  GEODRIVE_CHECK_INPUT(max_subsamples >= 1 && max_subsamples <= 8,
                       "dynamic edit options: max_subsamples must be in 1..8");
  GEODRIVE_CHECK_INPUT(num_threads >= 0,
                       "dynamic edit options: num_threads must be >= 0");
}

std::string DynamicEditSummary::BriefReport() const {
  std::ostringstream os;
  os << "dynamic edit (" << ToString(mode) << "): " << num_objects
     << " object(s) over " << num_frames << " frames";
  if (mode == EditMode::k3d) os << ", " << object_points << " moving points";
  os << ", " << removed_points << " points removed;";
  for (const AppliedEdit& e : edits) {
    os << " " << e.kind << " " << e.instance;
    if (!e.source.empty()) os << "<-" << e.source;
    os << " (" << e.num_points << " pts, " << e.frames_shown << " frames);";
  }
  if (!notes.empty()) os << " " << notes.size() << " note(s)";
  os << "; " << seconds << " s";
  return os.str();
}

std::string DynamicEditSummary::ToJson() const {
  json j;
  j["mode"] = ToString(mode);
  j["num_frames"] = num_frames;
  j["num_objects"] = num_objects;
  j["object_points"] = object_points;
  j["removed_points"] = removed_points;
  if (ground_plane) {
    j["ground_plane"] = {(*ground_plane)[0], (*ground_plane)[1],
                         (*ground_plane)[2], (*ground_plane)[3]};
    j["ground_plane_estimated"] = ground_plane_estimated;
  }
  json jedits = json::array();
  for (const AppliedEdit& e : edits) {
    json je = {{"kind", e.kind},
               {"instance", e.instance},
               {"num_points", e.num_points},
               {"frames_shown", e.frames_shown}};
    if (!e.source.empty()) je["source"] = e.source;
    jedits.push_back(je);
  }
  j["edits"] = jedits;
  json jnotes = json::array();
  for (const EditNote& n : notes) {
    json jn = {{"instance", n.instance}, {"message", n.message}};
    if (n.frame >= 0) jn["frame"] = n.frame;
    jnotes.push_back(jn);
  }
  j["notes"] = jnotes;
  j["seconds"] = seconds;
  return j.dump();
}

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
                               DynamicEditSummary* summary,
                               int output_width) {
  options.Check();
  CheckClip(cameras, cam_from_world, boxes);
  cloud_in_world.Check("dynamic edit: point cloud");
  const EditPlan plan = PlanEdits(boxes, edits);
  const int num_frames = static_cast<int>(cam_from_world.size());
  const size_t n = cloud_in_world.size();
  summary->mode = EditMode::k3d;
  summary->num_frames = num_frames;
  const PinholeCamera& camera0 = CameraOf(cameras, 0);
  const Rigid3d& pose0 = cam_from_world[0];

  DynamicScene scene;
  scene.num_frames = num_frames;

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
  // The ground plane serves 2D-box segmentation and lifting 2D boxes (frames
  // without a 3D box); with 3D boxes throughout it is not needed (each box's
  // bottom face is the ground there), so it is only estimated when needed.
  bool need_plane = need_2d_seg;
  auto has_2d_only_frames = [](const BoxSequence& seq) {
    for (const BoxFrame& f : seq.frames)
      if (f.box_2d && !f.box_3d) return true;
    return false;
  };
  for (const BoxSequence& seq : boxes.instances)
    need_plane = need_plane || has_2d_only_frames(seq);
  for (const ObjectEdit& e : edits)
    need_plane = need_plane || (e.kind != ObjectEditKind::kRemove &&
                                has_2d_only_frames(e.sequence));
  std::optional<Eigen::Vector4d> plane = options.ground_plane;
  if (!plane && need_plane) {
    std::vector<cv::Rect> windows;
    std::vector<FastBox> boxes3d;
    for (const Track& t : tracks) {
      if (t.box_3d[0]) boxes3d.emplace_back(*t.box_3d[0], options.box_margin);
      if (need_2d_seg && t.box_2d[0] && !t.box_3d[0]) {
        windows.push_back(PixelWindow(*PixelBox(t, 0, boxes, camera0, pose0),
                                      camera0.width, camera0.height));
      }
    }
    std::vector<size_t> candidates;
    const size_t stride =
        std::max<size_t>(1, n / (2 * size_t(options.ground_ransac_samples)));
    for (size_t i = 0; i < n; i += stride) {
      bool inside = false;
      for (const FastBox& b : boxes3d)
        inside = inside || b.Contains(cloud_in_world.positions[i]);
      if (need_2d_seg && proj.u[i] >= 0) {
        for (const cv::Rect& w : windows)
          inside = inside || InWindow(w, proj.u[i], proj.v[i]);
      }
      if (!inside) candidates.push_back(i);
    }
    const Eigen::Vector3d up =
        pose0.Inverse().rotation * Eigen::Vector3d(0, -1, 0);
    plane =
        EstimateGroundPlane(cloud_in_world.positions, candidates, up, options);
    summary->ground_plane_estimated = plane.has_value();
    if (!plane)
      AddNote(summary, "", -1,
              "no ground plane found: road points are not filtered and 2D "
              "boxes are lifted by "
              "their size only");
  }
  summary->ground_plane = plane;

  // Segment every instance in frame 0. Points inside the frame-0 3D boxes,
  // all boxes in one pass.
  std::vector<FastBox> fast_boxes;
  std::vector<int> fast_box_of(boxes.instances.size(), -1);
  for (size_t k = 0; k < boxes.instances.size(); ++k) {
    if (!tracks[k].box_3d[0]) continue;
    fast_box_of[k] = static_cast<int>(fast_boxes.size());
    fast_boxes.emplace_back(*tracks[k].box_3d[0], options.box_margin);
  }
  const std::vector<std::vector<size_t>> in_box = PointsInBoxes(
      cloud_in_world.positions, fast_boxes,
      options.num_threads > 0 ? options.num_threads : omp_get_max_threads());
  std::vector<char> taken(n, 0);
  std::vector<std::optional<Segment>> segments(boxes.instances.size());
  for (size_t k = 0; k < boxes.instances.size(); ++k) {
    const BoxSequence& s = boxes.instances[k];
    const Track& t = tracks[k];
    if (!t.box_3d[0] && !t.box_2d[0]) {
      AddNote(summary, s.id, 0,
              "no box in frame 0: its points cannot be found; left static");
      continue;
    }
    Segment seg;
    auto above_ground = [&](size_t i) {
      return !plane ||
             PlaneDistance(*plane, cloud_in_world.positions[i].cast<double>()) >
                 options.ground_margin;
    };
    if (t.box_3d[0]) {
      seg.box0 = *t.box_3d[0];
      const FastBox& fast = fast_boxes[fast_box_of[k]];
      const float margin = static_cast<float>(options.ground_margin);
      for (size_t i : in_box[fast_box_of[k]]) {
        if (taken[i]) continue;
        // Road points: near the ground plane, or without one, near the box's
        // bottom face.
        if (plane
                ? above_ground(i)
                : fast.HeightAboveBottom(cloud_in_world.positions[i]) > margin)
          seg.indices.push_back(i);
      }
    } else {
      const Box2d box = *PixelBox(t, 0, boxes, camera0, pose0);
      const cv::Rect w = PixelWindow(box, camera0.width, camera0.height);
      std::vector<size_t> cand;
      for (size_t i = 0; i < n; ++i) {
        if (taken[i] || proj.u[i] < 0 || !InWindow(w, proj.u[i], proj.v[i]) ||
            !above_ground(i))
          continue;
        cand.push_back(i);
      }
      if (!options.dynamic_mask.empty()) {
        std::vector<size_t> dyn;
        const double mx = double(options.dynamic_mask.cols) / camera0.width;
        const double my = double(options.dynamic_mask.rows) / camera0.height;
        for (size_t i : cand) {
          const int mu = std::min(options.dynamic_mask.cols - 1,
                                  int((proj.u[i] + 0.5) * mx));
          const int mv = std::min(options.dynamic_mask.rows - 1,
                                  int((proj.v[i] + 0.5) * my));
          if (options.dynamic_mask.at<uint8_t>(mv, mu)) dyn.push_back(i);
        }
        if (static_cast<int>(dyn.size()) >= options.min_object_points) {
          cand.swap(dyn);
        } else {
          AddNote(summary, s.id, 0,
                  "dynamic mask leaves too few points in the box; ignored");
        }
      }
      // Dominant depth cluster.
      std::sort(cand.begin(), cand.end(), [&](size_t a, size_t b) {
        return proj.z[a] < proj.z[b] || (proj.z[a] == proj.z[b] && a < b);
      });
      size_t best_begin = 0, best_end = 0, begin = 0;
      for (size_t k2 = 1; k2 <= cand.size(); ++k2) {
        const bool split = k2 == cand.size() ||
                           proj.z[cand[k2]] - proj.z[cand[k2 - 1]] >
                               options.depth_gap_abs +
                                   options.depth_gap_rel * proj.z[cand[k2 - 1]];
        if (split) {
          if (k2 - begin > best_end - best_begin) {
            best_begin = begin;
            best_end = k2;
          }
          begin = k2;
        }
      }
      seg.indices.assign(cand.begin() + best_begin, cand.begin() + best_end);
      std::sort(seg.indices.begin(), seg.indices.end());
      seg.lift.box0 = box;
      if (!seg.indices.empty()) {
        std::vector<float> depths;
        for (size_t i : seg.indices) depths.push_back(proj.z[i]);
        std::nth_element(depths.begin(), depths.begin() + depths.size() / 2,
                         depths.end());
        seg.lift.depth0 = depths[depths.size() / 2];
      }
    }
    if (static_cast<int>(seg.indices.size()) < options.min_object_points) {
      AddNote(summary, s.id, 0,
              "only " + std::to_string(seg.indices.size()) +
                  " point(s) segmented in frame 0 (min " +
                  std::to_string(options.min_object_points) + "); left static");
      continue;
    }
    // Lift reference (used when a frame has only a 2D box, which is what
    // need_plane says).
    if (seg.box0 && need_plane) {
      const std::optional<Box2d> b = PixelBox(t, 0, boxes, camera0, pose0);
      if (b) seg.lift.box0 = *b;
      // Camera-0 z: the third row of cam_from_world.
      const Eigen::Vector3d zrow =
          pose0.rotation.toRotationMatrix().row(2).transpose();
      const double tz = pose0.translation.z();
      std::vector<double> depths;
      depths.reserve(seg.indices.size());
      for (size_t i : seg.indices)
        depths.push_back(zrow.dot(cloud_in_world.positions[i].cast<double>()) +
                         tz);
      std::nth_element(depths.begin(), depths.begin() + depths.size() / 2,
                       depths.end());
      seg.lift.depth0 = depths[depths.size() / 2];
    }
    if (plane && seg.lift.box0.height() > 0) {
      seg.lift.ground0 = GroundHit(
          camera0, pose0,
          Eigen::Vector2d(0.5 * (seg.lift.box0.xmin + seg.lift.box0.xmax),
                          seg.lift.box0.ymax),
          *plane);
    }
    for (size_t i : seg.indices) taken[i] = 1;
    segments[k] = std::move(seg);
  }

  // Background: everything not segmented.
  for (size_t i = 0; i < n; ++i)
    if (taken[i]) scene.hidden.push_back(i);

  auto make_object = [&](const Segment& seg, const std::string& id,
                         const std::string& source) {
    DynamicObject object;
    object.id = id;
    object.source_id = source;
    object.render_id = static_cast<int32_t>(scene.objects.size());
    object.points_in_object = StripForRender(cloud_in_world, seg.indices);
    const Rigid3d object_from_world =
        seg.box0 ? seg.box0->WorldFromBox().Inverse() : Rigid3d();
    const Eigen::Matrix3d object_r =
        object_from_world.rotation.toRotationMatrix();
    const Eigen::Vector3d object_t = object_from_world.translation;
    for (Eigen::Vector3f& p : object.points_in_object.positions)
      p = (object_r * p.cast<double>() + object_t).cast<float>();
    return object;
  };
  // Subsampling per frame, then the footprints, only for objects drawn with
  // k > 1 somewhere (footprint of point i: camera-0 pixel steps at its
  // camera-0 depth, in the object frame).
  auto set_subsamples = [&](const Segment& seg, DynamicObject* object) {
    const Rigid3d world_from_object0 =
        seg.box0 ? seg.box0->WorldFromBox() : Rigid3d();
    SetSubsamples(cameras, cam_from_world, world_from_object0, output_width,
                  options.max_subsamples, object);
    bool magnified = false;
    for (const std::optional<ObjectPose>& pose : object->poses)
      magnified = magnified || (pose && pose->subsamples > 1);
    if (!magnified) return;
    const Eigen::Matrix3d world_r =
        world_from_object0.rotation.toRotationMatrix();
    const Eigen::Matrix3d cam_r = pose0.rotation.toRotationMatrix();
    // object_from_cam0 rotation: R_o^T R_c^T.
    const Eigen::Matrix3d r = world_r.transpose() * cam_r.transpose();
    // Camera-0 z of x_world = R_o x + t_o: (R_c.row(2) R_o) x + R_c.row(2) t_o
    // + t_c.z.
    const Eigen::Vector3d zrow = (cam_r.row(2) * world_r).transpose();
    const double tz = cam_r.row(2).dot(world_from_object0.translation) +
                      pose0.translation.z();
    const size_t m = object->points_in_object.size();
    object->footprint_u.resize(m);
    object->footprint_v.resize(m);
    for (size_t i = 0; i < m; ++i) {
      const double z =
          zrow.dot(object->points_in_object.positions[i].cast<double>()) + tz;
      object->footprint_u[i] = (r.col(0) * (z / camera0.fx)).cast<float>();
      object->footprint_v[i] = (r.col(1) * (z / camera0.fy)).cast<float>();
    }
  };

  for (size_t k = 0; k < boxes.instances.size(); ++k) {
    const BoxSequence& s = boxes.instances[k];
    const bool removed = plan.removed.count(s.id) > 0;
    const auto moved = plan.moved.find(s.id);
    AppliedEdit applied;
    applied.kind =
        removed ? "remove" : (moved != plan.moved.end() ? "move" : "animate");
    applied.instance = s.id;
    if (!segments[k]) {
      if (removed || moved != plan.moved.end())
        AddNote(summary, s.id, -1,
                applied.kind + " skipped: no points segmented");
      continue;
    }
    const Segment& seg = *segments[k];
    applied.num_points = static_cast<int64_t>(seg.indices.size());
    if (removed) {
      summary->removed_points += applied.num_points;
      summary->edits.push_back(applied);
      continue;
    }
    DynamicObject object = make_object(seg, s.id, "");
    const Track track = moved != plan.moved.end()
                            ? BuildTrack(*moved->second, num_frames,
                                         options.interpolate_missing)
                            : tracks[k];
    object.poses =
        TrackPoses(seg, track, s.id, boxes, cameras, cam_from_world, plane,
                   options.min_box_area_px, summary, &applied.frames_shown);
    set_subsamples(seg, &object);
    summary->object_points += applied.num_points;
    scene.objects.push_back(std::move(object));
    summary->edits.push_back(applied);
  }
  for (const ObjectEdit* e : plan.inserts) {
    size_t k = 0;
    while (boxes.instances[k].id != e->instance) ++k;
    AppliedEdit applied;
    applied.kind = "insert";
    applied.instance = e->sequence.id;
    applied.source = e->instance;
    if (!segments[k]) {
      AddNote(summary, e->sequence.id, -1,
              "insert skipped: source '" + e->instance +
                  "' has no segmented points");
      continue;
    }
    const Segment& seg = *segments[k];
    DynamicObject object = make_object(seg, e->sequence.id, e->instance);
    const Track track =
        BuildTrack(e->sequence, num_frames, options.interpolate_missing);
    object.poses = TrackPoses(seg, track, e->sequence.id, boxes, cameras,
                              cam_from_world, plane, options.min_box_area_px,
                              summary, &applied.frames_shown);
    set_subsamples(seg, &object);
    applied.num_points = static_cast<int64_t>(seg.indices.size());
    summary->object_points += applied.num_points;
    scene.objects.push_back(std::move(object));
    summary->edits.push_back(applied);
  }
  summary->num_objects = static_cast<int>(scene.objects.size());
  return scene;
}

cv::Mat FeatherAlpha(int width, int height) {
  cv::Mat alpha = cv::Mat::ones(height, width, CV_32F);
  if (width <= 0 || height <= 0) return alpha;
  const cv::Mat k1 = (cv::Mat_<float>(5, 1) << 1, 4, 6, 4, 1) / 16.0f;
  cv::Mat out;
  cv::sepFilter2D(alpha, out, CV_32F, k1, k1, cv::Point(-1, -1), 0,
                  cv::BORDER_CONSTANT);
  return out;
}

bool PasteFeathered(const cv::Mat& source,
                    const Box2d& source_box,
                    const Box2d& target_box,
                    cv::Mat* target,
                    cv::Mat* instance,
                    int32_t id) {
  GEODRIVE_CHECK_INPUT(source.type() == CV_8UC3 && target->type() == CV_8UC3,
                       "paste: images must be RGB CV_8UC3");
  if (!source_box.IsFinite() || !target_box.IsFinite()) return false;
  const cv::Rect src = PixelWindow(source_box, source.cols, source.rows);
  if (src.width <= 0 || src.height <= 0) return false;
  // Unclamped target window (upstream: int() truncation).
  const int x0 = static_cast<int>(std::trunc(target_box.xmin));
  const int y0 = static_cast<int>(std::trunc(target_box.ymin));
  const int x1 = static_cast<int>(std::trunc(target_box.xmax));
  const int y1 = static_cast<int>(std::trunc(target_box.ymax));
  const int tw = x1 - x0, th = y1 - y0;
  if (tw <= 0 || th <= 0) return false;
  const cv::Rect full(x0, y0, tw, th);
  const cv::Rect visible = full & cv::Rect(0, 0, target->cols, target->rows);
  if (visible.width <= 0 || visible.height <= 0) return false;
  // Guard absurd sizes (a box thousands of times the image): resize only what
  // is visible.
  const double sx = double(src.width) / tw, sy = double(src.height) / th;
  cv::Mat patch;
  if (double(tw) * th <= 64.0 * target->total() + 1e6) {
    cv::Mat resized;
    cv::resize(source(src), resized, cv::Size(tw, th), 0, 0, cv::INTER_LINEAR);
    patch = resized(cv::Rect(visible.x - x0, visible.y - y0, visible.width,
                             visible.height));
  } else {
    // Equivalent bilinear sampling (half-pixel centres) of the visible part
    // only.
    cv::Mat mapx(visible.height, visible.width, CV_32F),
        mapy(visible.height, visible.width, CV_32F);
    for (int r = 0; r < visible.height; ++r) {
      for (int c = 0; c < visible.width; ++c) {
        mapx.at<float>(r, c) =
            float((visible.x - x0 + c + 0.5) * sx - 0.5 + src.x);
        mapy.at<float>(r, c) =
            float((visible.y - y0 + r + 0.5) * sy - 0.5 + src.y);
      }
    }
    cv::remap(source, patch, mapx, mapy, cv::INTER_LINEAR,
              cv::BORDER_REPLICATE);
  }
  const cv::Mat alpha = FeatherAlpha(visible.width, visible.height);
  for (int r = 0; r < visible.height; ++r) {
    const cv::Vec3b* p = patch.ptr<cv::Vec3b>(r);
    const float* a = alpha.ptr<float>(r);
    cv::Vec3b* t = target->ptr<cv::Vec3b>(visible.y + r) + visible.x;
    int32_t* inst =
        instance ? instance->ptr<int32_t>(visible.y + r) + visible.x : nullptr;
    for (int c = 0; c < visible.width; ++c) {
      for (int ch = 0; ch < 3; ++ch) {
        t[c][ch] = cv::saturate_cast<uint8_t>(a[c] * p[c][ch] +
                                              (1.0f - a[c]) * t[c][ch]);
      }
      if (inst && a[c] >= 0.5f) inst[c] = id;
    }
  }
  return true;
}

namespace {

void CopyFrameRest(RenderedFrame* frame, const RenderOptions& options) {
  if (frame->instance.empty())
    frame->instance = cv::Mat(options.height, options.width, CV_32S, -1);
}

DynamicEditResult Render2d(const PointCloud& cloud_in_world,
                           const std::vector<PinholeCamera>& cameras,
                           const std::vector<Rigid3d>& cam_from_world,
                           const BoxSequences& boxes,
                           const std::vector<ObjectEdit>& edits,
                           const DynamicEditOptions& options,
                           RenderOptions render_options) {
  DynamicEditResult result;
  DynamicEditSummary& summary = result.summary;
  summary.mode = EditMode::k2d;
  const int num_frames = static_cast<int>(cam_from_world.size());
  summary.num_frames = num_frames;
  const EditPlan plan = PlanEdits(boxes, edits);
  const PinholeCamera& camera0 = CameraOf(cameras, 0);
  const int W = render_options.width, H = render_options.height;
  const double shift =
      render_options.pixel_convention == PixelConvention::kPixelCenter ? -0.5
                                                                       : 0.0;

  std::vector<Track> tracks;
  for (const BoxSequence& s : boxes.instances)
    tracks.push_back(BuildTrack(s, num_frames, options.interpolate_missing));

  // 1. Delete the points in each instance's frame-0 box region (camera 0, its
  // own pixel grid).
  const Frame0Projection proj =
      ProjectFrame0(cloud_in_world, camera0, cam_from_world[0]);
  std::vector<cv::Rect> windows;
  for (size_t k = 0; k < boxes.instances.size(); ++k) {
    const std::optional<Box2d> b =
        PixelBox(tracks[k], 0, boxes, camera0, cam_from_world[0]);
    if (!b) {
      AddNote(&summary, boxes.instances[k].id, 0,
              "no box in frame 0: nothing removed or pasted for it");
      continue;
    }
    const cv::Rect w = PixelWindow(*b, camera0.width, camera0.height);
    if (w.area() == 0) {
      AddNote(&summary, boxes.instances[k].id, 0,
              "frame-0 box is empty or outside the image: nothing removed or "
              "pasted for it");
      continue;
    }
    windows.push_back(w);
  }
  std::vector<size_t> keep;
  keep.reserve(cloud_in_world.size());
  for (size_t i = 0; i < cloud_in_world.size(); ++i) {
    bool inside = false;
    if (proj.u[i] >= 0) {
      for (const cv::Rect& w : windows)
        inside = inside || InWindow(w, proj.u[i], proj.v[i]);
    }
    if (!inside) keep.push_back(i);
  }
  summary.removed_points =
      static_cast<int64_t>(cloud_in_world.size() - keep.size());
  const PointCloud background = StripForRender(cloud_in_world, keep);

  // 2. Static render (the instance map marks pasted pixels; dropped at the end
  // unless asked for).
  const bool want_instance = render_options.output_instance;
  render_options.output_instance = true;
  if (background.empty()) {
    result.frames.assign(num_frames, RenderedFrame());
    for (int f = 0; f < num_frames; ++f)
      result.frames[f] = EmptyFrame(render_options);
  } else {
    result.frames =
        RenderFrames(background, cameras, cam_from_world, render_options)
            .frames;
  }
  for (RenderedFrame& f : result.frames) CopyFrameRest(&f, render_options);

  // 3. The crop source.
  cv::Mat source;
  if (!options.frame0_image.empty()) {
    cv::resize(options.frame0_image, source, cv::Size(W, H), 0, 0,
               cv::INTER_LINEAR);
  } else {
    RenderOptions o = render_options;
    o.output_instance = false;
    o.output_index = false;
    source = RenderFrame(cloud_in_world, cameras[0], cam_from_world[0], o).rgb;
  }

  // 4. Paste, instances in order, then inserted copies.
  struct Paste {
    std::string id, source_id, kind;
    const Track* source_track;
    Track track;
  };
  std::vector<Paste> pastes;
  for (size_t k = 0; k < boxes.instances.size(); ++k) {
    const std::string& id = boxes.instances[k].id;
    if (plan.removed.count(id)) {
      summary.edits.push_back(AppliedEdit{"remove", id, "", 0, 0});
      continue;
    }
    const auto moved = plan.moved.find(id);
    if (moved != plan.moved.end()) {
      pastes.push_back(Paste{
          id, id, "move", &tracks[k],
          BuildTrack(*moved->second, num_frames, options.interpolate_missing)});
    } else {
      pastes.push_back(Paste{id, id, "animate", &tracks[k], tracks[k]});
    }
  }
  for (const ObjectEdit* e : plan.inserts) {
    size_t k = 0;
    while (boxes.instances[k].id != e->instance) ++k;
    pastes.push_back(Paste{
        e->sequence.id, e->instance, "insert", &tracks[k],
        BuildTrack(e->sequence, num_frames, options.interpolate_missing)});
  }
  for (size_t p = 0; p < pastes.size(); ++p) {
    const Paste& paste = pastes[p];
    const int32_t render_id = static_cast<int32_t>(result.render_ids.size());
    AppliedEdit applied{paste.kind, paste.id,
                        paste.kind == "insert" ? paste.source_id : "", 0, 0};
    const PinholeCamera cam0 =
        ResizeCamera(camera0, W, H, render_options.pixel_convention);
    const std::optional<Box2d> src =
        PixelBox(*paste.source_track, 0, boxes, cam0, cam_from_world[0], shift);
    if (!src || PixelWindow(*src, W, H).area() == 0) {
      AddNote(&summary, paste.id, -1,
              paste.kind + " skipped: no usable frame-0 box to crop");
      continue;
    }
    std::vector<int> missing, skipped;
    for (int f = 0; f < num_frames; ++f) {
      const PinholeCamera cam = ResizeCamera(CameraOf(cameras, f), W, H,
                                             render_options.pixel_convention);
      const std::optional<Box2d> b =
          PixelBox(paste.track, f, boxes, cam, cam_from_world[f], shift);
      if (!b) {
        missing.push_back(f);
        continue;
      }
      if (b->Clipped(W, H).Area() < std::max(options.min_box_area_px, 1e-9)) {
        skipped.push_back(f);
        continue;
      }
      if (PasteFeathered(source, *src, *b, &result.frames[f].rgb,
                         &result.frames[f].instance, render_id)) {
        ++applied.frames_shown;
      } else {
        skipped.push_back(f);
      }
    }
    if (!missing.empty())
      AddNote(&summary, paste.id, -1,
              "not pasted in frames without a box: " + FrameList(missing));
    if (!skipped.empty())
      AddNote(&summary, paste.id, -1,
              "box empty or outside the image, skipped in frames: " +
                  FrameList(skipped));
    if (!paste.track.interpolated.empty())
      AddNote(&summary, paste.id, -1,
              "boxes interpolated in frames: " +
                  FrameList(paste.track.interpolated));
    result.render_ids.push_back(paste.id);
    summary.edits.push_back(applied);
  }
  // Pasted pixels are valid.
  for (RenderedFrame& frame : result.frames) {
    const int32_t* inst = frame.instance.ptr<int32_t>();
    uint8_t* mask = frame.mask.ptr<uint8_t>();
    const size_t npix = frame.mask.total();
    for (size_t p = 0; p < npix; ++p)
      if (inst[p] >= 0) mask[p] = kMaskValid;
    if (!want_instance) frame.instance.release();
  }
  summary.num_objects = static_cast<int>(result.render_ids.size());
  return result;
}

}  // namespace

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
    RenderOptions ro = render_options;
    ro.num_threads = options.num_threads > 0 ? options.num_threads
                                             : (render_options.num_threads > 0
                                                    ? render_options.num_threads
                                                    : omp_get_max_threads());
    DynamicEditOptions build_options = options;
    build_options.num_threads = ro.num_threads;
    DynamicScene scene =
        BuildDynamicScene(cloud_in_world, cameras, cam_from_world, boxes, edits,
                          build_options, &result.summary, render_options.width);
    for (const DynamicObject& o : scene.objects)
      result.render_ids.push_back(o.id);
    const std::vector<size_t> hidden = std::move(scene.hidden);
    // One depth test per frame over the background and that frame's moved
    // objects, so objects and background occlude each other correctly. Each
    // object is packed once in its own frame (once per footprint sampling k
    // it uses) and only projected per frame.
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
    RenderFramesWithMovingSets(*background, MovingSets(std::move(scene)),
                               cameras, cam_from_world, ro, &rendered, hidden);
    result.frames = std::move(rendered.frames);
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

RenderResult DynamicEditResult::ToRenderResult() && {
  RenderResult r;
  r.frames = std::move(frames);
  r.summary = render_summary;
  return r;
}

std::vector<ObjectEdit> ParseEditArgs(const EditCliArgs& args,
                                      BoxSequences* boxes) {
  GEODRIVE_CHECK_INPUT(!args.boxes_path.empty(),
                       "--boxes: a boxes file is required for edits");
  *boxes = ReadBoxesJson(args.boxes_path);
  ParseEditMode(args.edit_mode);
  std::vector<ObjectEdit> edits;
  for (const std::string& id : args.remove) {
    ObjectEdit e;
    e.kind = ObjectEditKind::kRemove;
    e.instance = id;
    GEODRIVE_CHECK_INPUT(boxes->Find(id) != nullptr, "--remove ", id,
                         ": no instance '", id, "' in ", args.boxes_path);
    edits.push_back(e);
  }
  auto parse_spec = [&](const std::string& spec, ObjectEditKind kind,
                        const char* flag) {
    const size_t colon = spec.find(':');
    GEODRIVE_CHECK_INPUT(
        colon != std::string::npos && colon > 0 && colon + 1 < spec.size(),
        flag, " ", spec, ": expected ID:FILE");
    ObjectEdit e;
    e.kind = kind;
    e.instance = spec.substr(0, colon);
    const std::string file = spec.substr(colon + 1);
    GEODRIVE_CHECK_INPUT(boxes->Find(e.instance) != nullptr, flag, " ", spec,
                         ": no instance '", e.instance, "' in ",
                         args.boxes_path);
    const BoxSequences seq = ReadBoxesJson(file);
    GEODRIVE_CHECK_INPUT(
        seq.instances.size() == 1, file, ": ", flag,
        " needs a boxes file with exactly one instance, found ",
        seq.instances.size());
    GEODRIVE_CHECK_INPUT(seq.num_frames == boxes->num_frames, file,
                         ": num_frames ", seq.num_frames, " differs from ",
                         args.boxes_path, " (", boxes->num_frames, ")");
    e.sequence = seq.instances[0];
    // Express the new 2D boxes in the main file's image size.
    const double sx = double(boxes->image_width) / seq.image_width;
    const double sy = double(boxes->image_height) / seq.image_height;
    for (BoxFrame& f : e.sequence.frames)
      if (f.box_2d) f.box_2d = f.box_2d->Scaled(sx, sy);
    edits.push_back(e);
  };
  for (const std::string& s : args.insert)
    parse_spec(s, ObjectEditKind::kInsert, "--insert");
  for (const std::string& s : args.move)
    parse_spec(s, ObjectEditKind::kMove, "--move");
  return edits;
}

DynamicEditResult ApplyEditsAndRender(
    const EditCliArgs& args,
    const PointCloud& cloud_in_world,
    const std::vector<PinholeCamera>& cameras,
    const std::vector<Rigid3d>& cam_from_world,
    const RenderOptions& render_options,
    const cv::Mat& frame0_image) {
  BoxSequences boxes;
  const std::vector<ObjectEdit> edits = ParseEditArgs(args, &boxes);
  DynamicEditOptions options;
  options.mode = ParseEditMode(args.edit_mode);
  options.frame0_image = frame0_image;
  options.num_threads = render_options.num_threads;
  return RenderWithDynamicEdits(cloud_in_world, cameras, cam_from_world, boxes,
                                edits, options, render_options);
}

}  // namespace geodrive

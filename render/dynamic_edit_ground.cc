// Dynamic editing, 3D mode: the ground plane (given or estimated by RANSAC
// from the points outside every frame-0 box) and the lifting of 2D boxes to
// 3D translations (ground hit of the box's bottom centre, or depth from the
// box height).

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>

#include "render/dynamic_edit.h"
#include "render/internal/dynamic_edit_internal.h"

namespace geodrive {
namespace dynamic_edit_internal {
namespace {

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

// World point on the ray through `pixel` at camera depth z.
Eigen::Vector3d PointAtDepth(const PinholeCamera& camera,
                             const Rigid3d& cam_from_world,
                             const Eigen::Vector2d& pixel,
                             double z) {
  return cam_from_world.Inverse() * camera.Unproject(pixel, z);
}

}  // namespace

bool NeedsGroundPlane(bool need_2d_seg,
                      const BoxSequences& boxes,
                      const std::vector<ObjectEdit>& edits) {
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
  return need_plane;
}

std::optional<Eigen::Vector4d> FindGroundPlane(
    const PointCloud& cloud_in_world,
    const PinholeCamera& camera0,
    const Rigid3d& pose0,
    const BoxSequences& boxes,
    const std::vector<Track>& tracks,
    const Frame0Projection& proj,
    bool need_2d_seg,
    const DynamicEditOptions& options,
    DynamicEditSummary* summary) {
  const size_t n = cloud_in_world.size();
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
  const std::optional<Eigen::Vector4d> plane =
      EstimateGroundPlane(cloud_in_world.positions, candidates, up, options);
  summary->ground_plane_estimated = plane.has_value();
  if (!plane)
    AddNote(summary, "", -1,
            "no ground plane found: road points are not filtered and 2D "
            "boxes are lifted by "
            "their size only");
  return plane;
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

}  // namespace dynamic_edit_internal
}  // namespace geodrive

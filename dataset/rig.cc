// Surround view (dataset/rig.h): per-view scenes fused under the ownership
// rule, the rig following an edited reference, the cross-view seam check.

#include "dataset/rig.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "geometry/util/status.h"
#include "render/footprint.h"

namespace geodrive {
namespace {

// Side of the cells (pixels) and relative depth tolerance of "j has that
// surface itself" (the lidar source's "sees" rule uses the same).
constexpr int kCell = 4;
constexpr double kSameSurface = 0.05;
// Depth agreement of the seam check.
constexpr double kSeamTolerance = 0.01;

// Moves a cloud by `b_from_a` (positions, and the footprint patch vectors by
// its rotation).
void TransformCloud(const Rigid3d& b_from_a, PointCloud* cloud) {
  const Eigen::Matrix3f r = b_from_a.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f t = b_from_a.translation.cast<float>();
  for (Eigen::Vector3f& p : cloud->positions) p = r * p + t;
  for (Eigen::Vector3f& u : cloud->footprint_u) u = r * u;
  for (Eigen::Vector3f& v : cloud->footprint_v) v = r * v;
}

// A view's frame-0 camera as seen from the scene frame, with its nearest
// depth per kCell x kCell cell of its own points.
struct ViewCells {
  PinholeCamera camera;
  Eigen::Matrix3d rot;  // cam0_from_scene
  Eigen::Vector3d trans;
  int cols = 0, rows = 0;
  std::vector<float> zmin;

  // Camera coordinates of scene point p.
  Eigen::Vector3d ToCam(const Eigen::Vector3f& p) const {
    return rot * p.cast<double>() + trans;
  }
  // The cell of camera point q, or -1 outside the image (or behind).
  int CellOf(const Eigen::Vector3d& q) const {
    if (q.z() <= 1e-6) return -1;
    const double u = camera.fx * q.x() / q.z() + camera.cx;
    const double v = camera.fy * q.y() / q.z() + camera.cy;
    if (!(u >= -0.5 && v >= -0.5 && u < camera.width - 0.5 &&
          v < camera.height - 0.5))
      return -1;
    const int x = static_cast<int>(std::lround(u)) / kCell;
    const int y = static_cast<int>(std::lround(v)) / kCell;
    return y * cols + x;
  }
};

ViewCells MakeCells(const PinholeCamera& camera,
                    const Rigid3d& scene_from_cam0,
                    const PointCloud& cloud_in_scene) {
  ViewCells c;
  c.camera = camera;
  const Rigid3d cam0_from_scene = scene_from_cam0.Inverse();
  c.rot = cam0_from_scene.rotation.toRotationMatrix();
  c.trans = cam0_from_scene.translation;
  c.cols = (camera.width + kCell - 1) / kCell;
  c.rows = (camera.height + kCell - 1) / kCell;
  c.zmin.assign(static_cast<size_t>(c.cols) * c.rows,
                std::numeric_limits<float>::infinity());
  for (const Eigen::Vector3f& p : cloud_in_scene.positions) {
    const Eigen::Vector3d q = c.ToCam(p);
    const int cell = c.CellOf(q);
    if (cell >= 0)
      c.zmin[cell] = std::min(c.zmin[cell], static_cast<float>(q.z()));
  }
  return c;
}

// Capacity for n points in each attribute `like` has (an empty cloud's
// Append of `like` then keeps them all).
void ReserveCloud(const PointCloud& like, size_t n, PointCloud* cloud) {
  cloud->positions.reserve(n);
  const auto reserve = [n](const auto& a, auto* b) {
    if (!a.empty()) b->reserve(n);
  };
  reserve(like.colors, &cloud->colors);
  reserve(like.confidence, &cloud->confidence);
  reserve(like.instance_ids, &cloud->instance_ids);
  reserve(like.intensity, &cloud->intensity);
  reserve(like.ring, &cloud->ring);
  reserve(like.footprints, &cloud->footprints);
  reserve(like.footprint_u, &cloud->footprint_u);
  reserve(like.footprint_v, &cloud->footprint_v);
}

// cos of the angle between the camera's optical axis and the ray to q.
double Frontality(const Eigen::Vector3d& q) {
  const double n = q.norm();
  return n > 0 ? q.z() / n : -1.0;
}

}  // namespace

std::string RigScene::BriefReport() const {
  std::ostringstream os;
  os << views.size() << " cameras, " << cloud.size() << " fused points (";
  for (size_t k = 0; k < views.size(); ++k) {
    os << (k ? ", " : "") << views[k].channel << " " << views[k].points_kept
       << " of " << views[k].points_built;
  }
  os << ")";
  return os.str();
}

RigScene FuseRigScenes(const DriveClip& clip,
                       std::vector<ConditionScene> views) {
  GEODRIVE_CHECK_INPUT(static_cast<int>(views.size()) == clip.num_views(),
                       clip.id, ": ", views.size(), " view scenes for ",
                       clip.num_views(), " cameras");
  RigScene rig;
  rig.world_from_scene = clip.frames.front().world_from_cam;
  const Rigid3d scene_from_world = rig.world_from_scene.Inverse();
  std::vector<ViewCells> cells;
  for (int k = 0; k < clip.num_views(); ++k) {
    const DriveClip view_clip = clip.View(k);
    ConditionScene& s = views[k];
    GEODRIVE_CHECK_INPUT(s.metric(), clip.id, ": ", view_clip.channel,
                         ": a surround-view scene needs metric geometry (the "
                         "lidar or lidar-dense source), not ",
                         s.units);
    GEODRIVE_CHECK_INPUT(s.trajectory.size() == view_clip.frames.size(),
                         clip.id, ": ", view_clip.channel, ": ",
                         s.trajectory.size(), " poses for ",
                         view_clip.frames.size(), " frames");
    // The source's frame is this camera at its own frame 0.
    const Rigid3d scene_from_view0 =
        scene_from_world * view_clip.frames.front().world_from_cam;
    RigView v;
    v.channel = view_clip.channel;
    v.camera = s.camera;
    for (const DriveFrame& f : view_clip.frames)
      v.scene_from_cam.push_back(scene_from_world * f.world_from_cam);
    // Footprints from the camera that captured the points (this view at its
    // frame 0), before the move: every camera then draws a point over its
    // capture pixel, and no render recomputes them from its own frame 0.
    if (!s.cloud.HasFootprints() && s.has_camera)
      SetCaptureFootprints(s.camera, Rigid3d(), &s.cloud);
    TransformCloud(scene_from_view0, &s.cloud);
    v.points_built = static_cast<int64_t>(s.cloud.size());
    cells.push_back(MakeCells(s.camera, scene_from_view0, s.cloud));
    rig.views.push_back(std::move(v));
  }
  // Ownership: keep p of view k unless a more frontal view has its surface.
  std::vector<std::vector<size_t>> keeps(views.size());
  for (size_t k = 0; k < views.size(); ++k) {
    const PointCloud& cloud = views[k].cloud;
    std::vector<size_t>& keep = keeps[k];
    keep.reserve(cloud.size());
    for (size_t i = 0; i < cloud.size(); ++i) {
      const Eigen::Vector3f& p = cloud.positions[i];
      // The cheap tests first (most points are outside the other images);
      // k's own frontality only when some j has the surface.
      double own = 2.0;  // not computed yet (a cosine is at most 1)
      bool owned_elsewhere = false;
      for (size_t j = 0; j < views.size() && !owned_elsewhere; ++j) {
        if (j == k) continue;
        const Eigen::Vector3d q = cells[j].ToCam(p);
        const int cell = cells[j].CellOf(q);
        if (cell < 0) continue;
        if (!(std::abs(cells[j].zmin[cell] - q.z()) <= kSameSurface * q.z()))
          continue;
        if (own > 1.5) own = Frontality(cells[k].ToCam(p));
        owned_elsewhere = Frontality(q) > own;
      }
      if (!owned_elsewhere) keep.push_back(i);
    }
  }
  // The kept points in view order, into a cloud sized once.
  size_t total = 0;
  for (const std::vector<size_t>& keep : keeps) total += keep.size();
  ReserveCloud(views.front().cloud, total, &rig.cloud);
  for (size_t k = 0; k < views.size(); ++k) {
    const PointCloud& cloud = views[k].cloud;
    const std::vector<size_t>& keep = keeps[k];
    rig.views[k].points_kept = static_cast<int64_t>(keep.size());
    if (keep.size() == cloud.size()) {
      rig.cloud.Append(cloud);
    } else {
      rig.cloud.Append(cloud.Select(keep));
    }
    views[k].cloud = PointCloud();
    rig.views[k].source = std::move(views[k]);
  }
  return rig;
}

bool PointGroupBounds(const PointCloud& cloud,
                      size_t begin,
                      size_t end,
                      Eigen::Vector3f* lo,
                      Eigen::Vector3f* hi) {
  *lo = cloud.positions[begin];
  *hi = *lo;
  for (size_t i = begin + 1; i < end; ++i) {
    *lo = lo->cwiseMin(cloud.positions[i]);
    *hi = hi->cwiseMax(cloud.positions[i]);
  }
  return lo->allFinite() && hi->allFinite();
}

std::vector<size_t> PointsInViewOfAny(
    const PointCloud& cloud,
    const PinholeCamera& camera,
    const std::vector<Rigid3d>& scene_from_cam,
    double near,
    double far,
    double margin_px) {
  // Rows of K * cam_from_scene in float, per pose: u*z, v*z and z are affine
  // in the point. Float margins (1e-3 m in depth, one pixel more) keep every
  // point the renderer's own float test could pass.
  struct Pose {
    Eigen::Matrix<float, 3, 4> m;
    Eigen::Matrix<double, 3, 4> md;
  };
  std::vector<Pose> poses;
  for (const Rigid3d& pose : scene_from_cam) {
    Eigen::Matrix<double, 3, 4> p = pose.Inverse().ToMatrix3x4();
    Eigen::Matrix3d k;
    k << camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1;
    poses.push_back({(k * p).cast<float>(), k * p});
  }
  const float lo_z = static_cast<float>(near) - 1e-3f;
  const float hi_z = static_cast<float>(far) + 1e-3f;
  const float m = static_cast<float>(margin_px) + 1.0f;
  const float lo_u = -0.5f - m, hi_u = camera.width - 0.5f + m;
  const float lo_v = -0.5f - m, hi_v = camera.height - 0.5f + m;
  // The per-point test on the poses of `test` (indices into poses).
  const auto in_view = [&](size_t i, const std::vector<int>& test) {
    const Eigen::Vector4f p(cloud.positions[i].x(), cloud.positions[i].y(),
                            cloud.positions[i].z(), 1.0f);
    for (int t : test) {
      const Pose& pose = poses[t];
      const float z = pose.m.row(2).dot(p);
      if (!(z > lo_z && z < hi_z)) continue;
      const float u = pose.m.row(0).dot(p) / z;
      const float v = pose.m.row(1).dot(p) / z;
      if (u > lo_u && u < hi_u && v > lo_v && v < hi_v) return true;
    }
    return false;
  };
  std::vector<int> all_poses(poses.size());
  for (size_t t = 0; t < poses.size(); ++t) all_poses[t] = static_cast<int>(t);
  std::vector<size_t> keep;
  keep.reserve(cloud.size());
  // In front of the camera (lo_z > 0) the view is the intersection of six
  // half-spaces, a_j . p + b_j > 0 (z - lo_z, hi_z - z, u z - lo_u z, ...):
  // per group of consecutive points and pose, their extremes over the
  // group's bounding box (double) say whether every point of the group
  // passes the per-point test (all six minima above a margin that covers
  // the float test's rounding: then all its points are kept), none does
  // (a maximum below minus that margin: the pose is skipped) or it takes
  // the per-point test. The same indices as the per-point test alone.
  if (!(lo_z > 0.01f)) {
    for (size_t i = 0; i < cloud.size(); ++i)
      if (in_view(i, all_poses)) keep.push_back(i);
    return keep;
  }
  constexpr size_t kGroup = 256;
  // Margins: one pixel in u and v (times z in the affine form), 0.01 m in
  // z; the float test's rounding is far below both.
  constexpr double kPixelSlack = 1.0, kDepthSlack = 0.01;
  std::vector<int> partial;
  for (size_t g0 = 0; g0 < cloud.size(); g0 += kGroup) {
    const size_t g1 = std::min(cloud.size(), g0 + kGroup);
    Eigen::Vector3f lo, hi;
    if (!PointGroupBounds(cloud, g0, g1, &lo, &hi)) {
      for (size_t i = g0; i < g1; ++i)
        if (in_view(i, all_poses)) keep.push_back(i);
      continue;
    }
    const Eigen::Vector3d c = 0.5 * (lo.cast<double>() + hi.cast<double>());
    const Eigen::Vector3d e = 0.5 * (hi.cast<double>() - lo.cast<double>());
    bool whole = false;
    partial.clear();
    for (size_t t = 0; t < poses.size() && !whole; ++t) {
      const Eigen::Matrix<double, 3, 4>& md = poses[t].md;
      // a . p + b over the box: centre value -/+ |a| . e.
      const auto range = [&](const Eigen::Vector3d& a, double b) {
        const double mid = a.dot(c) + b, half = a.cwiseAbs().dot(e);
        return std::make_pair(mid - half, mid + half);
      };
      const Eigen::Vector3d az = md.row(2).head<3>().transpose();
      const double bz = md(2, 3);
      const Eigen::Vector3d au = md.row(0).head<3>().transpose();
      const double bu = md(0, 3);
      const Eigen::Vector3d av = md.row(1).head<3>().transpose();
      const double bv = md(1, 3);
      // z - lo_z, hi_z - z, u z - lo_u z, hi_u z - u z, likewise v; the
      // pixel slack scales with z (at least lo_z on this side of the test).
      const std::pair<double, double> f[6] = {
          range(az, bz - lo_z),
          range(-az, hi_z - bz),
          range(au - lo_u * az, bu - lo_u * bz),
          range(hi_u * az - au, hi_u * bz - bu),
          range(av - lo_v * az, bv - lo_v * bz),
          range(hi_v * az - av, hi_v * bz - bv)};
      // The pixel slack times the largest |z| of the box.
      const std::pair<double, double> z_range = range(az, bz);
      const double pixel_slack =
          kPixelSlack *
          std::max(std::abs(z_range.first), std::abs(z_range.second));
      bool outside = false, inside = true;
      for (int j = 0; j < 6; ++j) {
        const double s = j < 2 ? kDepthSlack : pixel_slack;
        if (f[j].second < -s) outside = true;
        if (!(f[j].first > s)) inside = false;
      }
      if (outside) continue;
      if (inside) {
        whole = true;
      } else {
        partial.push_back(static_cast<int>(t));
      }
    }
    if (whole) {
      for (size_t i = g0; i < g1; ++i) keep.push_back(i);
    } else if (!partial.empty()) {
      for (size_t i = g0; i < g1; ++i)
        if (in_view(i, partial)) keep.push_back(i);
    }
  }
  return keep;
}

std::vector<std::vector<Rigid3d>> RigFollowEdit(
    const RigScene& scene, const std::vector<Rigid3d>& edited_reference) {
  GEODRIVE_CHECK_INPUT(!scene.views.empty(), "rig scene has no cameras");
  const std::vector<Rigid3d>& reference = scene.views.front().scene_from_cam;
  GEODRIVE_CHECK_INPUT(edited_reference.size() == reference.size(),
                       "edited trajectory has ", edited_reference.size(),
                       " poses for ", reference.size(), " frames");
  std::vector<std::vector<Rigid3d>> out(scene.views.size());
  for (size_t i = 0; i < reference.size(); ++i) {
    const Rigid3d motion = edited_reference[i] * reference[i].Inverse();
    for (size_t k = 0; k < scene.views.size(); ++k)
      out[k].push_back(motion * scene.views[k].scene_from_cam.at(i));
  }
  return out;
}

std::vector<SeamAgreement> RigSeamAgreement(
    const std::vector<std::string>& channels,
    const std::vector<PinholeCamera>& cameras,
    const std::vector<Rigid3d>& scene_from_cam,
    const std::vector<cv::Mat>& depth) {
  const size_t n = channels.size();
  GEODRIVE_CHECK_INPUT(
      cameras.size() == n && scene_from_cam.size() == n && depth.size() == n,
      "seam check: ", n, " channels, ", cameras.size(), " cameras, ",
      scene_from_cam.size(), " poses, ", depth.size(), " depth images");
  // Overlap and agreement of the pixels of a seen from b.
  // Pixel (x, y) of a at depth d is q = R (d r) + t in b, r = ((x - cx) /
  // fx, (y - cy) / fy, 1) (PinholeCamera::Unproject), then projected by b
  // (PinholeCamera::Project); R and the rays are computed once.
  auto one_way = [&](size_t a, size_t b, SeamAgreement* s) {
    const Rigid3d b_from_a = scene_from_cam[b].Inverse() * scene_from_cam[a];
    const Eigen::Matrix3d rot = b_from_a.rotation.toRotationMatrix();
    const Eigen::Vector3d& t = b_from_a.translation;
    const PinholeCamera& ca = cameras[a];
    const PinholeCamera& cb = cameras[b];
    std::vector<double> ray_x(depth[a].cols);
    for (int x = 0; x < depth[a].cols; ++x) ray_x[x] = (x - ca.cx) / ca.fx;
    for (int y = 0; y < depth[a].rows; ++y) {
      const float* da = depth[a].ptr<float>(y);
      const double ray_y = (y - ca.cy) / ca.fy;
      // R r = column 0 * r_x + (column 1 * r_y + column 2).
      const Eigen::Vector3d row_part = rot.col(1) * ray_y + rot.col(2);
      for (int x = 0; x < depth[a].cols; ++x) {
        if (!(da[x] > 0)) continue;
        const double d = da[x];
        const Eigen::Vector3d q = (rot.col(0) * ray_x[x] + row_part) * d + t;
        if (q.z() <= 1e-6) continue;
        const Eigen::Vector2d uv(cb.fx * q.x() / q.z() + cb.cx,
                                 cb.fy * q.y() / q.z() + cb.cy);
        const int u = static_cast<int>(std::lround(uv.x()));
        const int v = static_cast<int>(std::lround(uv.y()));
        if (u < 0 || v < 0 || u >= depth[b].cols || v >= depth[b].rows)
          continue;
        const float db = depth[b].at<float>(v, u);
        if (!(db > 0)) continue;
        ++s->overlap_pixels;
        if (std::abs(db - q.z()) <= kSeamTolerance * q.z())
          ++s->agreeing_pixels;
      }
    }
  };
  std::vector<SeamAgreement> out;
  for (size_t a = 0; a < n; ++a) {
    for (size_t b = a + 1; b < n; ++b) {
      SeamAgreement s;
      s.camera_a = channels[a];
      s.camera_b = channels[b];
      one_way(a, b, &s);
      one_way(b, a, &s);
      if (s.overlap_pixels > 0) out.push_back(s);
    }
  }
  return out;
}

}  // namespace geodrive

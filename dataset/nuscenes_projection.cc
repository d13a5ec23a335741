#include "dataset/nuscenes_projection.h"

#include <algorithm>
#include <cmath>

#include "geometry/util/status.h"

namespace geodrive {
namespace {

// Devkit LidarPointCloud.rotate: float64 product of a float32 point, stored
// back as float32.
inline Eigen::Vector3f RotateF(const Eigen::Matrix3d& R,
                               const Eigen::Vector3f& p) {
  const Eigen::Vector3d q = R * p.cast<double>();
  return q.cast<float>();
}
// Devkit LidarPointCloud.translate, stored back as float32.
inline Eigen::Vector3f TranslateF(const Eigen::Vector3d& t,
                                  const Eigen::Vector3f& p) {
  return (p.cast<double>() + t).cast<float>();
}

// Devkit view_points(normalize=True) of one point plus the mask; appends when
// kept.
inline void KeepIfInImage(const Eigen::Vector3d& p,
                          const Eigen::Matrix3d& K,
                          int width,
                          int height,
                          const LidarProjectionOptions& options,
                          int32_t index,
                          LidarProjection* out) {
  const double depth = p.z();
  if (!(depth > options.min_dist)) return;
  const Eigen::Vector3d h = K * p;
  const double u = h.x() / h.z(), v = h.y() / h.z();
  bool inside;
  if (options.devkit_border) {
    inside = u > 1 && u < width - 1 && v > 1 && v < height - 1;
  } else {
    inside = u >= 0 && u < width && v >= 0 && v < height;
  }
  if (!inside) return;
  out->pixels.emplace_back(u, v);
  out->depths.push_back(depth);
  out->indices.push_back(index);
}

void CheckImage(const Eigen::Matrix3d& K, int width, int height) {
  GEODRIVE_CHECK_INPUT(width > 0 && height > 0,
                       "lidar projection: invalid image size ", width, "x",
                       height);
  GEODRIVE_CHECK_INPUT(K.allFinite() && K(0, 0) > 0 && K(1, 1) > 0,
                       "lidar projection: invalid camera intrinsic matrix");
}

double Cross(const Eigen::Vector2d& o,
             const Eigen::Vector2d& a,
             const Eigen::Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

// Andrew's monotone chain; counter-clockwise, no collinear points. 1 or 2
// points for degenerate.
std::vector<Eigen::Vector2d> ConvexHull(std::vector<Eigen::Vector2d> p) {
  std::sort(p.begin(), p.end(),
            [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
              return a.x() != b.x() ? a.x() < b.x() : a.y() < b.y();
            });
  p.erase(std::unique(p.begin(), p.end()), p.end());
  if (p.size() <= 2) return p;
  std::vector<Eigen::Vector2d> hull(2 * p.size());
  size_t k = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && Cross(hull[k - 2], hull[k - 1], p[i]) <= 0) --k;
    hull[k++] = p[i];
  }
  for (size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && Cross(hull[k - 2], hull[k - 1], p[i - 1]) <= 0) --k;
    hull[k++] = p[i - 1];
  }
  hull.resize(k - 1);
  return hull;
}

// Sutherland-Hodgman clip of a closed polygon against the axis-aligned
// half-plane sign * (p[axis] - bound) >= 0. Intersections are placed exactly on
// the line.
std::vector<Eigen::Vector2d> ClipAxis(const std::vector<Eigen::Vector2d>& poly,
                                      int axis,
                                      double bound,
                                      double sign) {
  std::vector<Eigen::Vector2d> out;
  const size_t n = poly.size();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d& a = poly[i];
    const Eigen::Vector2d& b = poly[(i + 1) % n];
    const double fa = sign * (a[axis] - bound), fb = sign * (b[axis] - bound);
    if (fa >= 0) out.push_back(a);
    if ((fa >= 0) != (fb >= 0)) {
      const double t = fa / (fa - fb);
      Eigen::Vector2d p = a + t * (b - a);
      p[axis] = bound;
      out.push_back(p);
    }
  }
  return out;
}

}  // namespace

void LidarProjectionOptions::Check() const {
  GEODRIVE_CHECK_INPUT(std::isfinite(min_dist),
                       "lidar projection: min_dist must be finite");
}

LidarProjection MapPointCloudToImage(
    const std::vector<Eigen::Vector3f>& points_in_lidar,
    const Rigid3d& ego_from_lidar,
    const Rigid3d& global_from_ego_at_lidar,
    const Rigid3d& global_from_ego_at_cam,
    const Rigid3d& ego_from_cam,
    const Eigen::Matrix3d& K,
    int width,
    int height,
    const LidarProjectionOptions& options) {
  options.Check();
  CheckImage(K, width, height);
  const Eigen::Matrix3d R1 = ego_from_lidar.rotation.toRotationMatrix();
  const Eigen::Matrix3d R2 =
      global_from_ego_at_lidar.rotation.toRotationMatrix();
  const Eigen::Matrix3d R3t =
      global_from_ego_at_cam.rotation.toRotationMatrix().transpose();
  const Eigen::Matrix3d R4t =
      ego_from_cam.rotation.toRotationMatrix().transpose();
  const Eigen::Vector3d t1 = ego_from_lidar.translation;
  const Eigen::Vector3d t2 = global_from_ego_at_lidar.translation;
  const Eigen::Vector3d t3 = -global_from_ego_at_cam.translation;
  const Eigen::Vector3d t4 = -ego_from_cam.translation;
  LidarProjection out;
  for (size_t i = 0; i < points_in_lidar.size(); ++i) {
    Eigen::Vector3f p = points_in_lidar[i];
    p = TranslateF(t1, RotateF(R1, p));   // 1. sensor -> ego at the lidar time
    p = TranslateF(t2, RotateF(R2, p));   // 2. -> global
    p = RotateF(R3t, TranslateF(t3, p));  // 3. -> ego at the camera time
    p = RotateF(R4t, TranslateF(t4, p));  // 4. -> camera
    KeepIfInImage(p.cast<double>(), K, width, height, options,
                  static_cast<int32_t>(i), &out);
  }
  return out;
}

LidarProjection ProjectLidarToImage(
    const std::vector<Eigen::Vector3f>& points_in_lidar,
    const Eigen::Matrix4d& cam_from_lidar,
    const Eigen::Matrix3d& K,
    int width,
    int height,
    const LidarProjectionOptions& options) {
  options.Check();
  CheckImage(K, width, height);
  GEODRIVE_CHECK_INPUT(cam_from_lidar.allFinite(),
                       "lidar projection: cam_from_lidar not finite");
  const Eigen::Matrix3d R = cam_from_lidar.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = cam_from_lidar.topRightCorner<3, 1>();
  LidarProjection out;
  for (size_t i = 0; i < points_in_lidar.size(); ++i) {
    const Eigen::Vector3d p = R * points_in_lidar[i].cast<double>() + t;
    KeepIfInImage(p, K, width, height, options, static_cast<int32_t>(i), &out);
  }
  return out;
}

LidarProjection MapPointCloudToImage(
    const Nuscenes& nusc,
    const std::vector<Eigen::Vector3f>& points_in_lidar,
    int32_t lidar_sd,
    int32_t cam_sd,
    const LidarProjectionOptions& options) {
  const PinholeCamera camera = nusc.Camera(cam_sd);
  return MapPointCloudToImage(points_in_lidar, nusc.EgoFromSensor(lidar_sd),
                              nusc.GlobalFromEgo(lidar_sd),
                              nusc.GlobalFromEgo(cam_sd),
                              nusc.EgoFromSensor(cam_sd), camera.K(),
                              camera.width, camera.height, options);
}

double IoU(const Box2d& a, const Box2d& b) {
  Box2d inter{std::max(a.xmin, b.xmin), std::max(a.ymin, b.ymin),
              std::min(a.xmax, b.xmax), std::min(a.ymax, b.ymax)};
  const double i = inter.Area();
  const double u = a.Area() + b.Area() - i;
  return u > 0 ? i / u : 0.0;
}

std::optional<Box2d> PostProcessCoords(
    const std::vector<Eigen::Vector2d>& points, int width, int height) {
  if (points.empty()) return std::nullopt;
  for (const auto& p : points) {
    if (!p.allFinite()) return std::nullopt;
  }
  std::vector<Eigen::Vector2d> poly = ConvexHull(points);
  poly = ClipAxis(poly, 0, 0.0, 1.0);
  poly = ClipAxis(poly, 0, width, -1.0);
  poly = ClipAxis(poly, 1, 0.0, 1.0);
  poly = ClipAxis(poly, 1, height, -1.0);
  if (poly.empty()) return std::nullopt;
  Box2d box{poly[0].x(), poly[0].y(), poly[0].x(), poly[0].y()};
  for (const auto& p : poly) {
    box.xmin = std::min(box.xmin, p.x());
    box.ymin = std::min(box.ymin, p.y());
    box.xmax = std::max(box.xmax, p.x());
    box.ymax = std::max(box.ymax, p.y());
  }
  return box;
}

std::optional<Box2d> BoxTo2d(const NuscenesBox& box_in_cam,
                             const Eigen::Matrix3d& K,
                             int width,
                             int height) {
  std::vector<Eigen::Vector2d> pixels;
  for (const Eigen::Vector3d& c : box_in_cam.Corners()) {
    if (!(c.z() > 0)) continue;
    const Eigen::Vector3d h = K * c;
    pixels.emplace_back(h.x() / h.z(), h.y() / h.z());
  }
  return PostProcessCoords(pixels, width, height);
}

std::vector<CameraBox> CameraBoxes2d(const Nuscenes& nusc, int32_t cam_sd) {
  const PinholeCamera camera = nusc.Camera(cam_sd);
  const Eigen::Matrix3d K = camera.K();
  const Rigid3d cam_from_global = nusc.WorldFromSensor(cam_sd).Inverse();
  std::vector<CameraBox> out;
  for (const NuscenesBox& box : nusc.GetBoxes(cam_sd)) {
    CameraBox cb;
    cb.box_in_cam = box.Transformed(cam_from_global);
    const auto b2 = BoxTo2d(cb.box_in_cam, K, camera.width, camera.height);
    if (!b2) continue;
    cb.box_2d = *b2;
    out.push_back(cb);
  }
  return out;
}

bool BoxInImage(const NuscenesBox& box_in_cam,
                const Eigen::Matrix3d& K,
                int width,
                int height,
                BoxVisibility visibility) {
  if (visibility == BoxVisibility::kNone) return true;
  int visible = 0;
  for (const Eigen::Vector3d& c : box_in_cam.Corners()) {
    const Eigen::Vector3d h = K * c;
    const double u = h.x() / h.z(), v = h.y() / h.z();
    if (u > 0 && u < width && v > 0 && v < height && c.z() > 1) ++visible;
  }
  return visibility == BoxVisibility::kAll ? visible == 8 : visible > 0;
}

}  // namespace geodrive

#include "render/footprint.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace geodrive {
namespace {

// A neighbour's depth counts as the same surface within this fraction.
constexpr float kSameSurface = 0.05f;
// Longest surface axis, in units of the camera-facing footprint s (a surface
// seen at 89.1 degrees; the render's magnification cap bounds the splat).
constexpr float kMaxAxis = 64.0f;

}  // namespace

void SetCaptureFootprints(const PinholeCamera& camera,
                          const Rigid3d& cam_from_world,
                          PointCloud* cloud,
                          bool surface_axes) {
  const Eigen::Matrix3d r =
      cam_from_world.rotation.normalized().toRotationMatrix();
  const Eigen::Vector3d& t = cam_from_world.translation;
  const size_t n = cloud->size();
  cloud->footprints.resize(n);
  cloud->footprint_u.clear();
  cloud->footprint_v.clear();
  if (!surface_axes) {  // the depths alone
    const Eigen::RowVector3d zrow = r.row(2);
    for (size_t i = 0; i < n; ++i)
      cloud->footprints[i] = CaptureFootprint(
          camera, zrow.dot(cloud->positions[i].cast<double>()) + t.z());
    return;
  }
  std::vector<Eigen::Vector3f> in_cam(n);
  for (size_t i = 0; i < n; ++i) {
    in_cam[i] = (r * cloud->positions[i].cast<double>() + t).cast<float>();
    cloud->footprints[i] = CaptureFootprint(camera, in_cam[i].z());
  }
  if (n == 0) return;
  // The cloud's depth map on the camera's grid (the nearest point per pixel),
  // held over the bounding box of the projected points only (an object's
  // points cover a small part of the image).
  const int w = camera.width, h = camera.height;
  const float fx = static_cast<float>(camera.fx),
              fy = static_cast<float>(camera.fy);
  const float cx = static_cast<float>(camera.cx),
              cy = static_cast<float>(camera.cy);
  std::vector<int32_t> px(n, -1), py(n, -1);
  int x0 = w, y0 = h, x1 = -1, y1 = -1;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f& p = in_cam[i];
    if (!(p.z() > 0)) continue;
    const float u = fx * p.x() / p.z() + cx, v = fy * p.y() / p.z() + cy;
    if (!(u > -0.5f && u < w - 0.5f && v > -0.5f && v < h - 0.5f)) continue;
    px[i] = std::min(w - 1, static_cast<int>(std::lround(u)));
    py[i] = std::min(h - 1, static_cast<int>(std::lround(v)));
    x0 = std::min(x0, px[i]), x1 = std::max(x1, px[i]);
    y0 = std::min(y0, py[i]), y1 = std::max(y1, py[i]);
  }
  cloud->footprint_u.assign(n, Eigen::Vector3f::Zero());
  cloud->footprint_v.assign(n, Eigen::Vector3f::Zero());
  if (x1 < 0) return;
  const int bw = x1 - x0 + 1, bh = y1 - y0 + 1;
  std::vector<float> depth(static_cast<size_t>(bw) * bh,
                           std::numeric_limits<float>::infinity());
  auto cell = [&](int x, int y) -> float& {
    return depth[static_cast<size_t>(y - y0) * bw + (x - x0)];
  };
  for (size_t i = 0; i < n; ++i) {
    if (px[i] < 0) continue;
    float& d = cell(px[i], py[i]);
    d = std::min(d, in_cam[i].z());
  }
  // The depth map's point at pixel (x, y) and its depth (0 = none).
  auto at = [&](int x, int y, Eigen::Vector3f* out) {
    if (x < x0 || y < y0 || x > x1 || y > y1) return 0.0f;
    const float d = cell(x, y);
    if (!std::isfinite(d)) return 0.0f;
    *out = Eigen::Vector3f((x - cx) / fx * d, (y - cy) / fy * d, d);
    return d;
  };
  // Displacement per pixel along (dx, dy). A plane's inverse depth is affine
  // in the pixel coordinates, whatever its slope: where the inverse depths
  // of the two neighbours and the point have a second difference within 10 %
  // of their first difference, the point is inside a planar patch (central
  // difference). Otherwise (a crease, a depth edge, one neighbour missing)
  // the side whose depth is within 5 % of the point's, the nearer in depth;
  // none: no axis.
  auto axis = [&](int x, int y, const Eigen::Vector3f& p, int dx, int dy,
                  Eigen::Vector3f* out) {
    Eigen::Vector3f before = Eigen::Vector3f::Zero(), after = before;
    const float db = at(x - dx, y - dy, &before);
    const float da = at(x + dx, y + dy, &after);
    const float z = p.z();
    if (db > 0 && da > 0) {
      const float id0 = 1 / z, ib = 1 / db, ia = 1 / da;
      const float first = std::max(std::abs(ia - id0), std::abs(id0 - ib));
      if (std::abs(ia - 2 * id0 + ib) <= 0.1f * first + 1e-4f * id0) {
        *out = 0.5f * (after - before);
        return true;
      }
    }
    const bool b_ok = db > 0 && std::abs(db - z) <= kSameSurface * z;
    const bool a_ok = da > 0 && std::abs(da - z) <= kSameSurface * z;
    if (a_ok && (!b_ok || std::abs(da - z) <= std::abs(db - z))) {
      *out = after - p;
    } else if (b_ok) {
      *out = p - before;
    } else {
      return false;
    }
    return true;
  };
  const Eigen::Matrix3f world_from_cam_r = r.transpose().cast<float>();
  for (size_t i = 0; i < n; ++i) {
    if (px[i] < 0 || cell(px[i], py[i]) != in_cam[i].z()) continue;
    const int x = px[i], y = py[i];
    // The point as its pixel's centre sees it (the depth map's surface).
    const float z = in_cam[i].z();
    const Eigen::Vector3f p((x - cx) / fx * z, (y - cy) / fy * z, z);
    Eigen::Vector3f eu, ev;
    if (!axis(x, y, p, 1, 0, &eu) || !axis(x, y, p, 0, 1, &ev)) continue;
    const float longest = kMaxAxis * cloud->footprints[i];
    if (eu.norm() > longest) eu *= longest / eu.norm();
    if (ev.norm() > longest) ev *= longest / ev.norm();
    cloud->footprint_u[i] = world_from_cam_r * eu;
    cloud->footprint_v[i] = world_from_cam_r * ev;
  }
}

}  // namespace geodrive

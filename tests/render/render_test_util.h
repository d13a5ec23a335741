#pragma once
// Small synthetic scenes for the renderer tests: a ray-cast textured scene
// (ground plane, a wall and a box) seen by a pinhole camera, and its pointmap
// unprojected with the same pixel-centre reading of K.

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <opencv2/core.hpp>

#include "geometry/camera.h"
#include "geometry/point_cloud.h"
#include "geometry/rigid3.h"

namespace geodrive {
namespace test {

// Same size, type and bytes (row by row, so views compare too).
inline bool SameBytes(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return false;
  for (int y = 0; y < a.rows; ++y) {
    if (std::memcmp(a.ptr(y), b.ptr(y), a.cols * a.elemSize()) != 0)
      return false;
  }
  return true;
}

// Procedural texture of a world point: checkerboard + stripes + a hash term,
// all channels distinct.
inline cv::Vec3b SceneColor(const Eigen::Vector3d& p) {
  const int cx = static_cast<int>(std::floor(p.x() * 2)),
            cy = static_cast<int>(std::floor(p.y() * 2));
  const int cz = static_cast<int>(std::floor(p.z() * 2));
  // Unsigned (wrapping) products: the signed ones overflowed (UBSan).
  const uint32_t h = static_cast<uint32_t>(cx) * 73856093u ^
                     static_cast<uint32_t>(cy) * 19349663u ^
                     static_cast<uint32_t>(cz) * 83492791u;
  const int checker = ((cx + cy + cz) & 1) ? 60 : 0;
  return cv::Vec3b(static_cast<uint8_t>(40 + checker + (h % 97)),
                   static_cast<uint8_t>(
                       30 + 120 * (0.5 + 0.5 * std::sin(p.x() * 3.0 + p.z()))),
                   static_cast<uint8_t>(20 + checker * 2 + ((h >> 8) % 53)));
}

// Ray-casts a static scene defined in WORLD coordinates: ground y = 1.6 (y
// down), a wall z = 40, and a box front face z = 12 with x in [-2, 1], y in
// [-0.5, 1.6]; wall points above y = -20 are sky (no depth). Returns z-depth in
// the camera (0 = miss) and the colour at each pixel. Pixel (i, j) is the ray
// through (i + centre_offset, j + centre_offset) in the camera's K (0 = the
// integer-index reading of K, 0.5 = K read as PyTorch3D screen coordinates).
struct RayCastScene {
  cv::Mat depth;  // CV_32F
  cv::Mat rgb;    // CV_8UC3
};
inline RayCastScene RayCast(const PinholeCamera& camera,
                            const Rigid3d& world_from_cam,
                            double centre_offset = 0.0) {
  RayCastScene s;
  s.depth = cv::Mat::zeros(camera.height, camera.width, CV_32F);
  s.rgb = cv::Mat::zeros(camera.height, camera.width, CV_8UC3);
  const Eigen::Vector3d o = world_from_cam.translation;
  for (int j = 0; j < camera.height; ++j) {
    for (int i = 0; i < camera.width; ++i) {
      // Ray with camera z = 1, so the ray parameter is the z-depth.
      const Eigen::Vector3d ray = camera.Unproject(
          Eigen::Vector2d(i + centre_offset, j + centre_offset), 1.0);
      const Eigen::Vector3d d = world_from_cam.rotation * ray;
      double best = std::numeric_limits<double>::infinity();
      bool wall = false;
      if (d.y() > 1e-9) {
        const double t = (1.6 - o.y()) / d.y();
        if (t > 0) best = std::min(best, t);
      }
      if (d.z() > 1e-9) {
        const double t = (40.0 - o.z()) / d.z();
        if (t > 0 && t < best) best = t, wall = true;
        const double tb = (12.0 - o.z()) / d.z();
        const Eigen::Vector3d pb = o + tb * d;
        if (tb > 0 && tb < best && pb.x() >= -2 && pb.x() <= 1 &&
            pb.y() >= -0.5 && pb.y() <= 1.6) {
          best = tb, wall = false;
        }
      }
      if (!(best < 100)) continue;
      const Eigen::Vector3d p = o + best * d;
      if (wall && p.y() < -20) continue;  // sky
      s.depth.at<float>(j, i) = static_cast<float>(best);
      s.rgb.at<cv::Vec3b>(j, i) = SceneColor(p);
    }
  }
  return s;
}

// Unprojects every pixel with depth > 0 (through (i + centre_offset, j +
// centre_offset) in K, as in RayCast) into world points coloured with the
// image.
inline PointCloud Unproject(const PinholeCamera& camera,
                            const Rigid3d& world_from_cam,
                            const cv::Mat& depth,
                            const cv::Mat& rgb,
                            double centre_offset = 0.0) {
  PointCloud cloud;
  for (int j = 0; j < depth.rows; ++j) {
    for (int i = 0; i < depth.cols; ++i) {
      const float z = depth.at<float>(j, i);
      if (!(z > 0)) continue;
      const Eigen::Vector3d p =
          world_from_cam *
          camera.Unproject(
              Eigen::Vector2d(i + centre_offset, j + centre_offset), z);
      cloud.positions.push_back(p.cast<float>());
      const cv::Vec3b c = rgb.at<cv::Vec3b>(j, i);
      cloud.colors.push_back(Color3u8(c[0], c[1], c[2]));
    }
  }
  return cloud;
}

// PSNR (dB) over the pixels where `where` is non-zero; returns +inf for
// identical pixels.
inline double MaskedPsnr(const cv::Mat& a,
                         const cv::Mat& b,
                         const cv::Mat& where) {
  double se = 0;
  int64_t n = 0;
  for (int j = 0; j < a.rows; ++j) {
    for (int i = 0; i < a.cols; ++i) {
      if (!where.at<uint8_t>(j, i)) continue;
      const cv::Vec3b x = a.at<cv::Vec3b>(j, i), y = b.at<cv::Vec3b>(j, i);
      for (int c = 0; c < 3; ++c)
        se += (double(x[c]) - y[c]) * (double(x[c]) - y[c]);
      n += 3;
    }
  }
  if (n == 0) return 0;
  if (se == 0) return std::numeric_limits<double>::infinity();
  return 10 * std::log10(255.0 * 255.0 / (se / n));
}

}  // namespace test
}  // namespace geodrive

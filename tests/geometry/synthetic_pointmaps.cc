#include "tests/geometry/synthetic_pointmaps.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <random>

#include "geometry/image_io.h"
#include "geometry/npy.h"
#include "geometry/trajectory_io.h"

namespace geodrive {
namespace test {
namespace {

// Slab test: smallest t > 0 with origin + t * dir inside the box.
bool IntersectBox(const Eigen::Vector3d& o,
                  const Eigen::Vector3d& d,
                  const Eigen::Vector3d& lo,
                  const Eigen::Vector3d& hi,
                  double* t_hit) {
  double t0 = 0, t1 = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    if (std::abs(d[k]) < 1e-15) {
      if (o[k] < lo[k] || o[k] > hi[k]) return false;
      continue;
    }
    double a = (lo[k] - o[k]) / d[k], b = (hi[k] - o[k]) / d[k];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
    if (t0 > t1) return false;
  }
  if (t0 <= 1e-9) return false;  // origin inside a box: ignore that box
  *t_hit = t0;
  return true;
}

double BoxSurfaceDistance(const Eigen::Vector3d& p, const SynthBox& b) {
  const Eigen::Vector3d outside =
      (b.lo - p).cwiseMax(Eigen::Vector3d::Zero()).cwiseMax(p - b.hi);
  if (outside.maxCoeff() > 0) return outside.norm();
  return std::min((p - b.lo).minCoeff(), (b.hi - p).minCoeff());
}

Eigen::Vector3d Texture(const Eigen::Vector3d& p, const Eigen::Vector3d& base) {
  const int parity =
      static_cast<int>(std::floor(p.x() * 2) + std::floor(p.y() * 2) +
                       std::floor(p.z() * 2)) &
      1;
  return base * (parity ? 1.0 : 0.7);
}

}  // namespace

Eigen::Vector3d SyntheticClip::VehicleOffset(double frame) const {
  return Eigen::Vector3d(options.vehicle_lateral_speed * frame, 0,
                         options.vehicle_speed * frame);
}

RayHit SyntheticClip::Cast(int frame, double u, double v) const {
  const Rigid3d& pose = world_from_cam[frame];
  const Eigen::Vector3d dir_cam((u - camera.cx) / camera.fx,
                                (v - camera.cy) / camera.fy, 1.0);
  const Eigen::Vector3d dir =
      pose.rotation * dir_cam;  // unit camera-z: t = z-depth
  const Eigen::Vector3d o = pose.translation;
  RayHit hit;
  hit.depth = std::numeric_limits<double>::infinity();
  double t = 0;
  for (size_t i = 0; i < static_boxes.size(); ++i) {
    if (IntersectBox(o, dir, static_boxes[i].lo, static_boxes[i].hi, &t) &&
        t < hit.depth) {
      hit.depth = t;
      hit.box = static_cast<int>(i);
      hit.dynamic = false;
    }
  }
  if (options.moving_vehicle) {
    const Eigen::Vector3d off = VehicleOffset(frame);
    if (IntersectBox(o, dir, vehicle.lo + off, vehicle.hi + off, &t) &&
        t < hit.depth) {
      hit.depth = t;
      hit.box = -2;
      hit.dynamic = true;
    }
  }
  hit.point_in_world = o + hit.depth * dir;
  return hit;
}

double SyntheticClip::DistanceToStaticSurface(const Eigen::Vector3d& p) const {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& b : static_boxes)
    best = std::min(best, BoxSurfaceDistance(p, b));
  return best;
}

SyntheticClip MakeSyntheticClip(const SyntheticClipOptions& options) {
  SyntheticClip clip;
  clip.options = options;
  clip.camera =
      PinholeCamera(options.focal, options.focal, options.width / 2.0,
                    options.height / 2.0, options.width, options.height);
  auto box = [](Eigen::Vector3d lo, Eigen::Vector3d hi, Eigen::Vector3d c) {
    return SynthBox{lo, hi, c};
  };
  clip.static_boxes = {
      box({-40, 1.5, -20}, {40, 2.5, 250},
          {0.45, 0.45, 0.5}),  // road slab, top at y = 1.5
      box({-16, -14, -20}, {-8, 1.5, 250}, {0.8, 0.6, 0.4}),  // left facades
      box({8, -14, -20}, {16, 1.5, 250}, {0.5, 0.7, 0.8}),    // right facades
      box({-40, -60, 70}, {40, 1.5, 72}, {0.6, 0.8, 0.6}),    // back wall
      box({-6.5, 0.0, 12}, {-4.5, 1.5, 16.5},
          {0.9, 0.2, 0.2}),  // parked car left
      box({4.5, 0.2, 20}, {6.5, 1.5, 24.5},
          {0.2, 0.3, 0.9}),  // parked car right
      box({-7.5, -3.0, 30}, {-7.0, 1.5, 30.5}, {0.9, 0.9, 0.2}),  // pole
  };
  clip.vehicle =
      box({-0.5, -1.5, 9}, {2.5, 1.5, 14}, {0.95, 0.95, 0.95});  // a van
  for (int t = 0; t < options.num_frames; ++t) {
    const double yaw =
        0.02 * std::sin(0.3 * t);  // radians about the y (down) axis
    const Eigen::Vector3d centre(0.4 * std::sin(0.2 * t),
                                 0.05 * std::sin(0.5 * t), options.speed * t);
    clip.world_from_cam.emplace_back(QuaternionFromAngleAxis(Eigen::Vector3d(
                                         0.01 * std::sin(0.4 * t), yaw, 0.0)),
                                     centre);
  }
  std::vector<float> all_depths;
  for (int t = 0; t < options.num_frames; ++t) {
    cv::Mat depth(options.height, options.width, CV_32FC1);
    cv::Mat rgb(options.height, options.width, CV_8UC3);
    cv::Mat mask(options.height, options.width, CV_8UC1, cv::Scalar(0));
    for (int v = 0; v < options.height; ++v) {
      for (int u = 0; u < options.width; ++u) {
        const RayHit hit = clip.Cast(t, u, v);
        depth.at<float>(v, u) = static_cast<float>(hit.depth);
        all_depths.push_back(static_cast<float>(hit.depth));
        const Eigen::Vector3d base =
            hit.dynamic ? clip.vehicle.color
                        : (hit.box >= 0 ? clip.static_boxes[hit.box].color
                                        : Eigen::Vector3d(0, 0, 0));
        const Eigen::Vector3d c = Texture(hit.point_in_world, base) * 255.0;
        rgb.at<cv::Vec3b>(v, u) = cv::Vec3b(cv::saturate_cast<uint8_t>(c.x()),
                                            cv::saturate_cast<uint8_t>(c.y()),
                                            cv::saturate_cast<uint8_t>(c.z()));
        if (hit.dynamic) mask.at<uint8_t>(v, u) = 255;
      }
    }
    clip.depth.push_back(depth);
    clip.rgb.push_back(rgb);
    clip.dynamic_mask.push_back(mask);
  }
  std::nth_element(all_depths.begin(),
                   all_depths.begin() + all_depths.size() / 2,
                   all_depths.end());
  clip.median_depth = all_depths[all_depths.size() / 2];
  return clip;
}

void WriteMonst3rFolder(const SyntheticClip& clip,
                        const std::string& dir,
                        const Monst3rWriteOptions& options) {
  std::filesystem::create_directories(dir);
  const int n = static_cast<int>(clip.world_from_cam.size());
  const int w = clip.options.width, h = clip.options.height;
  Trajectory traj;
  for (int t = 0; t < n; ++t) {
    traj.Add(t, options.world_from_cam.empty() ? clip.world_from_cam[t]
                                               : options.world_from_cam[t]);
  }
  WriteMonst3rTrajectory(dir + "/pred_traj.txt", traj);
  WriteMonst3rIntrinsics(dir + "/pred_intrinsics.txt",
                         std::vector<PinholeCamera>(n, clip.camera));
  std::mt19937 rng(options.seed);
  std::normal_distribution<double> gauss(0, 1);
  std::uniform_real_distribution<double> uni(0, 1);
  const cv::Mat kernel =
      cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3));
  for (int t = 0; t < n; ++t) {
    cv::Mat depth = clip.depth[t].clone();
    cv::Mat conf(h, w, CV_32FC1), init_conf(h, w, CV_32FC1);
    for (int v = 0; v < h; ++v) {
      for (int u = 0; u < w; ++u) {
        float& d = depth.at<float>(v, u);
        if (options.depth_noise > 0)
          d *= static_cast<float>(1 + options.depth_noise * gauss(rng));
        float c =
            static_cast<float>(1.3 + 2.2 * uni(rng));  // conf01 0.73 .. 0.97
        if (uni(rng) < options.bad_depth_fraction) {
          d *= static_cast<float>(0.6 + 0.8 * uni(rng));
          c = static_cast<float>(0.05 + 0.85 * uni(rng));
          init_conf.at<float>(v, u) = c;
          if (uni(rng) < 1.0 / 3.0) c = -std::numeric_limits<float>::infinity();
        } else {
          init_conf.at<float>(v, u) = c;
        }
        conf.at<float>(v, u) = c;
      }
    }
    char name[64];
    std::snprintf(name, sizeof(name), "/frame_%04d", t);
    WriteNpy(dir + name + ".npy",
             NpyArray::Float32({h, w}, depth.ptr<float>()));
    WriteImageRgb(dir + name + ".png", clip.rgb[t]);
    const std::string i = std::to_string(t);
    WriteNpy(dir + "/conf_" + i + ".npy",
             NpyArray::Float32({h, w}, conf.ptr<float>()));
    WriteNpy(dir + "/init_conf_" + i + ".npy",
             NpyArray::Float32({h, w}, init_conf.ptr<float>()));
    WriteImageRgb(dir + "/dynamic_mask_" + i + ".png", clip.dynamic_mask[t]);
    cv::Mat enlarged;
    cv::dilate(clip.dynamic_mask[t], enlarged, kernel);
    WriteImageRgb(dir + "/enlarged_dynamic_mask_" + i + ".png", enlarged);
    if (options.write_pointmaps) {
      cv::Mat pts(h, w, CV_32FC3);
      for (int v = 0; v < h; ++v) {
        for (int u = 0; u < w; ++u) {
          const double nu = options.pointmap_pixel_noise * gauss(rng);
          const double nv = options.pointmap_pixel_noise * gauss(rng);
          RayHit hit = clip.Cast(t, u + nu, v + nv);
          Eigen::Vector3d p = hit.point_in_world;
          if (hit.dynamic && options.dynamic_lag_frames > 0) {
            p -= clip.VehicleOffset(t) -
                 clip.VehicleOffset(t - options.dynamic_lag_frames);
          }
          if (uni(rng) < options.pointmap_outlier_fraction) {
            const Eigen::Vector3d dir(gauss(rng), gauss(rng), gauss(rng));
            p += dir.normalized() * (0.3 * hit.depth * uni(rng));
          }
          pts.at<cv::Vec3f>(v, u) =
              cv::Vec3f(static_cast<float>(p.x()), static_cast<float>(p.y()),
                        static_cast<float>(p.z()));
        }
      }
      WriteNpy(dir + "/pts3d_" + i + ".npy",
               NpyArray::Float32({h, w, 3}, pts.ptr<float>()));
    }
  }
}

Rigid3d PerturbPose(const Rigid3d& world_from_cam,
                    double angle_deg,
                    double translation,
                    uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0, 1);
  const Eigen::Vector3d axis =
      Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
  const Eigen::Vector3d dir =
      Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
  Rigid3d out = world_from_cam;
  out.rotation =
      (QuaternionFromAngleAxis(axis * angle_deg * M_PI / 180.0) * out.rotation)
          .normalized();
  out.translation += dir * translation;
  return out;
}

}  // namespace test
}  // namespace geodrive

#pragma once
// A small synthetic street for dynamic-editing tests and benchmarks, with exact
// ground truth.
//
// World frame: x forward along the street, y left, z up (nuScenes-like). Ground
// z = 0 (textured checker), facades at y = +-10 (height 12), an end wall at x =
// 120. Vehicles are textured boxes (body from `clearance` above the ground to
// the box top) whose annotated 3D box spans the ground to the top, like a
// nuScenes box. The camera (OpenCV axes, 1.6 high) drives forward at 0.5 per
// frame. The frame-0 cloud is the per-pixel ray-cast "pointmap" of camera 0
// (one point per pixel that hits something, kIntegerIndex pixel centres); true
// per-frame instance masks come from ray casting the true scene at frame t.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/point_cloud.h"
#include "geometry/rigid3.h"
#include "render/boxes.h"

namespace geodrive {
namespace test_scene {

struct Vehicle {
  std::string id;
  Eigen::Vector3d size{1.9, 4.5, 1.6};  // w, l, h
  double clearance = 0.2;
  Eigen::Vector3d color{200, 40, 40};
  std::vector<Box3d> boxes;  // per frame (annotated box: ground to top)
};

struct Scene {
  PinholeCamera camera;  // render / pointmap camera
  std::vector<Rigid3d> cam_from_world;
  std::vector<Vehicle> vehicles;
  PointCloud cloud;  // frame-0 pointmap cloud (colours, instance_ids = vehicle
                     // index or -1)
  cv::Mat frame0_rgb;  // ray-cast frame-0 image (CV_8UC3 RGB)
  BoxSequences
      boxes;  // 2D (in image_width x image_height) + 3D boxes of all vehicles
};

inline Box3d YawBox(const Eigen::Vector3d& size,
                    double x,
                    double y,
                    double yaw) {
  Box3d b;
  b.size = size;
  b.center = Eigen::Vector3d(x, y, size[2] / 2);
  b.rotation =
      Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
  return b;
}

inline uint32_t Hash(int a, int b, int c) {
  uint32_t h = static_cast<uint32_t>(a) * 73856093u ^
               static_cast<uint32_t>(b) * 19349663u ^
               static_cast<uint32_t>(c) * 83492791u;
  h ^= h >> 13;
  h *= 0x5bd1e995u;
  h ^= h >> 15;
  return h;
}

struct Hit {
  double s = std::numeric_limits<double>::infinity();
  int vehicle = -1;  // -1 = static surface, -2 = nothing
  Eigen::Vector3d point;
  Color3u8 color{0, 0, 0};
};

// Ray / body-box intersection (slab method in the box frame); returns the entry
// distance or inf.
inline double RayBody(const Vehicle& v,
                      const Box3d& box,
                      const Eigen::Vector3d& origin,
                      const Eigen::Vector3d& dir,
                      Eigen::Vector3d* local_hit) {
  const Eigen::Quaterniond inv = box.rotation.conjugate();
  const Eigen::Vector3d o = inv * (origin - box.center);
  const Eigen::Vector3d d = inv * dir;
  const Eigen::Vector3d h = box.HalfExtents();
  const Eigen::Vector3d lo(-h.x(), -h.y(), -h.z() + v.clearance);
  const Eigen::Vector3d hi(h.x(), h.y(), h.z());
  double t0 = 0, t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (std::abs(d[a]) < 1e-12) {
      if (o[a] < lo[a] || o[a] > hi[a])
        return std::numeric_limits<double>::infinity();
      continue;
    }
    double ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return std::numeric_limits<double>::infinity();
  }
  if (t0 <= 1e-9) return std::numeric_limits<double>::infinity();
  *local_hit = o + t0 * d;
  return t0;
}

// Casts a world ray against the scene with the vehicles at frame `frame`.
inline Hit CastRay(const Scene& scene,
                   int frame,
                   const Eigen::Vector3d& origin,
                   const Eigen::Vector3d& dir) {
  Hit hit;
  hit.vehicle = -2;
  auto consider_plane = [&](int axis, double value, int kind) {
    if (std::abs(dir[axis]) < 1e-12) return;
    const double s = (value - origin[axis]) / dir[axis];
    if (!(s > 1e-9) || s >= hit.s) return;
    const Eigen::Vector3d p = origin + s * dir;
    if (kind == 1 && (p.z() > 12 || p.z() < 0))
      return;  // facades / end wall height
    hit.s = s;
    hit.vehicle = -1;
    hit.point = p;
    if (kind == 0) {
      const int cx = static_cast<int>(std::floor(p.x())),
                cy = static_cast<int>(std::floor(p.y()));
      const uint32_t h = Hash(cx, cy, 1);
      const int base = ((cx + cy) & 1) ? 95 : 125;
      const bool lane = std::abs(std::abs(p.y()) - 1.75) < 0.1 && (cx % 3 != 0);
      const int g = lane ? 230 : base + static_cast<int>(h % 20);
      hit.color = Color3u8(g, g, lane ? 230 : g + 5);
    } else {
      const int cu =
          static_cast<int>(std::floor((axis == 0 ? p.y() : p.x()) / 1.5));
      const int cv = static_cast<int>(std::floor(p.z() / 0.8));
      const uint32_t h = Hash(cu, cv, 7 + axis);
      hit.color =
          Color3u8(120 + h % 100, 90 + (h >> 8) % 80, 70 + (h >> 16) % 60);
    }
  };
  consider_plane(2, 0.0, 0);
  consider_plane(1, 10.0, 1);
  consider_plane(1, -10.0, 1);
  consider_plane(0, 120.0, 1);
  for (size_t k = 0; k < scene.vehicles.size(); ++k) {
    const Vehicle& v = scene.vehicles[k];
    Eigen::Vector3d local = Eigen::Vector3d::Zero();
    const double s = RayBody(v, v.boxes[frame], origin, dir, &local);
    if (s < hit.s) {
      hit.s = s;
      hit.vehicle = static_cast<int>(k);
      hit.point = origin + s * dir;
      const int q = static_cast<int>(std::floor(local.x() / 0.45) +
                                     std::floor(local.y() / 0.45) +
                                     std::floor(local.z() / 0.45));
      const double shade = (q & 1) ? 1.0 : 0.7;
      hit.color = Color3u8(static_cast<uint8_t>(v.color[0] * shade),
                           static_cast<uint8_t>(v.color[1] * shade),
                           static_cast<uint8_t>(v.color[2] * shade));
    }
  }
  return hit;
}

// Per-pixel true vehicle index (-1 = none) at frame `frame`, and optionally the
// RGB image.
inline cv::Mat TrueInstanceMask(const Scene& scene,
                                int frame,
                                cv::Mat* rgb = nullptr) {
  const PinholeCamera& cam = scene.camera;
  cv::Mat mask(cam.height, cam.width, CV_32S, cv::Scalar(-1));
  if (rgb) *rgb = cv::Mat::zeros(cam.height, cam.width, CV_8UC3);
  const Rigid3d world_from_cam = scene.cam_from_world[frame].Inverse();
  for (int j = 0; j < cam.height; ++j) {
    for (int i = 0; i < cam.width; ++i) {
      const Eigen::Vector3d dir =
          world_from_cam.rotation * cam.Unproject(Eigen::Vector2d(i, j), 1.0);
      const Hit hit = CastRay(scene, frame, world_from_cam.translation, dir);
      mask.at<int32_t>(j, i) = hit.vehicle >= 0 ? hit.vehicle : -1;
      if (rgb && hit.vehicle != -2)
        rgb->at<cv::Vec3b>(j, i) =
            cv::Vec3b(hit.color[0], hit.color[1], hit.color[2]);
    }
  }
  return mask;
}

// The scene with the first `num_vehicles` (1..5) vehicles.
inline Scene MakeScene(int num_vehicles = 5,
                       int width = 512,
                       int height = 288,
                       int num_frames = 25) {
  Scene scene;
  const double f = 280.0 * width / 512.0;
  scene.camera =
      PinholeCamera(f, f, (width - 1) / 2.0, (height - 1) / 2.0, width, height);
  Eigen::Matrix3d world_from_cam_r;
  world_from_cam_r.col(0) = Eigen::Vector3d(0, -1, 0);  // x right
  world_from_cam_r.col(1) = Eigen::Vector3d(0, 0, -1);  // y down
  world_from_cam_r.col(2) = Eigen::Vector3d(1, 0, 0);   // z forward
  for (int t = 0; t < num_frames; ++t) {
    const Rigid3d world_from_cam(
        Eigen::Quaterniond(world_from_cam_r),
        Eigen::Vector3d(0.5 * t, 0.1 * std::sin(0.2 * t), 1.6));
    scene.cam_from_world.push_back(world_from_cam.Inverse());
  }
  struct Spec {
    const char* id;
    double x0, y, vx, yaw0, yaw_rate, r, g, b;
  };
  // v0: close range, same lane; v1: left lane, approached; v2 passes in front
  // of v3 (occlusion); v4: oncoming.
  const Spec specs[5] = {
      {"v0-close", 7.0, 3.5, 0.5, 0.0, 0.0, 210, 40, 40},
      {"v1-left", 30.0, 3.5, 0.25, 0.0, 0.0, 40, 90, 210},
      {"v2-front", 9.0, -3.2, 0.8, 0.0, 0.004, 230, 200, 40},
      {"v3-behind", 32.0, -4.8, 0.5, 0.0, 0.0, 40, 180, 70},
      {"v4-oncoming", 40.0, 0.0, -0.3, M_PI, 0.0, 200, 80, 200}};
  for (int k = 0; k < num_vehicles; ++k) {
    const Spec& s = specs[k];
    Vehicle v;
    v.id = s.id;
    v.color = Eigen::Vector3d(s.r, s.g, s.b);
    for (int t = 0; t < num_frames; ++t) {
      v.boxes.push_back(
          YawBox(v.size, s.x0 + s.vx * t, s.y, s.yaw0 + s.yaw_rate * t));
    }
    scene.vehicles.push_back(v);
  }
  // Frame-0 pointmap cloud.
  const Rigid3d world_from_cam0 = scene.cam_from_world[0].Inverse();
  scene.frame0_rgb = cv::Mat::zeros(height, width, CV_8UC3);
  for (int j = 0; j < height; ++j) {
    for (int i = 0; i < width; ++i) {
      const Eigen::Vector3d dir =
          world_from_cam0.rotation *
          scene.camera.Unproject(Eigen::Vector2d(i, j), 1.0);
      const Hit hit = CastRay(scene, 0, world_from_cam0.translation, dir);
      if (hit.vehicle == -2) continue;
      scene.cloud.positions.push_back(hit.point.cast<float>());
      scene.cloud.colors.push_back(hit.color);
      scene.cloud.instance_ids.push_back(hit.vehicle);
      scene.frame0_rgb.at<cv::Vec3b>(j, i) =
          cv::Vec3b(hit.color[0], hit.color[1], hit.color[2]);
    }
  }
  // Boxes file: 2D boxes in a 2x image (as nuScenes boxes live in 1600x900),
  // projected corners.
  scene.boxes.image_width = 2 * width;
  scene.boxes.image_height = 2 * height;
  scene.boxes.num_frames = num_frames;
  const PinholeCamera big = ResizeCamera(scene.camera, 2 * width, 2 * height);
  for (const Vehicle& v : scene.vehicles) {
    BoxSequence seq;
    seq.id = v.id;
    seq.category = "vehicle.car";
    for (int t = 0; t < num_frames; ++t) {
      BoxFrame bf;
      bf.frame = t;
      bf.box_3d = v.boxes[t];
      bf.box_2d = ProjectBox3d(v.boxes[t], big, scene.cam_from_world[t]);
      if (!bf.box_2d) continue;
      seq.frames.push_back(bf);
    }
    scene.boxes.instances.push_back(seq);
  }
  return scene;
}

// IoU of (a == ia) and (b == ib) for CV_32S masks; -1 when both are empty.
inline double MaskIoU(
    const cv::Mat& a, int ia, const cv::Mat& b, int ib, int* area_b = nullptr) {
  int64_t inter = 0, uni = 0, nb = 0;
  for (int j = 0; j < a.rows; ++j) {
    const int32_t* pa = a.ptr<int32_t>(j);
    const int32_t* pb = b.ptr<int32_t>(j);
    for (int i = 0; i < a.cols; ++i) {
      const bool x = pa[i] == ia, y = pb[i] == ib;
      inter += x && y;
      uni += x || y;
      nb += y;
    }
  }
  if (area_b) *area_b = static_cast<int>(nb);
  return uni == 0 ? -1.0 : double(inter) / double(uni);
}

}  // namespace test_scene
}  // namespace geodrive

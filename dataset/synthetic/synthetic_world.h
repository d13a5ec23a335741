#pragma once
// A procedural nuScenes-like street world with exact ground truth, rendered by
// analytic ray casting (no meshes, no rasteriser): every pixel's z-depth and
// instance id is exact.
//
// The world of one scene lives in a "street frame" (x along the main street, y
// to its left, z up, ground z = 0) which is placed in the nuScenes global frame
// by a per-scene yaw and offset. Contents: ground plane (asphalt with lane
// marks, stop lines and zebra crossings; grass beyond the blocks), a four-way
// intersection at x = intersection_x(), raised sidewalk blocks whose sides are
// the kerbs, building facades with window/brick textures, light poles,
// planters, sky, and seven vehicles (textured oriented boxes) driving along
// lanes: two lead vehicles in the ego lane (the car occludes the truck behind
// it), one that brakes to a stop at the stop line, one that crosses the
// intersection, two oncoming, one parked. The ego follows one of four
// manoeuvres.
//
// All public poses and boxes are in the nuScenes GLOBAL frame (metres); times
// are seconds since the start of the scene.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/rigid3.h"

namespace geodrive {

// Ego manoeuvre of a scene.
enum class EgoManeuver {
  kLaneChange,    // right lane -> left lane (overtakes the vehicle that stops),
                  // then straight
  kLeftTurn,      // slows down, turns left at the intersection (radius 10 m),
                  // speeds up
  kBrakeAndStop,  // brakes to a stop at the stop line, waits, optionally
                  // reverses ~3.75 m
  kStraight,      // straight through the intersection
};
std::string ToString(EgoManeuver maneuver);

struct SyntheticWorldOptions {
  // World seed; the scene index selects the scene within the seed's world.
  uint64_t seed = 7;
  int scene_index = 0;
  // Scene length in seconds (manoeuvre timings scale with it).
  double duration_s = 20.0;
  // Manoeuvre; -1 = by scene index (scene_index % 4 in the enum's order).
  int maneuver = -1;
  // kBrakeAndStop only: reverse a few metres after the stop (the paper's
  // out-of-distribution case).
  bool reverse_after_stop = true;

  // Empty if valid, else the reason.
  std::string Validate() const;
  bool Check() const { return Validate().empty(); }
};

// Instance values in rendered instance images.
constexpr uint16_t kStaticInstance = 0;    // ground, buildings, kerbs, poles
constexpr uint16_t kSkyInstance = 0xFFFF;  // no hit (depth 0)
// Vehicle i (0-based) has instance value i + 1.

// A vehicle's 3D box at one instant (nuScenes sample_annotation conventions).
struct VehicleBox {
  int id = 0;            // 0-based vehicle index (instance value id + 1)
  std::string category;  // nuScenes category, e.g. "vehicle.car"
  std::string
      attribute;  // "vehicle.moving", "vehicle.stopped" or "vehicle.parked"
  Eigen::Vector3d center =
      Eigen::Vector3d::Zero();  // box centre, global frame, metres
  Eigen::Quaterniond rotation =
      Eigen::Quaterniond::Identity();  // global_from_box (x fwd, z up)
  Eigen::Vector3d size_wlh =
      Eigen::Vector3d::Zero();  // width, length, height (m)
  double speed = 0;             // signed speed along the box x axis (m/s)
  bool moving = false;          // |speed| > 0.1 m/s
};

// One ray's first hit.
struct RayHit {
  double range = 0;  // distance along the (normalised) ray; 0 = no hit
  uint16_t instance = kSkyInstance;
  uint8_t intensity = 0;  // lidar-like reflectivity 0..255
};

// A rendered camera view. rgb: CV_8UC3 in RGB order; depth: CV_32F z-depth in
// metres along the optical axis (0 = sky); instance: CV_16U (kStaticInstance,
// vehicle id + 1, or kSkyInstance). Pixel (col u, row v) is the ray through the
// integer pixel index (PixelConvention::kIntegerIndex).
struct RenderedView {
  cv::Mat rgb, depth, instance;
};

// One lidar sweep in the sensor frame: points (x, y, z) metres, intensity
// 0..255, ring 0..31 (ring 0 = lowest beam), and the true instance of each
// point.
struct LidarSweep {
  std::vector<Eigen::Vector3f> points;
  std::vector<float> intensity;
  std::vector<float> ring;
  std::vector<uint16_t> instance;
};

struct LidarOptions {
  int num_rings = 32;
  double min_elevation_deg =
      -30.67;  // HDL-32E-like: -30.67 .. +10.67 deg, 1.33 deg steps
  double max_elevation_deg = 10.67;
  int azimuth_steps = 720;  // rays per ring per revolution
  double min_range_m = 1.0;
  double max_range_m = 100.0;
};

class SyntheticWorld {
 public:
  explicit SyntheticWorld(const SyntheticWorldOptions& options);
  ~SyntheticWorld();
  SyntheticWorld(const SyntheticWorld&) = delete;
  SyntheticWorld& operator=(const SyntheticWorld&) = delete;

  const SyntheticWorldOptions& options() const { return options_; }
  EgoManeuver maneuver() const { return maneuver_; }
  // Street frame placement in the global frame.
  const Rigid3d& global_from_street() const { return global_from_street_; }
  // x of the intersection centre in the street frame.
  double intersection_x() const { return intersection_x_; }

  // Ego pose (rear axle on the ground: z = 0, no roll/pitch) at time t.
  Rigid3d GlobalFromEgo(double t) const;
  // Signed ego speed (m/s) at time t.
  double EgoSpeed(double t) const;

  int NumVehicles() const;
  VehicleBox Vehicle(int id, double t) const;
  std::vector<VehicleBox> Vehicles(double t) const;

  // Renders a pinhole camera at pose global_from_cam with the vehicles at time
  // t (OpenMP inside).
  RenderedView RenderCamera(const PinholeCamera& camera,
                            const Rigid3d& global_from_cam,
                            double t) const;
  // First hit of one ray (origin and direction in the global frame; direction
  // need not be normalised). Tests every object (no culling): for checks, not
  // for bulk rendering.
  RayHit CastRay(const Eigen::Vector3d& origin,
                 const Eigen::Vector3d& direction,
                 double t,
                 double max_range = 1000.0) const;
  // z-depth (metres) seen through a sub-pixel location (kIntegerIndex), 0 for
  // sky.
  double CameraDepthAt(const PinholeCamera& camera,
                       const Rigid3d& global_from_cam,
                       double t,
                       const Eigen::Vector2d& pixel,
                       uint16_t* instance = nullptr) const;
  // Spinning lidar at pose global_from_lidar (nuScenes LIDAR_TOP axes: x right,
  // y forward, z up); all rays at time t (motion-compensated sweep).
  LidarSweep CastLidar(const Rigid3d& global_from_lidar,
                       double t,
                       const LidarOptions& lidar = {}) const;

  struct Impl;

 private:
  SyntheticWorldOptions options_;
  EgoManeuver maneuver_;
  Rigid3d global_from_street_;
  double intersection_x_ = 0;
  std::unique_ptr<Impl> impl_;
};

}  // namespace geodrive

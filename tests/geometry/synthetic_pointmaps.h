#pragma once
// A small analytic street for the geometry tests: axis-aligned boxes (road
// slab, facades, back wall, parked cars) and one moving vehicle, seen by a
// camera driving forward. Ray casting gives exact depth, world points, instance
// ids and dynamic masks; WriteMonst3rFolder writes the MonST3R file set (plus
// pts3d_{i}.npy pointmaps) with controlled noise, confidence and poses.
//
// World axes follow the first camera (OpenCV: x right, y down, z forward); the
// road surface is the plane y = 1.5 (camera height 1.5 units).

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/rigid3.h"

namespace geodrive {
namespace test {

struct SynthBox {
  Eigen::Vector3d lo, hi;
  Eigen::Vector3d color;  // base RGB in [0, 1]
};

struct SyntheticClipOptions {
  int width = 256, height = 144;
  int num_frames = 25;
  double focal = 230.0;  // px; principal point at (W/2, H/2), as MonST3R
  double speed = 0.6;    // camera forward motion per frame (units)
  bool moving_vehicle =
      true;  // the vehicle ahead moves; otherwise it does not exist
  double vehicle_speed = 0.9;          // per frame, along +z
  double vehicle_lateral_speed = 0.0;  // per frame, along +x
};

struct RayHit {
  double depth = 0;  // z-depth in the camera
  Eigen::Vector3d point_in_world = Eigen::Vector3d::Zero();
  int box = -1;  // index into boxes (-1 = none)
  bool dynamic = false;
};

struct SyntheticClip {
  SyntheticClipOptions options;
  PinholeCamera camera;
  std::vector<Rigid3d> world_from_cam;  // true poses
  std::vector<SynthBox> static_boxes;
  SynthBox vehicle;  // at frame 0
  // Per frame (true, noise-free).
  std::vector<cv::Mat> depth;         // CV_32FC1
  std::vector<cv::Mat> rgb;           // CV_8UC3
  std::vector<cv::Mat> dynamic_mask;  // CV_8UC1, 255 = vehicle
  double median_depth = 0;

  Eigen::Vector3d VehicleOffset(double frame) const;
  // Casts the ray of continuous pixel (u, v) (integer-index convention) in
  // frame `frame`.
  RayHit Cast(int frame, double u, double v) const;
  // Distance from a world point to the nearest static surface (box faces).
  double DistanceToStaticSurface(const Eigen::Vector3d& p) const;
};

SyntheticClip MakeSyntheticClip(const SyntheticClipOptions& options = {});

struct Monst3rWriteOptions {
  // Poses written to pred_traj.txt (empty = the true poses).
  std::vector<Rigid3d> world_from_cam;
  // Multiplicative Gaussian depth noise (sigma, relative).
  double depth_noise = 0.0;
  // Fraction of pixels with corrupted depth (x U(0.6, 1.4)) and low confidence
  // (log-conf in [0.05, 0.9], i.e. conf01 < 0.6); a third of them get -inf in
  // conf_{i}.npy.
  double bad_depth_fraction = 0.0;
  // pts3d_{i}.npy world pointmaps (O_t) for pose refinement.
  bool write_pointmaps = false;
  double pointmap_pixel_noise =
      0.0;  // px, Gaussian on the pixel the point comes from
  double pointmap_outlier_fraction =
      0.0;  // random points (uniform offsets up to 30% of depth)
  // Dynamic pixels' points placed where the vehicle was `lag` frames earlier
  // (static-world bias).
  double dynamic_lag_frames = 0;
  uint32_t seed = 1;
};

// Writes pred_traj.txt, pred_intrinsics.txt, frame_%04d.npy/png, conf_{i}.npy,
// init_conf_{i}.npy, dynamic_mask_{i}.png, enlarged_dynamic_mask_{i}.png (3x3
// dilation) and optionally pts3d_{i}.npy.
void WriteMonst3rFolder(const SyntheticClip& clip,
                        const std::string& dir,
                        const Monst3rWriteOptions& options = {});

// Applies a rotation of `angle_deg` about a random axis and a translation of
// length `translation` in a random direction to world_from_cam (seeded).
Rigid3d PerturbPose(const Rigid3d& world_from_cam,
                    double angle_deg,
                    double translation,
                    uint32_t seed);

}  // namespace test
}  // namespace geodrive

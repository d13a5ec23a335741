// Ground-truth properties of the synthetic world itself (renderer, lidar,
// motion scripts).

#include "dataset/synthetic/synthetic_world.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>

#include "dataset/synthetic/synthetic_dataset.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

SyntheticWorldOptions WorldOptions(EgoManeuver m, double duration = 20.0) {
  SyntheticWorldOptions o;
  o.seed = 11;
  o.scene_index = static_cast<int>(m);
  o.duration_s = duration;
  return o;
}

double YawOf(const Rigid3d& pose) {
  const Eigen::Vector3d x = pose.rotation * Eigen::Vector3d::UnitX();
  return std::atan2(x.y(), x.x());
}

double AngleDiff(double a, double b) {
  double d = a - b;
  while (d > M_PI) d -= 2 * M_PI;
  while (d < -M_PI) d += 2 * M_PI;
  return d;
}

TEST(SyntheticWorld, ManeuversDoWhatTheySay) {
  {  // Left turn: +90 deg of heading, ego stays at z = 0 with no roll/pitch.
    const SyntheticWorld w(WorldOptions(EgoManeuver::kLeftTurn));
    ASSERT_EQ(w.maneuver(), EgoManeuver::kLeftTurn);
    const double turn =
        AngleDiff(YawOf(w.GlobalFromEgo(20.0)), YawOf(w.GlobalFromEgo(0.0)));
    EXPECT_NEAR(turn, M_PI / 2, 1e-9);
    EXPECT_EQ(w.GlobalFromEgo(7.3).translation.z(), 0.0);
    const Eigen::Vector3d up =
        w.GlobalFromEgo(9.0).rotation * Eigen::Vector3d::UnitZ();
    EXPECT_NEAR(up.z(), 1.0, 1e-12);
  }
  {  // Brake and stop: speed reaches 0, then negative (reverse), then 0 again.
    const SyntheticWorld w(WorldOptions(EgoManeuver::kBrakeAndStop));
    double min_speed = 1e9;
    bool stopped = false;
    for (double t = 0; t <= 20.0; t += 0.05) {
      min_speed = std::min(min_speed, w.EgoSpeed(t));
      if (std::abs(w.EgoSpeed(t)) < 1e-9) stopped = true;
    }
    EXPECT_TRUE(stopped);
    EXPECT_NEAR(min_speed, -1.5, 1e-9);
    EXPECT_NEAR(w.EgoSpeed(20.0), 0.0, 1e-9);
    // The stop is before the stop line: the ego's front (3.9 m ahead of the
    // rear axle) is 9.6 m before the intersection centre.
    const Rigid3d street_from_ego =
        w.global_from_street().Inverse() * w.GlobalFromEgo(12.0);
    EXPECT_NEAR(street_from_ego.translation.x() + 3.9, w.intersection_x() - 9.6,
                1e-6);
  }
  {  // Lane change: 3.5 m to the left, heading back to the start heading.
    const SyntheticWorld w(WorldOptions(EgoManeuver::kLaneChange));
    const Rigid3d a = w.global_from_street().Inverse() * w.GlobalFromEgo(0.0);
    const Rigid3d b = w.global_from_street().Inverse() * w.GlobalFromEgo(20.0);
    EXPECT_NEAR(b.translation.y() - a.translation.y(), 3.5, 1e-9);
    EXPECT_NEAR(AngleDiff(YawOf(a), YawOf(b)), 0.0, 1e-9);
  }
}

TEST(SyntheticWorld, VehiclesStopCrossAndOcclude) {
  const SyntheticWorld w(WorldOptions(EgoManeuver::kStraight));
  ASSERT_EQ(w.NumVehicles(), 7);
  // Vehicle 3 stops: moving at the start, stopped at the end.
  EXPECT_EQ(w.Vehicle(3, 0.0).attribute, "vehicle.moving");
  EXPECT_EQ(w.Vehicle(3, 20.0).attribute, "vehicle.stopped");
  EXPECT_EQ(w.Vehicle(6, 5.0).attribute, "vehicle.parked");
  // Vehicle 4 crosses: it moves perpendicular to the main street (street y
  // changes sign).
  const Rigid3d street_from_global = w.global_from_street().Inverse();
  double y_min = 1e9, y_max = -1e9;
  for (double t = 0; t <= 20; t += 0.5) {
    const double y = (street_from_global * w.Vehicle(4, t).center).y();
    y_min = std::min(y_min, y), y_max = std::max(y_max, y);
  }
  EXPECT_LT(y_min, -10.0);
  EXPECT_GT(y_max, 10.0);
  // Occlusion: from CAM_FRONT at t = 0 the lead car (instance 1) hides part of
  // the truck (instance 2) behind it: the truck is seen, but only above the
  // car.
  const PinholeCamera cam = SyntheticCameraIntrinsics("CAM_FRONT", 320, 180);
  const Rigid3d pose =
      w.GlobalFromEgo(0.0) * SyntheticEgoFromSensor("CAM_FRONT");
  const RenderedView view = w.RenderCamera(cam, pose, 0.0);
  int car = 0, truck = 0, truck_below_car_top = 0, car_top_row = 1 << 30;
  for (int v = 0; v < view.instance.rows; ++v) {
    for (int u = 0; u < view.instance.cols; ++u) {
      const uint16_t i = view.instance.at<uint16_t>(v, u);
      if (i == 1) ++car, car_top_row = std::min(car_top_row, v);
    }
  }
  for (int v = 0; v < view.instance.rows; ++v) {
    for (int u = 0; u < view.instance.cols; ++u) {
      if (view.instance.at<uint16_t>(v, u) == 2) {
        ++truck;
        if (v > car_top_row + 1) ++truck_below_car_top;
      }
    }
  }
  std::cout << "CAM_FRONT 320x180 at t=0: car " << car << " px, truck " << truck
            << " px\n";
  EXPECT_GT(car, 50);
  EXPECT_GT(truck, 20);
  EXPECT_LT(truck_below_car_top, truck / 4);
}

// Every rendered pixel (tile-culled fast path) equals an independent, unculled
// ray cast through the same pixel; and a camera looking straight down sees the
// ground at exactly its height.
TEST(SyntheticWorld, RendererMatchesUnculledRayCastAndGroundDepthIsExact) {
  const SyntheticWorld w(WorldOptions(EgoManeuver::kLeftTurn));
  const PinholeCamera cam = SyntheticCameraIntrinsics("CAM_FRONT", 160, 90);
  for (double t : {0.0, 9.0}) {
    const Rigid3d pose =
        w.GlobalFromEgo(t) * SyntheticEgoFromSensor("CAM_FRONT");
    const RenderedView view = w.RenderCamera(cam, pose, t);
    double max_err = 0;
    int mismatched = 0;
    for (int v = 0; v < cam.height; ++v) {
      for (int u = 0; u < cam.width; ++u) {
        uint16_t inst;
        const double d =
            w.CameraDepthAt(cam, pose, t, Eigen::Vector2d(u, v), &inst);
        max_err = std::max(max_err, std::abs(d - view.depth.at<float>(v, u)) /
                                        std::max(1.0, d));
        if (inst != view.instance.at<uint16_t>(v, u)) ++mismatched;
      }
    }
    std::cout << "t=" << t
              << ": max relative depth difference render vs ray cast "
              << max_err << ", instance mismatches " << mismatched << "\n";
    EXPECT_LT(max_err, 1e-6);
    EXPECT_EQ(mismatched, 0);
  }
  // Looking straight down from 2 m above the intersection centre: every pixel
  // sees the ground.
  const Eigen::Vector3d above =
      w.global_from_street() * Eigen::Vector3d(w.intersection_x(), 0, 2);
  // Camera z (optical axis) = -global z; x = global x.
  Eigen::Matrix3d r;
  r << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  const RenderedView down =
      w.RenderCamera(SyntheticCameraIntrinsics("CAM_FRONT", 64, 36),
                     Rigid3d(Eigen::Quaterniond(r), above), 100.0);
  double max_dev = 0;
  for (int v = 0; v < down.depth.rows; ++v)
    for (int u = 0; u < down.depth.cols; ++u)
      max_dev = std::max(max_dev, std::abs(down.depth.at<float>(v, u) - 2.0));
  EXPECT_LT(max_dev, 1e-6);
}

TEST(SyntheticWorld, LidarRingsAndRangesAreExact) {
  const SyntheticWorld w(WorldOptions(EgoManeuver::kStraight));
  const Rigid3d pose =
      w.GlobalFromEgo(1.0) * SyntheticEgoFromSensor("LIDAR_TOP");
  LidarOptions lo;
  lo.azimuth_steps = 360;
  const LidarSweep sweep = w.CastLidar(pose, 1.0, lo);
  ASSERT_GT(sweep.points.size(), 5000u);
  double max_el_err = 0, max_range_err = 0;
  for (size_t k = 0; k < sweep.points.size(); k += 7) {
    const Eigen::Vector3d p = sweep.points[k].cast<double>();
    const double el = std::asin(p.z() / p.norm()) * 180 / M_PI;
    const double expected = -30.67 + (10.67 + 30.67) * sweep.ring[k] / 31.0;
    max_el_err = std::max(max_el_err, std::abs(el - expected));
    const RayHit hit = w.CastRay(pose.translation, pose.rotation * p, 1.0);
    max_range_err = std::max(max_range_err, std::abs(hit.range - p.norm()));
    EXPECT_GE(sweep.ring[k], 0.f);
    EXPECT_LE(sweep.ring[k], 31.f);
  }
  std::cout << "lidar: " << sweep.points.size()
            << " points, max elevation error " << max_el_err
            << " deg, max range error vs ray cast " << max_range_err << " m\n";
  EXPECT_LT(max_el_err, 1e-3);
  EXPECT_LT(max_range_err, 1e-4);  // float32 storage
}

TEST(SyntheticWorld, RejectsBadOptions) {
  SyntheticWorldOptions o;
  o.duration_s = 0.1;
  EXPECT_THROW(SyntheticWorld w(o), InputError);
  o.duration_s = 10;
  o.maneuver = 7;
  EXPECT_FALSE(o.Check());
}

}  // namespace
}  // namespace geodrive

// Scores against exact truth: BEV box distances in closed form, a candidate
// driven into the synthetic world's parked car collides when the geometry
// says, a lane change past it clears it by the analytic gap, and the logged
// ego of every demo clip is collision-free and over the road.

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "dataset/synthetic/synthetic_dataset.h"
#include "dataset/synthetic/synthetic_world.h"
#include "geometry/util/status.h"
#include "planning/candidates.h"
#include "planning/scores.h"
#include "tests/common/test_util.h"

namespace plan_scores_test {

using geodrive::Box3d;
using geodrive::Candidate;
using geodrive::Rigid3d;

Box3d BevBox(double x, double y, double yaw, double width, double length) {
  Box3d b;
  b.center = Eigen::Vector3d(x, y, 0.8);
  b.size = Eigen::Vector3d(width, length, 1.6);
  b.rotation =
      Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
  return b;
}

TEST(PlanScores, BevBoxDistanceMatchesClosedForms) {
  // Side by side along x: gap = 10 - (4 + 2) / 2.
  EXPECT_NEAR(
      geodrive::BevBoxDistance(BevBox(0, 0, 0, 2, 4), BevBox(10, 0, 0, 2, 2)),
      7.0, 1e-12);
  // Diagonal offset, axis-aligned: corner to corner.
  EXPECT_NEAR(
      geodrive::BevBoxDistance(BevBox(0, 0, 0, 2, 2), BevBox(5, 6, 0, 2, 2)),
      std::hypot(3.0, 4.0), 1e-12);
  // A square turned 45 degrees points a corner at a face: gap = d - 1 -
  // sqrt(2).
  EXPECT_NEAR(geodrive::BevBoxDistance(BevBox(0, 0, 0, 2, 2),
                                       BevBox(5, 0, M_PI / 4, 2, 2)),
              5 - 1 - std::sqrt(2.0), 1e-12);
  // Overlapping, touching, and a case the axis-aligned bounds would call
  // overlapping but the rotated rectangles are apart.
  EXPECT_EQ(geodrive::BevBoxDistance(BevBox(0, 0, 0.3, 2, 4),
                                     BevBox(1, 0.5, -0.2, 2, 4)),
            0.0);
  EXPECT_NEAR(
      geodrive::BevBoxDistance(BevBox(0, 0, 0, 2, 2), BevBox(2, 0, 0, 2, 2)),
      0.0, 1e-12);
  const double d = geodrive::BevBoxDistance(
      BevBox(0, 0, M_PI / 4, 0.2, 10), BevBox(2.5, -2.5, M_PI / 4, 0.2, 3));
  EXPECT_NEAR(d, 2.5 * std::sqrt(2.0) - 0.2, 1e-12);
  // Heights are not compared: a box 5 m up still meets the ego.
  Box3d high = BevBox(0, 0, 0, 2, 2);
  high.center.z() = 5;
  EXPECT_EQ(geodrive::BevBoxDistance(BevBox(0.5, 0, 0, 2, 2), high), 0.0);
}

// The synthetic world seen from the ego at time t0: every vehicle as an
// obstacle track at the clip's frame times, in ego0.
struct World {
  geodrive::SyntheticWorld world;
  double t0 = 0;
  Rigid3d ego0_from_global;
  explicit World(int scene, double start)
      : world([&] {
          geodrive::SyntheticWorldOptions o;
          o.scene_index = scene;
          return o;
        }()),
        t0(start),
        ego0_from_global(world.GlobalFromEgo(start).Inverse()) {}

  Box3d VehicleBox(int id, double t) const {
    const geodrive::VehicleBox v = world.Vehicle(id, t);
    Box3d b;
    b.center = v.center;
    b.size = v.size_wlh;
    b.rotation = v.rotation;
    return b.Transformed(ego0_from_global);
  }
  geodrive::PlanningScene Scene(const std::vector<double>& times) const {
    geodrive::PlanningScene scene;
    for (int id = 0; id < world.NumVehicles(); ++id) {
      geodrive::ObstacleTrack track;
      track.id = "vehicle-" + std::to_string(id);
      for (double t : times) {
        track.times.push_back(t - t0);
        track.boxes.push_back(VehicleBox(id, t));
      }
      scene.obstacles.push_back(track);
    }
    return scene;
  }
};

// Waypoints every 1/12 s along `path(t)` (ego origin in ego0 and yaw).
template <typename Path>
Candidate Sampled(const std::string& name, double duration, Path path) {
  Candidate c;
  c.name = name;
  c.source = name;
  for (int i = 0; i * (1.0 / 12) <= duration + 1e-9; ++i) {
    const double t = i / 12.0;
    const Eigen::Vector3d p = path(t);  // x, y, yaw
    c.ego0_from_ego.Add(t, geodrive::EgoPose(p.x(), p.y(), 0, p.z()));
  }
  return c;
}

TEST(PlanScores, ParkedCarIsHitWhenTheGeometrySaysAndALaneChangeClearsIt) {
  const World w(0, 2.0);
  // The parked car (vehicle 6) in ego0: its heading and centre.
  const Box3d car = w.VehicleBox(6, w.t0);
  ASSERT_EQ(w.world.Vehicle(6, w.t0).attribute, "vehicle.parked");
  const Eigen::Vector2d c = car.center.head<2>();
  const Eigen::Vector2d u =
      (car.rotation * Eigen::Vector3d::UnitX()).head<2>().normalized();
  const Eigen::Vector2d n(-u.y(), u.x());
  const double yaw = std::atan2(u.y(), u.x());
  const geodrive::PlanScoreOptions options;
  const double car_l = car.size.y(), car_w = car.size.x();
  // Driven along the car's axis from 30 m behind its centre at 8 m/s.
  const double v = 8, s0 = -30;
  const Candidate into = Sampled("into", 4.0, [&](double t) {
    const Eigen::Vector2d p = c + (s0 + v * t) * u;
    return Eigen::Vector3d(p.x(), p.y(), yaw);
  });
  // Contact when the ego centre (1.3 m ahead of its origin) is (4.6 + L) / 2
  // behind the car's centre.
  const double truth =
      (-(options.ego_length + car_l) / 2 - options.ego_center_ahead - s0) / v;
  // The lane change: a quintic shift of 3.6 m to the car's left over the
  // first 3 s, then parallel past it.
  const double shift = 3.6, tc = 3.0;
  const Candidate past = Sampled("past", 6.0, [&](double t) {
    const double q = std::min(t / tc, 1.0);
    const double d = shift * q * q * q * (10 - 15 * q + 6 * q * q);
    const double dd =
        t < tc ? shift * 30 * q * q * (1 - q) * (1 - q) / tc : 0.0;
    const Eigen::Vector2d p = c + (s0 + v * t) * u + d * n;
    return Eigen::Vector3d(p.x(), p.y(), yaw + std::atan2(dd, v));
  });
  std::vector<double> times;
  for (int k = 0; k < 73; ++k) times.push_back(w.t0 + k / 12.0);
  // The parked car alone: these straight paths through the intersection
  // would also meet the moving traffic, which is not what is measured here.
  geodrive::PlanningScene only_car;
  only_car.obstacles.push_back(w.Scene(times).obstacles[6]);
  const geodrive::PlanResult r =
      geodrive::ScoreCandidates(only_car, {into, past}, options);
  ASSERT_EQ(r.candidates.size(), 2u);
  const geodrive::CandidateScores& hit = r.candidates[0];
  EXPECT_TRUE(hit.collides);
  EXPECT_EQ(hit.first_collision_with, "vehicle-6");
  EXPECT_NEAR(hit.first_collision_time, truth, 1.0 / 12);  // one frame
  EXPECT_NEAR(hit.first_collision_time, truth, 2e-3);      // bisection
  EXPECT_EQ(hit.reject, geodrive::RejectReason::kCollision);
  // Before the contact, the distance at a waypoint is the gap along the axis.
  const geodrive::CandidateScores& clear = r.candidates[1];
  EXPECT_EQ(clear.reject, geodrive::RejectReason::kNone) << clear.reject_detail;
  EXPECT_NEAR(clear.min_box_distance, shift - (options.ego_width + car_w) / 2,
              0.01);
  EXPECT_EQ(clear.closest_obstacle, "vehicle-6");
  EXPECT_EQ(r.ranking[0], 1);
  EXPECT_EQ(clear.rank, 1);
  EXPECT_EQ(hit.rank, 2);
  // The distance at a time before contact: along-axis gap, to 1 cm.
  Candidate early = into;
  early.ego0_from_ego.timestamps.resize(12);  // up to 11/12 s
  early.ego0_from_ego.world_from_cam.resize(12);
  const geodrive::CandidateScores e =
      geodrive::ScoreCandidates(only_car, {early}).candidates[0];
  const double gap = -s0 - v * 11.0 / 12 - options.ego_center_ahead -
                     (options.ego_length + car_l) / 2;
  EXPECT_NEAR(e.min_box_distance, gap, 0.01);
  EXPECT_NEAR(e.min_box_distance_time, 11.0 / 12, 1e-12);
  EXPECT_THAT(r.BriefReport(),
              testing::HasSubstr("2 candidates: 1 accepted, 1 rejected "
                                 "(1 collision"));
}

// Static points of LiDAR sweeps (vehicle returns removed by their true
// instance) over [t0 - 1, t1] in ego0.
geodrive::PointCloud StaticCloud(const World& w, double t1) {
  geodrive::PointCloud cloud;
  const Rigid3d ego_from_lidar = geodrive::SyntheticEgoFromSensor("LIDAR_TOP");
  geodrive::LidarOptions lidar;
  lidar.azimuth_steps = 360;
  for (double t = w.t0 - 1.0; t <= t1 + 1e-9; t += 0.25) {
    const Rigid3d global_from_lidar = w.world.GlobalFromEgo(t) * ego_from_lidar;
    const geodrive::LidarSweep sweep =
        w.world.CastLidar(global_from_lidar, t, lidar);
    const Rigid3d ego0_from_lidar = w.ego0_from_global * global_from_lidar;
    for (size_t i = 0; i < sweep.points.size(); ++i) {
      if (sweep.instance[i] != geodrive::kStaticInstance) continue;
      cloud.positions.push_back(
          (ego0_from_lidar * sweep.points[i].cast<double>()).cast<float>());
    }
  }
  return cloud;
}

TEST(PlanScores, LoggedEgoOfEveryDemoClipIsClearAndOnTheRoad) {
  const geodrive::SyntheticDatasetOptions demo;  // 2 scenes, seed 7: the demo
  for (int scene = 0; scene < demo.num_scenes; ++scene) {
    const geodrive::SyntheticTimeline timeline =
        geodrive::MakeSyntheticTimeline(demo, scene);
    const std::vector<int64_t>& cam = timeline.channel_us.at("CAM_FRONT");
    for (int start : geodrive::SyntheticMonst3rClipStarts(
             demo, static_cast<int>(cam.size()))) {
      std::vector<double> times;
      for (int k = 0; k < geodrive::kSyntheticClipLength; ++k)
        times.push_back(timeline.Seconds(cam[start + k]));
      const World w(scene, times.front());
      geodrive::PlanningScene s = w.Scene(times);
      s.static_cloud = StaticCloud(w, times.back());
      Candidate logged;
      logged.name = "logged";
      logged.source = "logged";
      for (double t : times)
        logged.ego0_from_ego.Add(t - w.t0,
                                 w.ego0_from_global * w.world.GlobalFromEgo(t));
      s.logged = logged.ego0_from_ego;
      const geodrive::PlanResult r = geodrive::ScoreCandidates(s, {logged});
      const geodrive::CandidateScores& c = r.candidates[0];
      SCOPED_TRACE("scene " + std::to_string(scene) + " clip start " +
                   std::to_string(start));
      EXPECT_FALSE(c.collides) << c.reject_detail;
      EXPECT_GE(c.drivable_fraction, 0.99);
      EXPECT_GT(c.static_clearance, 0.5);
      EXPECT_NEAR(c.ade, 0.0, 1e-9);
      EXPECT_NE(c.reject, geodrive::RejectReason::kCollision);
      EXPECT_NE(c.reject, geodrive::RejectReason::kOffDrivable);
      EXPECT_GT(r.ground_points, 1000);
      EXPECT_GT(r.obstacle_points, 100);
    }
  }
}

// Off the road: a candidate that turns onto the sidewalk and into a facade
// loses its drivable fraction and its clearance.
TEST(PlanScores, DrivingIntoTheFacadeIsOffDrivable) {
  const World w(0, 2.0);
  std::vector<double> times;
  for (int k = 0; k < 25; ++k) times.push_back(w.t0 + k / 12.0);
  geodrive::PlanningScene s;
  s.static_cloud = StaticCloud(w, times.back());
  const Candidate right = Sampled("right", 2.0, [](double t) {
    return Eigen::Vector3d(2 + 2 * t, -9 * t, -1.35);  // ~9 m to the right
  });
  const geodrive::CandidateScores c =
      geodrive::ScoreCandidates(s, {right}).candidates[0];
  EXPECT_LT(c.static_clearance, 0.3);
  EXPECT_LT(c.drivable_fraction, 0.9);
  EXPECT_EQ(c.reject, geodrive::RejectReason::kOffDrivable) << c.reject_detail;
}

TEST(PlanScores, BadOptionsAndObstaclesAreInputErrors) {
  geodrive::PlanScoreOptions o;
  o.ego_length = -1;
  EXPECT_FALSE(o.Check());
  EXPECT_THROW(geodrive::ScoreCandidates({}, {}, o), geodrive::InputError);
  geodrive::PlanningScene s;
  s.obstacles.push_back(geodrive::ObstacleTrack{"x", "", {0.0}, {}});
  EXPECT_THROW(geodrive::ScoreCandidates(s, {}), geodrive::InputError);
  EXPECT_EQ(geodrive::ToString(geodrive::RejectReason::kOffDrivable),
            "off-drivable");
}

}  // namespace plan_scores_test

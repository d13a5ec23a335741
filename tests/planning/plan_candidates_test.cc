// Candidates: JSON-lines and trajectory-file reading, one clear error per bad
// candidate, finite-difference kinematics against closed forms, the lattice.

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "geometry/trajectory_json.h"
#include "geometry/util/status.h"
#include "planning/candidates.h"
#include "tests/common/test_util.h"

namespace plan_candidates_test {

using geodrive::Candidate;
using geodrive::InputError;

std::string Write(const std::string& name, const std::string& text) {
  static const std::string dir = geodrive::test::MakeTempDir("plan_candidates");
  const std::string path = dir + "/" + name;
  geodrive::test::WriteFile(path, text);
  return path;
}

// The message of the InputError `f` throws ("" if none).
template <typename F>
std::string ErrorOf(F f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(PlanCandidates, ReadsJsonlWaypointsAndYawFromMotion) {
  const std::string path =
      Write("straight.jsonl",
            "# t x y\n{\"t\": 0, \"x\": 0, \"y\": 0}\n{\"t\": 0.5, \"x\": 0, "
            "\"y\": 2}\n\n{\"t\": 1.0, \"x\": 1, \"y\": 2, \"yaw\": 0.25}\n");
  const std::vector<Candidate> c = geodrive::ReadCandidates(path);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].name, "straight");
  ASSERT_EQ(c[0].size(), 3u);
  const auto& poses = c[0].ego0_from_ego.world_from_cam;
  EXPECT_NEAR(geodrive::EgoYaw(poses[0]), M_PI / 2, 1e-12);  // towards +y
  EXPECT_NEAR(geodrive::EgoYaw(poses[1]), 0.0, 1e-12);       // towards +x
  EXPECT_NEAR(geodrive::EgoYaw(poses[2]), 0.25, 1e-12);      // given
  EXPECT_DOUBLE_EQ(c[0].ego0_from_ego.timestamps[2], 1.0);
}

TEST(PlanCandidates, CandidateFieldSplitsOneFileIntoSeveral) {
  const std::string path =
      Write("two.jsonl",
            "{\"candidate\": \"b\", \"t\": 0, \"x\": 0, \"y\": 0}\n"
            "{\"candidate\": \"a\", \"t\": 0, \"x\": 0, \"y\": 0}\n"
            "{\"candidate\": \"b\", \"t\": 1, \"x\": 5, \"y\": 0}\n"
            "{\"candidate\": \"a\", \"t\": 1, \"x\": 4, \"y\": 1}\n");
  const std::vector<Candidate> c = geodrive::ReadCandidatesJsonl(path);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].name, "b");
  EXPECT_EQ(c[1].name, "a");
  EXPECT_DOUBLE_EQ(c[1].ego0_from_ego.world_from_cam[1].translation.y(), 1.0);
}

TEST(PlanCandidates, WriteReadRoundTrip) {
  geodrive::LatticeOptions o;
  o.lateral_offsets = {1.75};
  o.accelerations = {0.5};
  o.yaw_rates = {0.05};
  const std::vector<Candidate> lattice = geodrive::SampleLattice(o);
  ASSERT_EQ(lattice.size(), 1u);
  const std::string path = Write("lattice.jsonl", "");
  geodrive::WriteCandidateJsonl(path, lattice[0]);
  const Candidate back = geodrive::ReadCandidates(path)[0];
  ASSERT_EQ(back.size(), lattice[0].size());
  for (size_t k = 0; k < back.size(); ++k) {
    EXPECT_NEAR((back.ego0_from_ego.world_from_cam[k].translation -
                 lattice[0].ego0_from_ego.world_from_cam[k].translation)
                    .norm(),
                0.0, 1e-6);
  }
}

// A camera trajectory file becomes ego poses through the mounting: a camera
// moving along its own z axis moves the ego along x.
TEST(PlanCandidates, TrajectoryFileIsPutOnTheEgo) {
  geodrive::Trajectory cam;
  const geodrive::Rigid3d start(
      geodrive::QuaternionFromAngleAxis(Eigen::Vector3d(0.1, 0.2, 0.3)),
      Eigen::Vector3d(10, 20, 30));
  for (int i = 0; i < 5; ++i) {
    cam.Add(100.0 + 0.5 * i,
            start * geodrive::Rigid3d(Eigen::Quaterniond::Identity(),
                                      Eigen::Vector3d(0, 0, 2.0 * i)));
  }
  const std::string path = Write("cam.json", "");
  geodrive::WriteTrajectoryJson(path, cam);
  const Candidate c = geodrive::ReadCandidates(path)[0];
  ASSERT_EQ(c.size(), 5u);
  EXPECT_DOUBLE_EQ(c.ego0_from_ego.timestamps[0], 0.0);
  EXPECT_NEAR(c.ego0_from_ego.timestamps[4], 2.0, 1e-12);
  EXPECT_NEAR(
      (c.ego0_from_ego.world_from_cam[4].translation - Eigen::Vector3d(8, 0, 0))
          .norm(),
      0.0, 1e-9);
  EXPECT_NEAR(geodrive::EgoYaw(c.ego0_from_ego.world_from_cam[4]), 0.0, 1e-9);
}

TEST(PlanCandidates, BadCandidatesGiveOneClearError) {
  // Empty.
  EXPECT_EQ(ErrorOf([&] {
              geodrive::ReadCandidates(Write("empty.jsonl", "\n# none\n"));
            }),
            Write("empty.jsonl", "\n# none\n") + ": no waypoints");
  // NaN: not JSON; a NaN in a text trajectory is refused by its reader.
  const std::string nan = Write("nan.jsonl",
                                "{\"t\": 0, \"x\": 0, \"y\": 0}\n"
                                "{\"t\": 0.1, \"x\": NaN, \"y\": 0}\n");
  EXPECT_THAT(ErrorOf([&] { geodrive::ReadCandidates(nan); }),
              testing::HasSubstr(nan + ":2: malformed JSON"));
  const std::string tum_nan =
      Write("nan.txt", "0 0 0 0 0 0 0 1\n0.1 nan 0 0 0 0 0 1\n");
  EXPECT_THAT(ErrorOf([&] { geodrive::ReadCandidates(tum_nan); }),
              testing::HasSubstr(tum_nan));
  // Non-monotonic time.
  const std::string back = Write("back.jsonl",
                                 "{\"t\": 0, \"x\": 0, \"y\": 0}\n"
                                 "{\"t\": 0.5, \"x\": 1, \"y\": 0}\n"
                                 "{\"t\": 0.4, \"x\": 2, \"y\": 0}\n");
  EXPECT_EQ(ErrorOf([&] { geodrive::ReadCandidates(back); }),
            back +
                ":3: time 0.4 s is not after the previous waypoint's 0.5 s "
                "(times must increase strictly)");
  // A jump of 100 m in 0.1 s.
  const std::string jump = Write("jump.jsonl",
                                 "{\"t\": 0, \"x\": 0, \"y\": 0}\n"
                                 "{\"t\": 0.1, \"x\": 1, \"y\": 0}\n"
                                 "{\"t\": 0.2, \"x\": 101, \"y\": 0}\n");
  EXPECT_EQ(ErrorOf([&] { geodrive::ReadCandidates(jump); }),
            jump + ":3: jumps 100 m in 0.1 s (1000 m/s > the limit 100 m/s)");
  // A missing field and a single waypoint.
  const std::string no_y = Write("noy.jsonl", "{\"t\": 0, \"x\": 0}\n");
  EXPECT_EQ(ErrorOf([&] { geodrive::ReadCandidates(no_y); }),
            no_y + ":1: missing \"y\"");
  const std::string one =
      Write("one.jsonl", "{\"t\": 0, \"x\": 0, \"y\": 0}\n");
  EXPECT_EQ(ErrorOf([&] { geodrive::ReadCandidates(one); }),
            one + ": 1 waypoint(s), at least 2 needed");
  // Hostile: nesting 100,000 deep is one error, not a stack overflow.
  const std::string deep = Write("deep.jsonl", std::string(100000, '[') + "\n");
  EXPECT_THAT(ErrorOf([&] { geodrive::ReadCandidates(deep); }),
              testing::HasSubstr(deep + ":1: JSON nested more than 64"));
  // In memory: a NaN pose names the candidate and the waypoint.
  Candidate c;
  c.source = "mine";
  c.ego0_from_ego.Add(0, geodrive::EgoPose(0, 0, 0, 0));
  c.ego0_from_ego.Add(0.1, geodrive::EgoPose(std::nan(""), 0, 0, 0));
  EXPECT_EQ(ErrorOf([&] { geodrive::ValidateCandidate(c); }),
            "mine: waypoint 1: position or rotation is not finite");
}

// Uniform circular motion: curvature 1/R, lateral acceleration v^2/R, no
// longitudinal acceleration or jerk (finite differences of a circle sampled
// uniformly are exact up to the chord factor, checked to 1e-3).
TEST(PlanCandidates, KinematicsOfACircleAndAConstantAcceleration) {
  const double r = 20, v = 10, dt = 0.05;
  Candidate c;
  for (int i = 0; i <= 40; ++i) {
    const double th = v * i * dt / r;
    c.ego0_from_ego.Add(
        i * dt,
        geodrive::EgoPose(r * std::sin(th), r * (1 - std::cos(th)), 0, th));
  }
  const geodrive::CandidateKinematics k = geodrive::ComputeKinematics(c);
  EXPECT_NEAR(k.max_curvature, 1 / r, 1e-3 / r);
  EXPECT_NEAR(k.max_lat_accel, v * v / r, 1e-3 * v * v / r);
  EXPECT_NEAR(k.max_lon_accel, 0.0, 1e-9);
  EXPECT_NEAR(k.max_lat_jerk, 0.0, 1e-6);
  EXPECT_NEAR(k.path_length, v * 40 * dt, 1e-3);

  Candidate a;  // x = 3 t + 0.5 * 2 t^2: exact for a quadratic
  for (int i = 0; i <= 10; ++i) {
    const double t = 0.1 * i;
    a.ego0_from_ego.Add(t, geodrive::EgoPose(3 * t + t * t, 0, 0, 0));
  }
  const geodrive::CandidateKinematics ka = geodrive::ComputeKinematics(a);
  EXPECT_NEAR(ka.max_lon_accel, 2.0, 1e-9);
  EXPECT_NEAR(ka.max_lon_jerk, 0.0, 1e-6);
  EXPECT_NEAR(ka.max_speed, 5.0 - 0.1, 1e-9);  // last segment's mean speed
  EXPECT_EQ(geodrive::KinematicEnvelope().Violation(ka), "");
  geodrive::KinematicEnvelope tight;
  tight.max_lon_accel = 1.5;
  EXPECT_EQ(tight.Violation(ka), "longitudinal acceleration 2 m/s^2 > 1.5");
}

TEST(PlanCandidates, LatticeStaysInTheEnvelopeAndIsDeterministic) {
  geodrive::LatticeOptions o;
  o.initial_speed = 8;
  const std::vector<Candidate> all = geodrive::SampleLattice(o);
  ASSERT_FALSE(all.empty());
  EXPECT_LE(all.size(), 5u * 4u * 3u);
  for (const Candidate& c : all) {
    EXPECT_EQ(o.envelope.Violation(geodrive::ComputeKinematics(c)), "")
        << c.name;
    EXPECT_EQ(c.size(), 25u);
    EXPECT_NO_THROW(geodrive::ValidateCandidate(c));
  }
  // A lane change to +3.5 m ends 3.5 m to the left.
  bool found = false;
  for (const Candidate& c : all) {
    if (c.name != "lat+3.50_acc+0.0_yaw+0.00") continue;
    found = true;
    const auto& last = c.ego0_from_ego.world_from_cam.back();
    EXPECT_NEAR(last.translation.y(), 3.5, 1e-12);
    EXPECT_NEAR(last.translation.x(), 8 * 12.0, 1e-9);
    EXPECT_NEAR(geodrive::EgoYaw(last), 0.0, 1e-12);
  }
  EXPECT_TRUE(found);
  o.max_candidates = 7;
  const std::vector<Candidate> some = geodrive::SampleLattice(o);
  ASSERT_EQ(some.size(), 7u);
  EXPECT_EQ(some[0].name, "lat+0.00_acc+0.0_yaw+0.00");
  const std::vector<Candidate> again = geodrive::SampleLattice(o);
  for (size_t i = 0; i < some.size(); ++i)
    EXPECT_EQ(some[i].name, again[i].name);
  // A tight envelope rejects the sharp cells.
  o.max_candidates = 0;
  o.envelope.max_lat_accel = 0.5;
  EXPECT_LT(geodrive::SampleLattice(o).size(), all.size());
  o.dt_s = 0;
  EXPECT_THROW(geodrive::SampleLattice(o), InputError);
}

}  // namespace plan_candidates_test

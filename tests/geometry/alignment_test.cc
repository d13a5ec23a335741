#include "geometry/alignment.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

// A curving drive of n camera poses (metres), 12 Hz.
Trajectory CurvedDrive(int n) {
  Trajectory t;
  for (int i = 0; i < n; ++i) {
    const double s = i / 12.0, yaw = 0.15 * s;
    t.Add(s, Rigid3d(QuaternionFromAngleAxis(Eigen::Vector3d(0, yaw, 0)),
                     Eigen::Vector3d(8.0 * std::sin(yaw) * 5, 0.1 * std::sin(3 * s),
                                     8.0 * s + 0.5 * s * s)));
  }
  return t;
}

Sim3d RandomSim3(std::mt19937& rng) {
  std::normal_distribution<double> n(0, 1);
  std::uniform_real_distribution<double> u(0.2, 5.0);
  return Sim3d(u(rng), Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized(),
               Eigen::Vector3d(n(rng), n(rng), n(rng)) * 20.0);
}

TEST(Alignment, Sim3RecoversRandomSimilarityExactly) {
  auto& rng = test::Rng();
  const Trajectory ref = CurvedDrive(25);
  for (int trial = 0; trial < 10; ++trial) {
    const Sim3d est_from_ref = RandomSim3(rng);
    const Trajectory est = TransformTrajectory(est_from_ref, ref);
    const TrajectoryErrorReport r = EvaluateTrajectory(est, ref, AlignmentType::kSim3);
    const Sim3d expected = est_from_ref.Inverse();
    EXPECT_NEAR(r.ref_from_est.scale, expected.scale, 1e-6 * expected.scale);
    EXPECT_LT(RotationDistanceDeg(r.ref_from_est.rotation, expected.rotation), 1e-6);
    EXPECT_LT((r.ref_from_est.translation - expected.translation).norm(), 1e-6);
    EXPECT_LT(r.ate.max, 1e-6);
    EXPECT_LT(r.rpe_trans.max, 1e-6);
  }
}

TEST(Alignment, Se3AndScaleVariants) {
  auto& rng = test::Rng();
  const Trajectory ref = CurvedDrive(25);
  Sim3d rigid = RandomSim3(rng);
  rigid.scale = 1.0;
  const TrajectoryErrorReport se3 =
      EvaluateTrajectory(TransformTrajectory(rigid, ref), ref, AlignmentType::kSE3);
  EXPECT_LT(se3.ate.max, 1e-6);
  EXPECT_DOUBLE_EQ(se3.ref_from_est.scale, 1.0);
  // A pure scale: scale-only alignment recovers it, SE(3) cannot.
  const Sim3d scale_only(2.5, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  const Trajectory scaled = TransformTrajectory(scale_only, ref);
  const TrajectoryErrorReport s = EvaluateTrajectory(scaled, ref, AlignmentType::kScale);
  EXPECT_NEAR(s.ref_from_est.scale, 0.4, 1e-9);
  EXPECT_LT(s.ate.max, 1e-6);
  EXPECT_GT(EvaluateTrajectory(scaled, ref, AlignmentType::kSE3).ate.rms, 1.0);
  // No alignment: the ATE is the raw distance.
  const TrajectoryErrorReport none = EvaluateTrajectory(scaled, ref, AlignmentType::kNone);
  EXPECT_NEAR(none.ate.max, 1.5 * ref.world_from_cam.back().translation.norm(), 1e-9);
}

TEST(Alignment, AteMatchesInjectedNoise) {
  auto& rng = test::Rng();
  const Trajectory ref = CurvedDrive(400);
  const Sim3d est_from_ref = RandomSim3(rng);
  Trajectory est = ref;
  // Isotropic Gaussian position noise of sigma per axis -> E||e||^2 = 3 sigma^2.
  const double sigma = 0.05;
  std::normal_distribution<double> n(0, sigma);
  for (auto& p : est.world_from_cam) p.translation += Eigen::Vector3d(n(rng), n(rng), n(rng));
  est = TransformTrajectory(est_from_ref, est);
  const TrajectoryErrorReport r = EvaluateTrajectory(est, ref, AlignmentType::kSim3);
  std::printf("injected sigma %.3f m per axis -> ATE rms %.4f m (expected ~%.4f)\n", sigma,
              r.ate.rms, sigma * std::sqrt(3.0));
  EXPECT_NEAR(r.ate.rms, sigma * std::sqrt(3.0), 0.1 * sigma * std::sqrt(3.0));
}

TEST(Alignment, RpeMeasuresRelativeMotionError) {
  // Hand-computed: a 1 m step forward in the reference, 1.1 m in the estimate -> RPE 0.1 m.
  Trajectory ref, est;
  for (int i = 0; i < 4; ++i) {
    ref.Add(i, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, i)));
    est.Add(i, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 1.1 * i)));
  }
  const TrajectoryErrorReport r = EvaluateTrajectory(est, ref, AlignmentType::kNone);
  EXPECT_NEAR(r.rpe_trans.mean, 0.1, 1e-12);
  EXPECT_NEAR(r.ate.max, 0.3, 1e-12);
  EXPECT_NEAR(r.ate.median, 0.15, 1e-12);  // errors 0, .1, .2, .3
}

TEST(Alignment, BadInput) {
  const Trajectory a = CurvedDrive(5), b = CurvedDrive(6);
  EXPECT_THROW(EvaluateTrajectory(a, b, AlignmentType::kSim3), InputError);
  EXPECT_THROW(AlignPoints({{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}},
                           AlignmentType::kSim3),
               InputError);
  EXPECT_THROW(ParseAlignmentType("affine"), InputError);
  EXPECT_EQ(ParseAlignmentType("sim3"), AlignmentType::kSim3);
}

}  // namespace
}  // namespace geodrive

// ADE/FDE: hand-computed cases and recovery of a known similarity.

#include "eval/trajectory_metrics.h"

#include <gtest/gtest.h>

#include <random>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

Trajectory FromCentres(const std::vector<Eigen::Vector3d>& centres) {
  Trajectory t;
  for (size_t i = 0; i < centres.size(); ++i) {
    t.Add(0.1 * i, Rigid3d(Eigen::Quaterniond::Identity(), centres[i]));
  }
  return t;
}

TEST(TrajectoryMetrics, HandComputedNoAlignment) {
  const Trajectory gt =
      FromCentres({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}});
  const Trajectory pred =
      FromCentres({{0, 0, 0}, {1, 1, 0}, {2, 0, 2}, {3, 3, 4}});
  const TrajectoryErrors e = ComputeTrajectoryErrors(pred, gt);
  EXPECT_DOUBLE_EQ(e.ade, (0 + 1 + 2 + 5) / 4.0);
  EXPECT_DOUBLE_EQ(e.fde, 5.0);
  EXPECT_DOUBLE_EQ(e.rmse, std::sqrt((0 + 1 + 4 + 25) / 4.0));
  const TrajectoryErrors x100 = e.Scaled(100);
  EXPECT_DOUBLE_EQ(x100.ade, 200.0);
  EXPECT_DOUBLE_EQ(x100.fde, 500.0);
}

// Finite positions whose errors overflow give an error, not ADE = inf
// written as "not computed".
TEST(TrajectoryMetrics, OverflowingErrorsAreAnError) {
  const Trajectory gt = FromCentres({{0, 0, 0}, {1, 0, 0}});
  const Trajectory pred = FromCentres({{1e308, 0, 0}, {-1e308, 0, 0}});
  try {
    ComputeTrajectoryErrors(pred, gt);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("overflow"), std::string::npos);
  }
}

TEST(TrajectoryMetrics, ScaleAlignmentHandComputed) {
  // pred = gt / 2 about the origin: scale-only alignment finds 2 and zero
  // error; SE(3) cannot fix scale: best rigid fit of {0,1,2}/2 to {0,1,2} on a
  // line leaves errors |x - x/2 - t|.
  const Trajectory gt =
      FromCentres({{0, 0, 0}, {2, 1, 0}, {4, 0, 1}, {6, 2, 2}});
  const Trajectory pred =
      FromCentres({{0, 0, 0}, {1, 0.5, 0}, {2, 0, 0.5}, {3, 1, 1}});
  TrajectoryErrorOptions options;
  options.alignment = AlignmentType::kScale;
  const TrajectoryErrors e = ComputeTrajectoryErrors(pred, gt, options);
  EXPECT_NEAR(e.gt_from_pred.scale, 2.0, 1e-12);
  EXPECT_NEAR(e.ade, 0.0, 1e-12);
  options.alignment = AlignmentType::kSim3;
  EXPECT_NEAR(ComputeTrajectoryErrors(pred, gt, options).ade, 0.0, 1e-12);
  options.alignment = AlignmentType::kSE3;
  EXPECT_GT(ComputeTrajectoryErrors(pred, gt, options).ade, 0.1);
}

TEST(TrajectoryMetrics, RecoversKnownRandomSim3) {
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<Eigen::Vector3d> gt_c;
  for (int i = 0; i < 25; ++i) {
    gt_c.emplace_back(2.0 * i + normal(test::Rng()), 0.3 * normal(test::Rng()),
                      0.5 * i * i / 25.0 + normal(test::Rng()));
  }
  const Eigen::Quaterniond q = QuaternionFromAngleAxis(Eigen::Vector3d(
      normal(test::Rng()), normal(test::Rng()), normal(test::Rng())));
  const Sim3d pred_from_gt(0.37, q, Eigen::Vector3d(5, -3, 12));
  std::vector<Eigen::Vector3d> pred_c;
  for (const auto& c : gt_c) pred_c.push_back(pred_from_gt * c);
  TrajectoryErrorOptions options;
  options.alignment = AlignmentType::kSim3;
  const TrajectoryErrors e =
      ComputeTrajectoryErrors(FromCentres(pred_c), FromCentres(gt_c), options);
  const Sim3d expected = pred_from_gt.Inverse();
  EXPECT_NEAR(e.gt_from_pred.scale, expected.scale, 1e-9);
  EXPECT_LT(e.gt_from_pred.rotation.angularDistance(expected.rotation), 1e-9);
  EXPECT_THAT(e.gt_from_pred.translation,
              test::EigenNear(expected.translation, 1e-9));
  EXPECT_LT(e.ade, 1e-9);
  EXPECT_LT(e.fde, 1e-9);
  options.alignment = AlignmentType::kNone;
  EXPECT_GT(
      ComputeTrajectoryErrors(FromCentres(pred_c), FromCentres(gt_c), options)
          .ade,
      1.0);
}

TEST(TrajectoryMetrics, BadInput) {
  const Trajectory a = FromCentres({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}});
  const Trajectory b = FromCentres({{0, 0, 0}, {1, 0, 0}});
  try {
    ComputeTrajectoryErrors(a, b);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "differ in length (predicted 3 poses, ground truth 2)"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(ComputeTrajectoryErrors(Trajectory(), b), InputError);
}

}  // namespace
}  // namespace geodrive

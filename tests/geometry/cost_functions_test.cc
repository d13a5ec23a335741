#include "geometry/internal/cost_functions.h"

#include <ceres/numeric_diff_cost_function.h>
#include <gtest/gtest.h>

#include <random>

#include "geometry/rigid3.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

// Evaluates residuals and Jacobians of `cost` at `params` (block sizes from the
// cost function).
void Evaluate(const ceres::CostFunction& cost,
              const std::vector<const double*>& params,
              std::vector<double>* residuals,
              std::vector<std::vector<double>>* jacobians) {
  const auto& sizes = cost.parameter_block_sizes();
  residuals->assign(cost.num_residuals(), 0);
  jacobians->resize(sizes.size());
  std::vector<double*> jac_ptrs;
  for (size_t i = 0; i < sizes.size(); ++i) {
    (*jacobians)[i].assign(cost.num_residuals() * sizes[i], 0);
    jac_ptrs.push_back((*jacobians)[i].data());
  }
  ASSERT_TRUE(cost.Evaluate(params.data(), residuals->data(), jac_ptrs.data()));
}

// Three draws in a fixed order (the arguments of one constructor call are
// evaluated in an unspecified order: GCC and clang draw different vectors).
Eigen::Vector3d Draw3(std::normal_distribution<double>& g, std::mt19937& rng) {
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i) v[i] = g(rng);
  return v;
}

double MaxJacobianDifference(const ceres::CostFunction& a,
                             const ceres::CostFunction& b,
                             const std::vector<const double*>& params) {
  std::vector<double> ra, rb;
  std::vector<std::vector<double>> ja, jb;
  Evaluate(a, params, &ra, &ja);
  Evaluate(b, params, &rb, &jb);
  double worst = 0;
  for (size_t i = 0; i < ra.size(); ++i) EXPECT_NEAR(ra[i], rb[i], 1e-12);
  for (size_t k = 0; k < ja.size(); ++k) {
    for (size_t i = 0; i < ja[k].size(); ++i) {
      worst = std::max(worst, std::abs(ja[k][i] - jb[k][i]) /
                                  std::max(1.0, std::abs(ja[k][i])));
    }
  }
  return worst;
}

TEST(ReprojectionCost, AutodiffJacobianMatchesNumericDifferentiation) {
  std::normal_distribution<double> g(0, 1);
  auto& rng = test::Rng();
  double worst = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Quaterniond q = QuaternionFromAngleAxis(Draw3(g, rng) * 0.3);
    const double qa[4] = {q.w(), q.x(), q.y(), q.z()};
    const double t[3] = {g(rng), g(rng), g(rng)};  // braces: in order
    const double s[1] = {1.0 + 0.05 * g(rng)};
    const Eigen::Vector3d x = Draw3(g, rng) + Eigen::Vector3d(0, 0, 10);
    const Eigen::Vector2d px =
        Eigen::Vector2d(100, 80) + 10 * Draw3(g, rng).head<2>();
    std::unique_ptr<ceres::CostFunction> autodiff(
        ReprojectionCost::Create(x, px, 230, 231, 128, 72));
    // Ridders' extrapolation from its default first step (1 % of each
    // parameter) was off by up to 7 % on some of these poses (central
    // differences agree with autodiff to 1e-7 there); from 1e-4 it agrees to
    // 1e-11 on all of them.
    ceres::NumericDiffOptions nd;
    nd.relative_step_size = 1e-6;
    nd.ridders_relative_initial_step_size = 1e-4;
    ceres::NumericDiffCostFunction<ReprojectionCost, ceres::RIDDERS, 2, 4, 3, 1>
        numeric(new ReprojectionCost(x, px, 230, 231, 128, 72),
                ceres::TAKE_OWNERSHIP, 2, nd);
    worst =
        std::max(worst, MaxJacobianDifference(*autodiff, numeric, {qa, t, s}));
  }
  std::printf(
      "max relative Jacobian difference (autodiff vs Ridders numeric): %.2e\n",
      worst);
  EXPECT_LT(worst, 1e-6);
}

TEST(ReprojectionCost, ZeroAtTheTruePose) {
  const Rigid3d cam_from_world(
      QuaternionFromAngleAxis(Eigen::Vector3d(0.1, -0.2, 0.05)),
      Eigen::Vector3d(0.5, -0.3, 2.0));
  const Eigen::Vector3d x_world(1.0, 0.5, 8.0);
  const Eigen::Vector3d x_cam = cam_from_world * x_world;
  const Eigen::Vector2d px(200 * x_cam.x() / x_cam.z() + 64,
                           200 * x_cam.y() / x_cam.z() + 36);
  const Eigen::Quaterniond& q = cam_from_world.rotation;
  const double qa[4] = {q.w(), q.x(), q.y(), q.z()};
  const double s = 1.0;
  double r[2];
  ReprojectionCost(x_world, px, 200, 200, 64, 36)(
      qa, cam_from_world.translation.data(), &s, r);
  EXPECT_NEAR(r[0], 0, 1e-12);
  EXPECT_NEAR(r[1], 0, 1e-12);
}

TEST(TemporalSmoothnessCost, AutodiffJacobianMatchesNumericDifferentiation) {
  std::normal_distribution<double> g(0, 1);
  auto& rng = test::Rng();
  double worst = 0;
  for (int trial = 0; trial < 20; ++trial) {
    double q[3][4], t[3][3];
    for (int k = 0; k < 3; ++k) {
      const Eigen::Quaterniond qq =
          QuaternionFromAngleAxis(Draw3(g, rng) * 0.2);
      q[k][0] = qq.w(), q[k][1] = qq.x(), q[k][2] = qq.y(), q[k][3] = qq.z();
      for (int j = 0; j < 3; ++j) t[k][j] = g(rng);
    }
    std::unique_ptr<ceres::CostFunction> autodiff(
        TemporalSmoothnessCost::Create(2.0, 3.0));
    ceres::NumericDiffOptions nd;
    ceres::NumericDiffCostFunction<TemporalSmoothnessCost, ceres::RIDDERS, 6, 4,
                                   3, 4, 3, 4, 3>
        numeric(new TemporalSmoothnessCost(2.0, 3.0), ceres::TAKE_OWNERSHIP, 6,
                nd);
    worst = std::max(
        worst, MaxJacobianDifference(*autodiff, numeric,
                                     {q[0], t[0], q[1], t[1], q[2], t[2]}));
  }
  std::printf("max relative Jacobian difference (smoothness): %.2e\n", worst);
  EXPECT_LT(worst, 1e-6);
}

TEST(TemporalSmoothnessCost, ZeroForConstantVelocity) {
  // Poses with constant angular and linear velocity have zero second
  // differences.
  const Eigen::Quaterniond step =
      QuaternionFromAngleAxis(Eigen::Vector3d(0.01, 0.02, -0.01));
  double q[3][4], t[3][3];
  for (int k = 0; k < 3; ++k) {
    Eigen::Quaterniond world_from_cam = Eigen::Quaterniond::Identity();
    for (int j = 0; j < k; ++j) world_from_cam = world_from_cam * step;
    const Rigid3d cam_from_world =
        Rigid3d(world_from_cam, Eigen::Vector3d(0.3 * k, 0.1 * k, 1.0 * k))
            .Inverse();
    const Eigen::Quaterniond& qq = cam_from_world.rotation;
    q[k][0] = qq.w(), q[k][1] = qq.x(), q[k][2] = qq.y(), q[k][3] = qq.z();
    for (int j = 0; j < 3; ++j) t[k][j] = cam_from_world.translation[j];
  }
  double r[6];
  TemporalSmoothnessCost(1, 1)(q[0], t[0], q[1], t[1], q[2], t[2], r);
  for (double x : r) EXPECT_NEAR(x, 0, 1e-12);
}

}  // namespace
}  // namespace geodrive

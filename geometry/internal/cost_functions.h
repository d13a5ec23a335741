#pragma once
// Ceres cost functors for pose refinement (GeoDrive eq. 3). This header
// includes Ceres: include it only from .cc files (geometry/pose_refinement.cc
// and tests).
//
// Parameter blocks (all double):
//   q_cam_from_world[4]  rotation cam_from_world as a unit quaternion (w, x, y,
//   z) -- w FIRST,
//                        the order of ceres::QuaternionManifold and
//                        ceres/rotation.h;
//   t_cam_from_world[3]  translation cam_from_world;
//   focal_scale[1]       multiplicative focal correction s (fx' = s fx, fy' = s
//   fy).

#include <ceres/autodiff_cost_function.h>
#include <ceres/rotation.h>

#include <Eigen/Core>

namespace geodrive {

// Reprojection error of a world point O(i, j) observed at its own pixel (u, v)
// = (i, j):
//   X_c = R(q) O + t
//   pi(X_c) = (s fx X_c.x / X_c.z + cx,  s fy X_c.y / X_c.z + cy)
//   r = pi(X_c) - (u, v)                                   [2 residuals,
//   pixels]
// (u, v) and (cx, cy) use the integer-index pixel convention (MonST3R: no
// +0.5). The robust loss rho of eq. 3 is applied by Ceres on ||r||^2
// (ceres::HuberLoss / CauchyLoss with scale in px).
struct ReprojectionCost {
  ReprojectionCost(const Eigen::Vector3d& point_in_world,
                   const Eigen::Vector2d& pixel,
                   double fx,
                   double fy,
                   double cx,
                   double cy)
      : point_in_world(point_in_world),
        pixel(pixel),
        fx(fx),
        fy(fy),
        cx(cx),
        cy(cy) {}

  template <typename T>
  bool operator()(const T* const q_cam_from_world,
                  const T* const t_cam_from_world,
                  const T* const focal_scale,
                  T* residuals) const {
    const T point[3] = {T(point_in_world.x()), T(point_in_world.y()),
                        T(point_in_world.z())};
    T x_cam[3];
    ceres::UnitQuaternionRotatePoint(q_cam_from_world, point, x_cam);
    x_cam[0] += t_cam_from_world[0];
    x_cam[1] += t_cam_from_world[1];
    x_cam[2] += t_cam_from_world[2];
    const T inv_z = T(1) / x_cam[2];
    residuals[0] =
        focal_scale[0] * T(fx) * x_cam[0] * inv_z + T(cx) - T(pixel.x());
    residuals[1] =
        focal_scale[0] * T(fy) * x_cam[1] * inv_z + T(cy) - T(pixel.y());
    return true;
  }

  // Returns a new cost function (2 residuals; blocks 4, 3, 1). Ceres takes
  // ownership when it is added to a ceres::Problem.
  static ceres::CostFunction* Create(const Eigen::Vector3d& point_in_world,
                                     const Eigen::Vector2d& pixel,
                                     double fx,
                                     double fy,
                                     double cx,
                                     double cy) {
    return new ceres::AutoDiffCostFunction<ReprojectionCost, 2, 4, 3, 1>(
        new ReprojectionCost(point_in_world, pixel, fx, fy, cx, cy));
  }

  Eigen::Vector3d point_in_world;
  Eigen::Vector2d pixel;
  double fx, fy, cx, cy;
};

// Temporal smoothness of three consecutive camera poses a, b, c
// (constant-velocity prior):
//   centres  C_k = -R_k^T t_k (world frame)
//   r[0:3] = w_t (C_a - 2 C_b + C_c)                         (second difference
//   of the centres) r[3:6] = w_r (log(R_c R_b^T) - log(R_b R_a^T)) (change of
//   the relative rotation,
//                                                             angle-axis,
//                                                             radians)
// Weights: w_t in residual units per scene unit, w_r per radian.
struct TemporalSmoothnessCost {
  TemporalSmoothnessCost(double translation_weight, double rotation_weight)
      : w_t(translation_weight), w_r(rotation_weight) {}

  template <typename T>
  static void Centre(const T* q, const T* t, T* centre) {
    const T q_inv[4] = {q[0], -q[1], -q[2], -q[3]};
    T rotated[3];
    ceres::UnitQuaternionRotatePoint(q_inv, t, rotated);
    centre[0] = -rotated[0];
    centre[1] = -rotated[1];
    centre[2] = -rotated[2];
  }
  // log(R_2 R_1^T) as an angle-axis vector.
  template <typename T>
  static void RelativeAngleAxis(const T* q1, const T* q2, T* angle_axis) {
    const T q1_inv[4] = {q1[0], -q1[1], -q1[2], -q1[3]};
    T rel[4];
    ceres::QuaternionProduct(q2, q1_inv, rel);
    if (rel[0] < T(0)) {  // shortest rotation
      for (int k = 0; k < 4; ++k) rel[k] = -rel[k];
    }
    ceres::QuaternionToAngleAxis(rel, angle_axis);
  }

  template <typename T>
  bool operator()(const T* const q_a,
                  const T* const t_a,
                  const T* const q_b,
                  const T* const t_b,
                  const T* const q_c,
                  const T* const t_c,
                  T* residuals) const {
    T ca[3], cb[3], cc[3];
    Centre(q_a, t_a, ca);
    Centre(q_b, t_b, cb);
    Centre(q_c, t_c, cc);
    for (int k = 0; k < 3; ++k)
      residuals[k] = T(w_t) * (ca[k] - T(2) * cb[k] + cc[k]);
    T w_ab[3], w_bc[3];
    RelativeAngleAxis(q_a, q_b, w_ab);
    RelativeAngleAxis(q_b, q_c, w_bc);
    for (int k = 0; k < 3; ++k) residuals[3 + k] = T(w_r) * (w_bc[k] - w_ab[k]);
    return true;
  }

  // 6 residuals; blocks 4, 3, 4, 3, 4, 3. Ceres takes ownership.
  static ceres::CostFunction* Create(double translation_weight,
                                     double rotation_weight) {
    return new ceres::AutoDiffCostFunction<TemporalSmoothnessCost, 6, 4, 3, 4,
                                           3, 4, 3>(
        new TemporalSmoothnessCost(translation_weight, rotation_weight));
  }

  double w_t, w_r;
};

}  // namespace geodrive

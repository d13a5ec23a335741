#pragma once
// Rigid and similarity transforms.
//
// Convention (as COLMAP's rigid3.h): a transform named `b_from_a` maps a point expressed in frame
// a to frame b: x_in_b = b_from_a * x_in_a = R * x_in_a + t. Composition reads right to left:
// c_from_a = c_from_b * b_from_a. Camera frames use OpenCV axes (x right, y down, z forward).
//
// Quaternions are Eigen::Quaterniond (Hamilton). Eigen's *constructor* takes (w, x, y, z) but its
// coeffs() are stored (x, y, z, w): never pass raw arrays; use the explicitly named
// QuaternionFromWxyz / QuaternionFromXyzw helpers at every file boundary.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace geodrive {

using Matrix3x4d = Eigen::Matrix<double, 3, 4>;

// Hamilton quaternion from scalar-first (w, x, y, z): nuScenes, MonST3R pred_traj.txt.
Eigen::Quaterniond QuaternionFromWxyz(double w, double x, double y, double z);
Eigen::Quaterniond QuaternionFromWxyz(const Eigen::Vector4d& wxyz);
// Hamilton quaternion from scalar-last (x, y, z, w): standard TUM, scipy, ROS.
Eigen::Quaterniond QuaternionFromXyzw(double x, double y, double z, double w);
Eigen::Quaterniond QuaternionFromXyzw(const Eigen::Vector4d& xyzw);
// Returns (w, x, y, z).
Eigen::Vector4d QuaternionToWxyz(const Eigen::Quaterniond& q);
// Returns (x, y, z, w).
Eigen::Vector4d QuaternionToXyzw(const Eigen::Quaterniond& q);
// Axis-angle vector (unit axis times angle in radians) <-> quaternion.
Eigen::Quaterniond QuaternionFromAngleAxis(const Eigen::Vector3d& angle_axis);
Eigen::Vector3d QuaternionToAngleAxis(const Eigen::Quaterniond& q);
// Angle in degrees of the rotation a^-1 * b (in [0, 180]).
double RotationDistanceDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b);

// Rigid body transform x_in_b = rotation * x_in_a + translation.
struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation);

  // From a 4x4 (or 3x4) matrix [R|t]; throws InputError if R is not a rotation within `tol`.
  static Rigid3d FromMatrix(const Eigen::Matrix4d& matrix, double tol = 1e-6);
  static Rigid3d FromMatrix3x4(const Matrix3x4d& matrix, double tol = 1e-6);
  Eigen::Matrix4d ToMatrix() const;
  Matrix3x4d ToMatrix3x4() const;

  Rigid3d Inverse() const;
  // True if all values are finite and the quaternion has unit norm within `tol`.
  bool IsValid(double tol = 1e-6) const;
};

// c_from_a = c_from_b * b_from_a.
Rigid3d operator*(const Rigid3d& c_from_b, const Rigid3d& b_from_a);
// x_in_b = b_from_a * x_in_a.
Eigen::Vector3d operator*(const Rigid3d& b_from_a, const Eigen::Vector3d& x_in_a);

// Interpolates between two poses: slerp on rotation, lerp on translation; t in [0, 1].
Rigid3d Interpolate(const Rigid3d& a, const Rigid3d& b, double t);

// Similarity transform x_in_b = scale * rotation * x_in_a + translation.
struct Sim3d {
  double scale = 1.0;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Sim3d() = default;
  Sim3d(double scale, const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation);

  // From [sR|t]; throws InputError if the upper 3x3 is not a positive scaled rotation.
  static Sim3d FromMatrix(const Eigen::Matrix4d& matrix, double tol = 1e-6);
  Eigen::Matrix4d ToMatrix() const;
  Sim3d Inverse() const;
};

Sim3d operator*(const Sim3d& c_from_b, const Sim3d& b_from_a);
Eigen::Vector3d operator*(const Sim3d& b_from_a, const Eigen::Vector3d& x_in_a);

// Applies a similarity to a camera pose: world'_from_cam = sim * world_from_cam, with the
// rotation part kept orthonormal (scale applies to the translation only).
Rigid3d TransformPose(const Sim3d& new_from_old, const Rigid3d& old_from_cam);

}  // namespace geodrive

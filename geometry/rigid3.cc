#include "geometry/rigid3.h"

#include <algorithm>
#include <cmath>

#include "geometry/util/status.h"

namespace geodrive {

Eigen::Quaterniond QuaternionFromWxyz(double w, double x, double y, double z) {
  return Eigen::Quaterniond(w, x, y, z);
}
Eigen::Quaterniond QuaternionFromWxyz(const Eigen::Vector4d& wxyz) {
  return Eigen::Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
}
Eigen::Quaterniond QuaternionFromXyzw(double x, double y, double z, double w) {
  return Eigen::Quaterniond(w, x, y, z);
}
Eigen::Quaterniond QuaternionFromXyzw(const Eigen::Vector4d& xyzw) {
  return Eigen::Quaterniond(xyzw[3], xyzw[0], xyzw[1], xyzw[2]);
}
Eigen::Vector4d QuaternionToWxyz(const Eigen::Quaterniond& q) {
  return Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
}
Eigen::Vector4d QuaternionToXyzw(const Eigen::Quaterniond& q) {
  return Eigen::Vector4d(q.x(), q.y(), q.z(), q.w());
}

Eigen::Quaterniond QuaternionFromAngleAxis(const Eigen::Vector3d& angle_axis) {
  const double angle = angle_axis.norm();
  if (angle < 1e-16) {
    // First-order expansion keeps tiny rotations exact to machine precision.
    return Eigen::Quaterniond(1.0, 0.5 * angle_axis.x(), 0.5 * angle_axis.y(),
                              0.5 * angle_axis.z())
        .normalized();
  }
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, angle_axis / angle));
}

Eigen::Vector3d QuaternionToAngleAxis(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  if (q.w() < 0) q.coeffs() *= -1.0;  // shortest rotation, angle in [0, pi]
  const double sin_half = q.vec().norm();
  if (sin_half < 1e-16) return 2.0 * q.vec();
  const double angle = 2.0 * std::atan2(sin_half, q.w());
  return q.vec() / sin_half * angle;
}

double RotationDistanceDeg(const Eigen::Quaterniond& a,
                           const Eigen::Quaterniond& b) {
  const Eigen::Quaterniond d = a.normalized().conjugate() * b.normalized();
  const double s = d.vec().norm();
  const double angle = 2.0 * std::atan2(s, std::abs(d.w()));
  return angle * 180.0 / M_PI;
}

namespace {
void CheckRotation(const Eigen::Matrix3d& r, double tol, const char* what) {
  GEODRIVE_CHECK_INPUT(r.allFinite(), what, ": matrix has non-finite values");
  const double ortho =
      (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  GEODRIVE_CHECK_INPUT(
      ortho <= tol, what,
      ": rotation block is not orthonormal (max |RtR-I| = ", ortho, ")");
  GEODRIVE_CHECK_INPUT(r.determinant() > 0, what,
                       ": rotation block has negative determinant");
}
}  // namespace

Rigid3d::Rigid3d(const Eigen::Quaterniond& rotation_in,
                 const Eigen::Vector3d& translation_in)
    : rotation(rotation_in), translation(translation_in) {}

namespace {
// A 4x4 transform's bottom row is [0 0 0 1]; anything else (a transposed
// matrix holds its translation there) would be dropped silently.
void CheckBottomRow(const Eigen::Matrix4d& m, double tol, const char* what) {
  const Eigen::RowVector4d bottom = m.row(3);
  GEODRIVE_CHECK_INPUT(
      bottom.allFinite() &&
          (bottom - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() <=
              tol,
      what, ": bottom row is [", bottom(0), " ", bottom(1), " ", bottom(2), " ",
      bottom(3), "], expected [0 0 0 1] (a transposed matrix?)");
}
}  // namespace

Rigid3d Rigid3d::FromMatrix(const Eigen::Matrix4d& m, double tol) {
  CheckBottomRow(m, tol, "Rigid3d::FromMatrix");
  return FromMatrix3x4(m.topRows<3>(), tol);
}

Rigid3d Rigid3d::FromMatrix3x4(const Matrix3x4d& m, double tol) {
  const Eigen::Matrix3d r = m.leftCols<3>();
  CheckRotation(r, tol, "Rigid3d::FromMatrix");
  GEODRIVE_CHECK_INPUT(m.col(3).allFinite(),
                       "Rigid3d::FromMatrix: non-finite translation");
  return Rigid3d(Eigen::Quaterniond(r).normalized(), m.col(3));
}

Eigen::Matrix4d Rigid3d::ToMatrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topRows<3>() = ToMatrix3x4();
  return m;
}

Matrix3x4d Rigid3d::ToMatrix3x4() const {
  Matrix3x4d m;
  m.leftCols<3>() = rotation.toRotationMatrix();
  m.col(3) = translation;
  return m;
}

Rigid3d Rigid3d::Inverse() const {
  const Eigen::Quaterniond inv = rotation.conjugate();
  return Rigid3d(inv, -(inv * translation));
}

bool Rigid3d::IsValid(double tol) const {
  return rotation.coeffs().allFinite() && translation.allFinite() &&
         std::abs(rotation.norm() - 1.0) <= tol;
}

Rigid3d operator*(const Rigid3d& c_from_b, const Rigid3d& b_from_a) {
  return Rigid3d(
      (c_from_b.rotation * b_from_a.rotation).normalized(),
      c_from_b.translation + c_from_b.rotation * b_from_a.translation);
}

Eigen::Vector3d operator*(const Rigid3d& b_from_a,
                          const Eigen::Vector3d& x_in_a) {
  return b_from_a.rotation * x_in_a + b_from_a.translation;
}

Rigid3d Interpolate(const Rigid3d& a, const Rigid3d& b, double t) {
  return Rigid3d(a.rotation.slerp(t, b.rotation).normalized(),
                 (1.0 - t) * a.translation + t * b.translation);
}

Sim3d::Sim3d(double scale_in,
             const Eigen::Quaterniond& rotation_in,
             const Eigen::Vector3d& translation_in)
    : scale(scale_in), rotation(rotation_in), translation(translation_in) {}

Sim3d Sim3d::FromMatrix(const Eigen::Matrix4d& m, double tol) {
  CheckBottomRow(m, tol, "Sim3d::FromMatrix");
  const Eigen::Matrix3d sr = m.topLeftCorner<3, 3>();
  GEODRIVE_CHECK_INPUT(sr.allFinite() && m.col(3).allFinite(),
                       "Sim3d::FromMatrix: non-finite values");
  const double det = sr.determinant();
  GEODRIVE_CHECK_INPUT(det > 0, "Sim3d::FromMatrix: non-positive determinant");
  const double scale = std::cbrt(det);
  CheckRotation(sr / scale, tol, "Sim3d::FromMatrix");
  return Sim3d(scale, Eigen::Quaterniond(sr / scale).normalized(),
               m.block<3, 1>(0, 3));
}

Eigen::Matrix4d Sim3d::ToMatrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = scale * rotation.toRotationMatrix();
  m.block<3, 1>(0, 3) = translation;
  return m;
}

Sim3d Sim3d::Inverse() const {
  const Eigen::Quaterniond inv = rotation.conjugate();
  return Sim3d(1.0 / scale, inv, -(inv * translation) / scale);
}

Sim3d operator*(const Sim3d& c_from_b, const Sim3d& b_from_a) {
  return Sim3d(c_from_b.scale * b_from_a.scale,
               (c_from_b.rotation * b_from_a.rotation).normalized(),
               c_from_b.scale * (c_from_b.rotation * b_from_a.translation) +
                   c_from_b.translation);
}

Eigen::Vector3d operator*(const Sim3d& b_from_a,
                          const Eigen::Vector3d& x_in_a) {
  return b_from_a.scale * (b_from_a.rotation * x_in_a) + b_from_a.translation;
}

Rigid3d TransformPose(const Sim3d& new_from_old, const Rigid3d& old_from_cam) {
  return Rigid3d((new_from_old.rotation * old_from_cam.rotation).normalized(),
                 new_from_old * old_from_cam.translation);
}

}  // namespace geodrive

#include "geometry/rigid3.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

using test::EigenNear;

Rigid3d RandomRigid(std::mt19937& rng, double trans_scale = 10.0) {
  std::normal_distribution<double> n(0.0, 1.0);
  const Eigen::Quaterniond q = Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();
  return Rigid3d(q, trans_scale * Eigen::Vector3d(n(rng), n(rng), n(rng)));
}

TEST(Rigid3d, QuaternionOrderIsExplicit) {
  // A 90 degree rotation about z: (w, x, y, z) = (cos45, 0, 0, sin45).
  const double c = std::sqrt(0.5);
  const Eigen::Quaterniond from_wxyz = QuaternionFromWxyz(c, 0, 0, c);
  const Eigen::Quaterniond from_xyzw = QuaternionFromXyzw(0, 0, c, c);
  EXPECT_NEAR(RotationDistanceDeg(from_wxyz, from_xyzw), 0.0, 1e-9);
  EXPECT_THAT((from_wxyz * Eigen::Vector3d::UnitX()).eval(),
              EigenNear(Eigen::Vector3d::UnitY().eval(), 1e-12));
  EXPECT_THAT(QuaternionToWxyz(from_wxyz), EigenNear(Eigen::Vector4d(c, 0, 0, c), 1e-15));
  EXPECT_THAT(QuaternionToXyzw(from_wxyz), EigenNear(Eigen::Vector4d(0, 0, c, c), 1e-15));
  // Reading w-first numbers as w-last gives a different rotation.
  EXPECT_GT(RotationDistanceDeg(QuaternionFromWxyz(0.9, 0.1, 0.3, 0.2).normalized(),
                                QuaternionFromXyzw(0.9, 0.1, 0.3, 0.2).normalized()),
            10.0);
}

TEST(Rigid3d, ComposeAndInverse) {
  auto& rng = test::Rng();
  for (int i = 0; i < 100; ++i) {
    const Rigid3d b_from_a = RandomRigid(rng);
    const Rigid3d c_from_b = RandomRigid(rng);
    const Eigen::Vector3d x_in_a(1.5, -2.0, 3.0);
    const Eigen::Vector3d expected = c_from_b * (b_from_a * x_in_a);
    EXPECT_THAT(((c_from_b * b_from_a) * x_in_a).eval(), EigenNear(expected, 1e-9));
    const Rigid3d identity = b_from_a.Inverse() * b_from_a;
    EXPECT_NEAR(identity.translation.norm(), 0.0, 1e-9);
    EXPECT_NEAR(RotationDistanceDeg(identity.rotation, Eigen::Quaterniond::Identity()), 0.0, 1e-6);
  }
}

TEST(Rigid3d, MatrixRoundTrip) {
  auto& rng = test::Rng();
  const Rigid3d t = RandomRigid(rng);
  const Rigid3d back = Rigid3d::FromMatrix(t.ToMatrix());
  EXPECT_THAT(back.ToMatrix(), EigenNear(t.ToMatrix(), 1e-12));
  EXPECT_THAT(t.Inverse().ToMatrix(), EigenNear(t.ToMatrix().inverse().eval(), 1e-9));
}

TEST(Rigid3d, FromMatrixRejectsNonRotation) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m(0, 0) = 2.0;
  EXPECT_THROW(Rigid3d::FromMatrix(m), InputError);
  m = Eigen::Matrix4d::Identity();
  m(0, 0) = -1.0;  // reflection
  EXPECT_THROW(Rigid3d::FromMatrix(m), InputError);
  m = Eigen::Matrix4d::Identity();
  m(1, 3) = std::nan("");
  EXPECT_THROW(Rigid3d::FromMatrix(m), InputError);
}

// A transposed pose holds its translation in the bottom row: refused, never
// read as the identity translation.
TEST(Rigid3d, FromMatrixRefusesABottomRowOtherThan0001) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m(3, 0) = 1.0;
  m(3, 1) = 2.0;
  m(3, 2) = 3.0;  // the translation of the transposed matrix
  try {
    Rigid3d::FromMatrix(m);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bottom row is [1 2 3 1]"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(Sim3d::FromMatrix(m), InputError);
  m = Eigen::Matrix4d::Identity();
  m(3, 3) = 2.0;  // a homogeneous scale
  EXPECT_THROW(Rigid3d::FromMatrix(m), InputError);
  m(3, 3) = 1.0 + 1e-12;  // rounding is not an error
  EXPECT_NO_THROW(Rigid3d::FromMatrix(m));
}

TEST(Rigid3d, AngleAxisRoundTrip) {
  auto& rng = test::Rng();
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 100; ++i) {
    Eigen::Vector3d aa(u(rng), u(rng), u(rng));
    aa *= (i % 10 == 0 ? 1e-9 : 1.7);  // norm < pi (unique); include tiny ones
    EXPECT_THAT(QuaternionToAngleAxis(QuaternionFromAngleAxis(aa)), EigenNear(aa, 1e-9));
  }
  EXPECT_NEAR(RotationDistanceDeg(Eigen::Quaterniond::Identity(),
                                  QuaternionFromAngleAxis(Eigen::Vector3d(0, 0, M_PI / 2))),
              90.0, 1e-9);
}

TEST(Rigid3d, InterpolateIsSlerpPlusLerp) {
  const Rigid3d a(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 0));
  const Rigid3d b(QuaternionFromAngleAxis(Eigen::Vector3d(0, 0, 1.0)), Eigen::Vector3d(2, 4, 6));
  const Rigid3d mid = Interpolate(a, b, 0.25);
  EXPECT_THAT(mid.translation, EigenNear(Eigen::Vector3d(0.5, 1.0, 1.5), 1e-12));
  EXPECT_NEAR(RotationDistanceDeg(a.rotation, mid.rotation), 0.25 * 180.0 / M_PI, 1e-9);
  EXPECT_NEAR(RotationDistanceDeg(Interpolate(a, b, 1.0).rotation, b.rotation), 0.0, 1e-6);
}

TEST(Sim3d, ComposeInverseAndMatrix) {
  auto& rng = test::Rng();
  for (int i = 0; i < 50; ++i) {
    const Rigid3d r1 = RandomRigid(rng), r2 = RandomRigid(rng);
    const Sim3d b_from_a(2.5, r1.rotation, r1.translation);
    const Sim3d c_from_b(0.3, r2.rotation, r2.translation);
    const Eigen::Vector3d x(0.2, 1.0, -4.0);
    EXPECT_THAT(((c_from_b * b_from_a) * x).eval(), EigenNear((c_from_b * (b_from_a * x)).eval(), 1e-9));
    EXPECT_THAT((b_from_a.Inverse() * (b_from_a * x)).eval(), EigenNear(x, 1e-9));
    const Sim3d back = Sim3d::FromMatrix(b_from_a.ToMatrix());
    EXPECT_NEAR(back.scale, 2.5, 1e-12);
    EXPECT_THAT(back.ToMatrix(), EigenNear(b_from_a.ToMatrix(), 1e-12));
  }
}

TEST(Sim3d, TransformPoseKeepsRotationOrthonormal) {
  const Sim3d new_from_old(3.0, QuaternionFromAngleAxis(Eigen::Vector3d(0, 0.5, 0)),
                           Eigen::Vector3d(1, 0, 0));
  const Rigid3d old_from_cam(QuaternionFromAngleAxis(Eigen::Vector3d(0.1, 0, 0)),
                             Eigen::Vector3d(0, 2, 0));
  const Rigid3d new_from_cam = TransformPose(new_from_old, old_from_cam);
  EXPECT_TRUE(new_from_cam.IsValid(1e-12));
  // The camera centre maps like a point.
  EXPECT_THAT(new_from_cam.translation,
              EigenNear((new_from_old * old_from_cam.translation).eval(), 1e-12));
}

}  // namespace
}  // namespace geodrive

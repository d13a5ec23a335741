#include "geometry/trajectory.h"

#include <gtest/gtest.h>

#include <cmath>

#include "geometry/point_cloud.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

using test::EigenNear;

// A camera driving along +z of the world at 10 m/s, sampled at 12 Hz, yawing slowly.
Trajectory StraightDrive(int n) {
  Trajectory t;
  for (int i = 0; i < n; ++i) {
    const double time = i / 12.0;
    t.Add(time, Rigid3d(QuaternionFromAngleAxis(Eigen::Vector3d(0, 0.01 * i, 0)),
                        Eigen::Vector3d(0, 0, 10.0 * time)));
  }
  return t;
}

TEST(Trajectory, LengthDurationSpeed) {
  const Trajectory t = StraightDrive(25);
  EXPECT_NEAR(t.Duration(), 2.0, 1e-12);
  EXPECT_NEAR(t.Length(), 20.0, 1e-9);
  EXPECT_NEAR(t.MeanSpeed(), 10.0, 1e-9);
  for (double s : t.SegmentSpeeds()) EXPECT_NEAR(s, 10.0, 1e-9);
  EXPECT_NO_THROW(t.Check());
}

TEST(Trajectory, RelativeToFirstStartsAtIdentity) {
  Trajectory t = StraightDrive(5);
  const Rigid3d offset(QuaternionFromAngleAxis(Eigen::Vector3d(0.3, -0.2, 1.0)),
                       Eigen::Vector3d(100, -50, 3));
  for (auto& p : t.world_from_cam) p = offset * p;
  const Trajectory rel = t.RelativeToFirst();
  EXPECT_NEAR(rel.world_from_cam[0].translation.norm(), 0.0, 1e-9);
  EXPECT_NEAR(RotationDistanceDeg(rel.world_from_cam[0].rotation, Eigen::Quaterniond::Identity()),
              0.0, 1e-6);
  // Relative motion is invariant to the world offset.
  const Trajectory ref = StraightDrive(5).RelativeToFirst();
  for (size_t i = 0; i < rel.size(); ++i) {
    EXPECT_THAT(rel.world_from_cam[i].ToMatrix(), EigenNear(ref.world_from_cam[i].ToMatrix(), 1e-9));
  }
}

TEST(Trajectory, PoseAtInterpolatesAndClamps) {
  const Trajectory t = StraightDrive(3);
  EXPECT_THAT(t.PoseAt(0.5 / 12.0).translation, EigenNear(Eigen::Vector3d(0, 0, 10.0 / 24.0), 1e-9));
  EXPECT_THAT(t.PoseAt(-1.0).translation, EigenNear(t.world_from_cam[0].translation, 0.0));
  EXPECT_THAT(t.PoseAt(99.0).translation, EigenNear(t.world_from_cam[2].translation, 0.0));
}

TEST(Trajectory, CheckRejectsBadInput) {
  Trajectory t = StraightDrive(3);
  t.timestamps[2] = t.timestamps[1];
  EXPECT_THROW(t.Check(), InputError);
  t = StraightDrive(3);
  t.world_from_cam[1].translation.x() = std::nan("");
  EXPECT_THROW(t.Check(), InputError);
  t = StraightDrive(3);
  t.world_from_cam[1].rotation.coeffs() *= 2.0;
  EXPECT_THROW(t.Check(), InputError);
  t = StraightDrive(3);
  t.timestamps.pop_back();
  EXPECT_THROW(t.Check(), InputError);
}

TEST(PointCloud, CheckBoundsSelectAppend) {
  PointCloud a;
  a.positions = {{0, 0, 0}, {1, 2, 3}, {-1, 5, 2}};
  a.colors = {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}};
  EXPECT_NO_THROW(a.Check());
  const auto box = a.Bounds();
  EXPECT_THAT(box.min(), EigenNear(Eigen::Vector3f(-1, 0, 0), 0.0f));
  EXPECT_THAT(box.max(), EigenNear(Eigen::Vector3f(1, 5, 3), 0.0f));
  const PointCloud s = a.Select({2, 0});
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s.colors[0], a.colors[2]);
  PointCloud b;
  b.positions = {{9, 9, 9}};
  PointCloud c = a;
  c.Append(b);  // b has no colours: the attribute is dropped rather than misaligned
  EXPECT_EQ(c.size(), 4u);
  EXPECT_TRUE(c.colors.empty());
  PointCloud d = a;
  d.Append(a);
  EXPECT_EQ(d.colors.size(), 6u);
  a.confidence = {0.5f};
  EXPECT_THROW(a.Check(), InputError);
  EXPECT_THROW(a.Select({7}), InputError);
}

}  // namespace
}  // namespace geodrive

// Tests of the trajectory and intrinsics text formats (MonST3R pred_traj.txt,
// TUM, pred_intrinsics.txt).

#include "geometry/trajectory_io.h"

#include <gtest/gtest.h>

#include <fstream>
#include <random>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace trajectory_io_test {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

Trajectory RandomTrajectory(int n) {
  std::uniform_real_distribution<double> u(-10, 10);
  std::normal_distribution<double> g;
  Trajectory t;
  for (int i = 0; i < n; ++i) {
    const Eigen::Quaterniond q =
        Eigen::Quaterniond(g(test::Rng()), g(test::Rng()), g(test::Rng()),
                           g(test::Rng()))
            .normalized();
    t.Add(i, Rigid3d(q, Eigen::Vector3d(u(test::Rng()), u(test::Rng()),
                                        u(test::Rng()))));
  }
  return t;
}

template <typename Fn>
std::string ErrorOf(Fn fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

void ExpectSameTrajectory(const Trajectory& a, const Trajectory& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    // Shortest round-trip text: timestamps and translations come back
    // bit-exact; quaternions are re-normalised on read, which may move the last
    // bit (|q| = 1 +- 1 ulp).
    EXPECT_EQ(a.timestamps[i], b.timestamps[i]);
    EXPECT_EQ(a.world_from_cam[i].translation, b.world_from_cam[i].translation);
    EXPECT_LT((a.world_from_cam[i].rotation.coeffs() -
               b.world_from_cam[i].rotation.coeffs())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-15);
  }
}

TEST(TrajectoryIo, Monst3rRoundTripIsExact) {
  const std::string path = test::MakeTempDir("traj_monst3r") + "/pred_traj.txt";
  const Trajectory t = RandomTrajectory(25);
  WriteMonst3rTrajectory(path, t);
  ExpectSameTrajectory(t, ReadMonst3rTrajectory(path));
}

TEST(TrajectoryIo, TumRoundTripIsExact) {
  const std::string path = test::MakeTempDir("traj_tum") + "/traj.tum";
  Trajectory t = RandomTrajectory(10);
  for (size_t i = 0; i < t.size(); ++i)
    t.timestamps[i] = 1532402927.612460 + 0.083 * i;
  WriteTumTrajectory(path, t);
  ExpectSameTrajectory(t, ReadTumTrajectory(path));
}

TEST(TrajectoryIo, Monst3rWritesWFirstLikePythonStr) {
  // MonST3R writes `f"{t} {x} {y} {z} {qw} {qx} {qy} {qz}"` with Python str()
  // of floats; the expected strings were produced by Python 3.11's repr().
  const std::string path = test::MakeTempDir("traj_str") + "/pred_traj.txt";
  Trajectory t;
  const Eigen::Quaterniond q = QuaternionFromWxyz(0.5, -0.5, 0.5, 0.5);
  t.Add(0.0, Rigid3d(q, Eigen::Vector3d(0.1, 1e-05, 0.0001)));
  t.Add(1.0,
        Rigid3d(q, Eigen::Vector3d(1e16, 1234567890123456.0, -(0.1 + 0.2))));
  t.Add(2.0, Rigid3d(q, Eigen::Vector3d(1.5e300, -0.0, 2.5e-7)));
  t.Add(1e15,
        Rigid3d(q, Eigen::Vector3d(0.00012345, 12345678901234567.0, 5e-324)));
  WriteMonst3rTrajectory(path, t);
  EXPECT_EQ(
      test::ReadFile(path),
      "0.0 0.1 1e-05 0.0001 0.5 -0.5 0.5 0.5\n"
      "1.0 1e+16 1234567890123456.0 -0.30000000000000004 0.5 -0.5 0.5 0.5\n"
      "2.0 1.5e+300 -0.0 2.5e-07 0.5 -0.5 0.5 0.5\n"
      "1000000000000000.0 0.00012345 1.2345678901234568e+16 5e-324 0.5 -0.5 "
      "0.5 0.5\n");
}

TEST(TrajectoryIo, TumWritesWLast) {
  const std::string path = test::MakeTempDir("traj_tum_order") + "/t.txt";
  Trajectory t;
  t.Add(0.5, Rigid3d(QuaternionFromWxyz(0.5, -0.5, 0.5, 0.5),
                     Eigen::Vector3d(1, 2, 3)));
  WriteTumTrajectory(path, t);
  EXPECT_EQ(test::ReadFile(path), "0.5 1.0 2.0 3.0 -0.5 0.5 0.5 0.5\n");
}

TEST(TrajectoryIo, SameNumbersGiveDifferentRotationsInMonst3rAndTum) {
  // The quaternion order is never guessed: (0.7071, 0.7071, 0, 0) is 90 deg
  // about x when read w-first (MonST3R) and 180 deg about (1, 1, 0) when read
  // w-last (TUM).
  const std::string path = test::MakeTempDir("traj_order") + "/t.txt";
  test::WriteFile(
      path, "0.0 1.0 2.0 3.0 0.7071067811865476 0.7071067811865476 0.0 0.0\n");
  const Trajectory m = ReadMonst3rTrajectory(path);
  const Trajectory t = ReadTumTrajectory(path);
  const Eigen::Quaterniond rx90(
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()));
  const Eigen::Quaterniond r180(
      Eigen::AngleAxisd(M_PI, Eigen::Vector3d(1, 1, 0).normalized()));
  EXPECT_LT(RotationDistanceDeg(m.world_from_cam[0].rotation, rx90), 1e-6);
  EXPECT_LT(RotationDistanceDeg(t.world_from_cam[0].rotation, r180), 1e-6);
  EXPECT_NEAR(RotationDistanceDeg(m.world_from_cam[0].rotation,
                                  t.world_from_cam[0].rotation),
              120.0, 1e-6);
  EXPECT_EQ(m.world_from_cam[0].translation, t.world_from_cam[0].translation);
}

TEST(TrajectoryIo, Monst3rPoseIsCameraToWorld) {
  // A camera at (1, 2, 3) rotated 90 deg about z: the camera centre in the
  // world is t, and the camera's x axis points along world +y.
  const std::string path = test::MakeTempDir("traj_c2w") + "/pred_traj.txt";
  test::WriteFile(
      path, "0.0 1.0 2.0 3.0 0.7071067811865476 0.0 0.0 0.7071067811865476\n");
  const Rigid3d world_from_cam = ReadMonst3rTrajectory(path).world_from_cam[0];
  EXPECT_THAT(world_from_cam * Eigen::Vector3d(0, 0, 0),
              test::EigenNear(Eigen::Vector3d(1, 2, 3), 1e-12));
  EXPECT_THAT(world_from_cam * Eigen::Vector3d(1, 0, 0),
              test::EigenNear(Eigen::Vector3d(1, 3, 3), 1e-12));
}

TEST(TrajectoryIo, QuaternionsAreNormalisedOnRead) {
  const std::string path = test::MakeTempDir("traj_norm") + "/pred_traj.txt";
  test::WriteFile(path,
                  "0.0 0 0 0 2.0 0.0 0.0 0.0\n1.0 0 0 0 0.0 0.0 3.0 4.0\n");
  const Trajectory t = ReadMonst3rTrajectory(path);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_DOUBLE_EQ(t.world_from_cam[0].rotation.w(), 1.0);
  EXPECT_DOUBLE_EQ(t.world_from_cam[1].rotation.norm(), 1.0);
  EXPECT_DOUBLE_EQ(t.world_from_cam[1].rotation.y(), 0.6);
  EXPECT_DOUBLE_EQ(t.world_from_cam[1].rotation.z(), 0.8);
  EXPECT_NO_THROW(t.Check());
}

TEST(TrajectoryIo, TumSkipsCommentsAndBlankLinesButCountsThem) {
  const std::string path = test::MakeTempDir("traj_comments") + "/t.txt";
  test::WriteFile(
      path,
      "# timestamp tx ty tz qx qy qz qw\n\n1.0 0 0 0 0 0 0 1\r\n  \n2.0 1 "
      "0 0 0 0 0 1\n");
  const Trajectory t = ReadTumTrajectory(path);
  EXPECT_EQ(t.size(), 2u);
  EXPECT_DOUBLE_EQ(t.Length(), 1.0);
  test::WriteFile(path, "# header\n\n1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 1\n");
  EXPECT_EQ(
      ErrorOf([&] { ReadTumTrajectory(path); }),
      path + ": line 4: expected 8 numbers (t x y z qx qy qz qw), found 7");
}

TEST(TrajectoryIo, RejectsZeroAndNonFiniteQuaternions) {
  const std::string path = test::MakeTempDir("traj_zero") + "/pred_traj.txt";
  test::WriteFile(path, "0.0 0 0 0 1 0 0 0\n1.0 0 0 0 0.0 0.0 0.0 0.0\n");
  EXPECT_EQ(ErrorOf([&] { ReadMonst3rTrajectory(path); }),
            path + ": line 2: zero quaternion");
  test::WriteFile(path, "0.0 0 0 0 nan 0 0 0\n");
  EXPECT_EQ(ErrorOf([&] { ReadMonst3rTrajectory(path); }),
            path + ": line 1: non-finite value 'nan'");
  test::WriteFile(path, "0.0 inf 0 0 1 0 0 0\n");
  EXPECT_THAT(ErrorOf([&] { ReadMonst3rTrajectory(path); }),
              HasSubstr("line 1: non-finite"));
}

TEST(TrajectoryIo, MalformedLinesNameFileAndLine) {
  const std::string path =
      test::MakeTempDir("traj_malformed") + "/pred_traj.txt";
  test::WriteFile(path, "0.0 0 0 0 1 0 0 0\n1.0 0 0 zero 1 0 0 0\n");
  EXPECT_EQ(ErrorOf([&] { ReadMonst3rTrajectory(path); }),
            path + ": line 2: not a number: 'zero'");
  test::WriteFile(path, "0.0 0 0 0 1 0 0 0 9\n");
  EXPECT_EQ(
      ErrorOf([&] { ReadMonst3rTrajectory(path); }),
      path + ": line 1: expected 8 numbers (t x y z qw qx qy qz), found 9");
  test::WriteFile(path, "1.0 0 0 0 1 0 0 0\n1.0 0 0 0 1 0 0 0\n");
  EXPECT_THAT(ErrorOf([&] { ReadMonst3rTrajectory(path); }),
              StartsWith(path + ": line 2: timestamp 1.0 is not greater"));
}

TEST(TrajectoryIo, MissingFileSaysCannotOpen) {
  const std::string path = test::MakeTempDir("traj_missing") + "/pred_traj.txt";
  EXPECT_EQ(ErrorOf([&] { ReadMonst3rTrajectory(path); }),
            path + ": cannot open (No such file or directory)");
  EXPECT_EQ(ErrorOf([&] { ReadTumTrajectory(path); }),
            path + ": cannot open (No such file or directory)");
  EXPECT_EQ(ErrorOf([&] { ReadMonst3rIntrinsics(path, 512, 288); }),
            path + ": cannot open (No such file or directory)");
}

TEST(TrajectoryIo, EmptyFileIsAnEmptyTrajectory) {
  const std::string path = test::MakeTempDir("traj_empty") + "/pred_traj.txt";
  test::WriteFile(path, "");
  EXPECT_TRUE(ReadMonst3rTrajectory(path).empty());
  WriteMonst3rTrajectory(path, Trajectory());
  EXPECT_EQ(test::ReadFile(path), "");
}

TEST(TrajectoryIo, WriteRejectsInvalidTrajectory) {
  const std::string path =
      test::MakeTempDir("traj_write_bad") + "/pred_traj.txt";
  Trajectory t = RandomTrajectory(3);
  t.world_from_cam[1].translation.x() = std::nan("");
  EXPECT_THAT(ErrorOf([&] { WriteMonst3rTrajectory(path, t); }),
              StartsWith(path + ": "));
  EXPECT_FALSE(std::ifstream(path).good());
}

TEST(Monst3rIntrinsics, WritesPercent6fLikeNumpySavetxt) {
  const std::string path =
      test::MakeTempDir("intr_write") + "/pred_intrinsics.txt";
  const PinholeCamera cam(398.0426, 398.0426, 256.0, 144.0, 512, 288);
  WriteMonst3rIntrinsics(path, {cam, cam});
  const std::string line =
      "398.042600 0.000000 256.000000 0.000000 398.042600 144.000000 0.000000 "
      "0.000000 "
      "1.000000\n";
  EXPECT_EQ(test::ReadFile(path), line + line);
}

TEST(Monst3rIntrinsics, ReadsOneCameraPerLine) {
  const std::string path =
      test::MakeTempDir("intr_read") + "/pred_intrinsics.txt";
  test::WriteFile(
      path,
      "398.042633 0.000000 256.000000 0.000000 398.042633 144.000000 "
      "0.000000 0.000000 "
      "1.000000\n"
      "400.5 0 256 0 401.25 144 0 0 1\n");
  const std::vector<PinholeCamera> cams = ReadMonst3rIntrinsics(path, 512, 288);
  ASSERT_EQ(cams.size(), 2u);
  EXPECT_DOUBLE_EQ(cams[0].fx, 398.042633);
  EXPECT_DOUBLE_EQ(cams[0].cx, 256.0);
  EXPECT_DOUBLE_EQ(cams[0].cy, 144.0);
  EXPECT_DOUBLE_EQ(cams[1].fy, 401.25);
  EXPECT_EQ(cams[1].width, 512);
  EXPECT_EQ(cams[1].height, 288);
}

TEST(Monst3rIntrinsics, RoundTripWithin6Decimals) {
  const std::string path =
      test::MakeTempDir("intr_rt") + "/pred_intrinsics.txt";
  std::vector<PinholeCamera> cams;
  std::uniform_real_distribution<double> f(200, 900), c(100, 300);
  for (int i = 0; i < 5; ++i) {
    cams.emplace_back(f(test::Rng()), f(test::Rng()), c(test::Rng()),
                      c(test::Rng()), 512, 288);
  }
  WriteMonst3rIntrinsics(path, cams);
  const std::vector<PinholeCamera> back = ReadMonst3rIntrinsics(path, 512, 288);
  ASSERT_EQ(back.size(), cams.size());
  for (size_t i = 0; i < cams.size(); ++i) {
    // %.6f rounds to the nearest 1e-6: error <= 5e-7 (plus decimal->binary
    // conversion).
    EXPECT_THAT(back[i].K(), test::EigenNear(cams[i].K(), 5e-7 + 1e-12));
  }
}

TEST(Monst3rIntrinsics, RejectsMalformedRows) {
  const std::string path =
      test::MakeTempDir("intr_bad") + "/pred_intrinsics.txt";
  test::WriteFile(path, "400 0 256 0 400 144 0 0\n");
  EXPECT_EQ(ErrorOf([&] { ReadMonst3rIntrinsics(path, 512, 288); }),
            path +
                ": line 1: expected 9 numbers (row-major 3x3 K: fx 0 cx 0 fy "
                "cy 0 0 1), found 8");
  test::WriteFile(path,
                  "400 0 256 0 400 144 0 0 1\n400 3 256 0 400 144 0 0 1\n");
  EXPECT_THAT(ErrorOf([&] { ReadMonst3rIntrinsics(path, 512, 288); }),
              StartsWith(path + ": line 2: not a pinhole K"));
  test::WriteFile(path, "-400 0 256 0 400 144 0 0 1\n");
  EXPECT_THAT(ErrorOf([&] { ReadMonst3rIntrinsics(path, 512, 288); }),
              StartsWith(path + ": line 1: focal lengths must be positive"));
}

}  // namespace
}  // namespace trajectory_io_test
}  // namespace geodrive

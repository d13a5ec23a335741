// Trajectories in the formats users have (geometry/trajectory_io.h,
// trajectory_json.h): KITTI odometry poses (the real 4,541-pose sequence 00),
// COLMAP images.txt, format detection, and TUM output in evo's order.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>

#include "geometry/trajectory_io.h"
#include "geometry/trajectory_json.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

using ::testing::HasSubstr;

void Write(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// The real KITTI odometry sequence 00 poses with its times.txt. Reference
// figures from NumPy on the same files (np.loadtxt, reshape (-1, 3, 4)): 4,541
// poses, 470.5816 s, centre path 3,724.187 m, centre of pose 1000
// (-184.7565, -3.522351, 327.5735), of the last (-5.583931, -3.562758,
// 96.96153); rotations orthonormal to 2.3e-7.
TEST(TrajectoryFormats, ReadsTheRealKittiSequence) {
  const std::string dir = test::RealDataPath("kitti_odometry_00");
  const Trajectory t = ReadKittiTrajectory(dir + "/00.txt", dir + "/times.txt");
  ASSERT_EQ(t.size(), 4541u);
  EXPECT_NEAR(t.Duration(), 470.5816, 1e-9);
  EXPECT_NEAR(t.Length(), 3724.186990597451, 1e-6);
  EXPECT_LT((t.world_from_cam[1000].translation -
             Eigen::Vector3d(-184.7565, -3.522351, 327.5735))
                .norm(),
            1e-9);
  EXPECT_LT((t.world_from_cam.back().translation -
             Eigen::Vector3d(-5.583931, -3.562758, 96.96153))
                .norm(),
            1e-9);
  // Auto detection: 12 numbers per row = KITTI, times.txt beside it used.
  EXPECT_EQ(DetectTrajectoryFormat(dir + "/00.txt"), TrajectoryFormat::kKitti);
  const Trajectory a = ReadTrajectoryAny(dir + "/00.txt");
  ASSERT_EQ(a.size(), 4541u);
  EXPECT_EQ(a.timestamps.back(), t.timestamps.back());
  // To TUM (evo's order) and back: the same poses.
  const std::string tmp = test::MakeTempDir("kitti_tum");
  WriteTumTrajectory(tmp + "/00.tum", t);
  const Trajectory back = ReadTumTrajectory(tmp + "/00.tum");
  ASSERT_EQ(back.size(), t.size());
  double worst = 0;
  for (size_t i = 0; i < t.size(); ++i)
    worst = std::max(worst, (back.world_from_cam[i].translation -
                             t.world_from_cam[i].translation)
                                .norm());
  EXPECT_LT(worst, 1e-5);
}

TEST(TrajectoryFormats, KittiBadInputNamesFileAndLine) {
  const std::string tmp = test::MakeTempDir("kitti_bad");
  Write(tmp + "/short.txt", "1 0 0 0 0 1 0 0 0 0 1\n");
  try {
    ReadKittiTrajectory(tmp + "/short.txt");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("short.txt"));
    EXPECT_THAT(e.what(), HasSubstr("line 1"));
  }
  Write(tmp + "/scaled.txt", "2 0 0 0 0 2 0 0 0 0 2 0\n");
  EXPECT_THROW(ReadKittiTrajectory(tmp + "/scaled.txt"), InputError);
  Write(tmp + "/ok.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 1\n");
  Write(tmp + "/times.txt", "0.0\n");
  try {
    ReadKittiTrajectory(tmp + "/ok.txt", tmp + "/times.txt");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("1 timestamps for 2 poses"));
  }
}

// COLMAP images.txt: cam_from_world with QW first, inverted to
// world_from_cam; frames ordered by image name; the POINTS2D lines (empty or
// not) skipped.
TEST(TrajectoryFormats, ColmapImagesTxtIsInvertedAndOrderedByName) {
  const std::string tmp = test::MakeTempDir("colmap");
  // Two cameras: world_from_cam = yaw 90 deg about y, centre (1, 2, 3); and
  // identity rotation, centre (0, 0, 5).
  const Eigen::Quaterniond q(
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()));
  const Rigid3d a(q, Eigen::Vector3d(1, 2, 3));
  const Rigid3d b(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 5));
  auto line = [](int id, const Rigid3d& world_from_cam, const char* name) {
    const Rigid3d c = world_from_cam.Inverse();
    char buf[256];
    std::snprintf(
        buf, sizeof(buf), "%d %.17g %.17g %.17g %.17g %.17g %.17g %.17g 1 %s\n",
        id, c.rotation.w(), c.rotation.x(), c.rotation.y(), c.rotation.z(),
        c.translation.x(), c.translation.y(), c.translation.z(), name);
    return std::string(buf);
  };
  Write(tmp + "/images.txt",
        "# Image list with two lines of data per image:\n"
        "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n" +
            line(7, b, "frame_0001.jpg") + "100.5 200.5 -1 10.0 20.0 3\n" +
            line(3, a, "frame_0000.jpg") + "\n");
  EXPECT_EQ(DetectTrajectoryFormat(tmp + "/images.txt"),
            TrajectoryFormat::kColmap);
  const Trajectory t = ReadTrajectoryAny(tmp + "/images.txt");
  ASSERT_EQ(t.size(), 2u);
  EXPECT_LT((t.world_from_cam[0].translation - a.translation).norm(), 1e-12);
  EXPECT_LT(t.world_from_cam[0].rotation.angularDistance(a.rotation), 1e-12);
  EXPECT_LT((t.world_from_cam[1].translation - b.translation).norm(), 1e-12);
  Write(tmp + "/bad/images.txt", "");
  std::filesystem::create_directories(tmp + "/bad");
  Write(tmp + "/bad/images.txt", "1 0.5 0 0 0 0 0 0 1 x.jpg\n\n");
  try {
    ReadColmapTrajectory(tmp + "/bad/images.txt");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("line 1: quaternion norm 0.5"));
  }
  // Without its POINTS2D lines every second image would be taken for points:
  // refused, naming the line; and the header's image count is checked.
  std::filesystem::create_directories(tmp + "/nopoints");
  std::filesystem::create_directories(tmp + "/count");
  Write(tmp + "/nopoints/images.txt",
        line(1, a, "a.jpg") + line(2, b, "b.jpg") + line(3, a, "c.jpg"));
  try {
    ReadColmapTrajectory(tmp + "/nopoints/images.txt");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("line 2: expected the 2D points line"));
  }
  Write(tmp + "/count/images.txt",
        "# Number of images: 3, mean observations per image: 0\n" +
            line(1, a, "a.jpg") + "\n" + line(2, b, "b.jpg") + "\n");
  try {
    ReadColmapTrajectory(tmp + "/count/images.txt");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("the header says 3 images, the file "
                                    "holds 2"));
  }
}

}  // namespace
}  // namespace geodrive

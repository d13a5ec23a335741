// End-to-end tests of `geodrive info FILE` on real and deliberately broken
// files: what it prints, and exit code 2 with exactly one line naming the file
// for bad input.

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>

#include "geometry/npy.h"
#include "geometry/trajectory_io.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace info_command_test {
namespace {

using test::GeodriveBinary;
using test::RunCommand;
using ::testing::HasSubstr;

const char kNuscenesSweep[] =
    "nuscenes_n015/"
    "n015-2018-07-24-11-22-45+0800__LIDAR_TOP__1532402927647951.pcd.bin";

// Runs `geodrive info 'path'`, returns the exit code and fills *output (stdout
// + stderr).
int Info(const std::string& path, std::string* output) {
  return RunCommand(GeodriveBinary() + " info '" + path + "'", output);
}

// Bad input: exit 2, exactly one line, naming the file.
void ExpectOneLineError(const std::string& path, const std::string& problem) {
  std::string out;
  EXPECT_EQ(Info(path, &out), 2) << out;
  EXPECT_EQ(test::CountLines(out), 1) << out;
  EXPECT_THAT(out, HasSubstr(path)) << out;
  EXPECT_THAT(out, HasSubstr(problem)) << out;
}

TEST(InfoCommand, NuscenesSweepPrints34688Points) {
  std::string out;
  ASSERT_EQ(Info(test::RealDataPath(kNuscenesSweep), &out), 0) << out;
  EXPECT_THAT(out, HasSubstr("34688 points"));
  EXPECT_THAT(out, HasSubstr("ring 0 .. 31"));
  EXPECT_THAT(out, HasSubstr("intensity 0.000 .. 255.000"));
  std::cout << out;
}

TEST(InfoCommand, KittiScanPrints17238Points) {
  std::string out;
  ASSERT_EQ(Info(test::RealDataPath("kitti_000008/000008.bin"), &out), 0)
      << out;
  EXPECT_THAT(out, HasSubstr("KITTI velodyne scan"));
  EXPECT_THAT(out, HasSubstr("17238 points"));
}

TEST(InfoCommand, MissingNpyExitsTwoWithOneLine) {
  const std::string path = test::MakeTempDir("info_missing") + "/missing.npy";
  ExpectOneLineError(path, "missing.npy");
  // Relative path, as a user would type it.
  std::string out;
  EXPECT_EQ(RunCommand(GeodriveBinary() + " info missing.npy", &out), 2);
  EXPECT_EQ(test::CountLines(out), 1) << out;
  EXPECT_THAT(out, HasSubstr("missing.npy"));
}

TEST(InfoCommand, TruncatedNpyExitsTwoWithOneLine) {
  const std::string path = test::MakeTempDir("info_truncated") + "/frame.npy";
  WriteNpy(path, NpyArray::Zeros(NpyDtype::kFloat32, {288, 512}));
  test::WriteFile(path, test::ReadFile(path).substr(0, 128 + 100));
  ExpectOneLineError(
      path, "truncated: header says 589824 bytes of data, file has 100");
}

TEST(InfoCommand, NpyWithBadHeaderExitsTwoWithOneLine) {
  const std::string path = test::MakeTempDir("info_bad_npy") + "/conf_0.npy";
  test::WriteFile(path, "not numpy at all");
  ExpectOneLineError(path, "not a .npy file");
}

TEST(InfoCommand, NpyPrintsDtypeShapeAndOrder) {
  const std::string path = test::MakeTempDir("info_npy") + "/frame_0000.npy";
  WriteNpy(path, NpyArray::Zeros(NpyDtype::kFloat32, {288, 512}),
           NpyWriteOptions{2, /*fortran_order=*/true, /*big_endian=*/false});
  std::string out;
  ASSERT_EQ(Info(path, &out), 0) << out;
  EXPECT_THAT(out, HasSubstr("npy v2.0, dtype <f4"));
  EXPECT_THAT(out,
              HasSubstr("shape (288, 512), Fortran order, 147456 elements"));
}

TEST(InfoCommand, JpegPrintsSizeAndTruncatedJpegFails) {
  const std::string jpeg = test::RealDataPath(
      "nuscenes_n015/n015-2018-07-24-11-22-45+0800__CAM_FRONT__"
      "1532402927612460.jpg");
  std::string out;
  ASSERT_EQ(Info(jpeg, &out), 0) << out;
  EXPECT_THAT(out, HasSubstr("image 1600x900, 3 channel(s), 8-bit"));
  const std::string cut = test::MakeTempDir("info_jpeg") + "/cut.jpg";
  const std::string bytes = test::ReadFile(jpeg);
  test::WriteFile(cut, bytes.substr(0, bytes.size() / 2));
  ExpectOneLineError(cut, "truncated");
}

TEST(InfoCommand, BrokenPointCloudsExitTwoWithOneLine) {
  const std::string dir = test::MakeTempDir("info_clouds");
  test::WriteFile(dir + "/scan.pcd",
                  "hello\n");  // PCL 1.13 itself would crash on this
  ExpectOneLineError(dir + "/scan.pcd", "malformed PCD header");
  test::WriteFile(dir + "/mesh.ply",
                  "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                  "property float y\nproperty float z\nend_header\n1 2 3\n");
  ExpectOneLineError(dir + "/mesh.ply", "truncated");
  test::WriteFile(dir + "/sweep.pcd.bin", std::string(21, '\0'));
  ExpectOneLineError(dir + "/sweep.pcd.bin",
                     "size 21 bytes is not a multiple of 20");
}

TEST(InfoCommand, TrajectoryFilesUseTheirNamedOrder) {
  const std::string dir = test::MakeTempDir("info_traj");
  test::WriteFile(dir + "/pred_traj.txt",
                  "0.0 0 0 0 1 0 0 0\n1.0 3 4 0 1 0 0 0\n");
  std::string out;
  ASSERT_EQ(Info(dir + "/pred_traj.txt", &out), 0) << out;
  EXPECT_THAT(
      out,
      HasSubstr("MonST3R trajectory (t x y z qw qx qy qz), 2 poses, length 5"));
  test::WriteFile(dir + "/bad_traj.txt",
                  "0.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0\n");
  ExpectOneLineError(dir + "/bad_traj.txt", "line 2: expected 8 numbers");
}

TEST(InfoCommand, WaymoTfrecordPrintsFramesPosesAndCalibrations) {
  std::string out;
  ASSERT_EQ(
      Info(test::RealDataPath("waymo_one_frame/pvps_data_one_frame.tfrecord"),
           &out),
      0)
      << out;
  EXPECT_THAT(out, HasSubstr("Waymo Open Dataset v1 TFRecord, 1 frame(s), "
                             "segment 1024360143612057520_3580_000_3600_000"));
  EXPECT_THAT(out, HasSubstr("frame 0: timestamp 1553735853462203 us, "
                             "world_from_vehicle [0.721910 0.691875"));
  EXPECT_THAT(out, HasSubstr("75 laser_labels"));
  EXPECT_THAT(out, HasSubstr("5 lasers, no range images"));
  EXPECT_THAT(out, HasSubstr("FRONT: 1920x1280, f_u 2044.51"));
  EXPECT_THAT(out, HasSubstr("SIDE_RIGHT: 1920x886"));
  EXPECT_THAT(out, HasSubstr("rolling shutter LEFT_TO_RIGHT"));
  std::cout << out;
}

TEST(InfoCommand, BrokenTfrecordExitsTwoWithOneLine) {
  const std::string real = test::ReadFile(
      test::RealDataPath("waymo_one_frame/pvps_data_one_frame.tfrecord"));
  ASSERT_GT(real.size(), 1000u);
  const std::string dir = test::MakeTempDir("info_tfrecord");
  test::WriteFile(dir + "/cut.tfrecord", real.substr(0, 1000));
  ExpectOneLineError(dir + "/cut.tfrecord",
                     "record 0 (at byte 0): truncated data");
  std::string flipped = real;
  flipped[500] ^= 0x10;
  test::WriteFile(dir + "/flipped.tfrecord", flipped);
  ExpectOneLineError(dir + "/flipped.tfrecord", "data CRC mismatch");
}

}  // namespace
}  // namespace info_command_test
}  // namespace geodrive

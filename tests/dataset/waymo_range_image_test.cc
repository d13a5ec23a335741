// Waymo v1 range images (dataset/waymo/waymo_range_image.h) on synthetic
// MatrixFloats built here: decoding, the row and column conventions of
// waymo_v1.md checked in the vehicle frame (row 0 highest; column 0 looks
// back, W/4 left, W/2 ahead, 3W/4 right, whatever the sensor's yaw), the
// points' ranges, and bad range images as one InputError naming the file,
// the record and the laser.

#include "dataset/waymo/waymo_range_image.h"

#include <gtest/gtest.h>
#include <zlib.h>

#include <Eigen/Geometry>
#include <cmath>
#include <string>
#include <vector>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"
#include "waymo_open_dataset/dataset.pb.h"

namespace geodrive {
// A named namespace, not an anonymous one: the unity build compiles this
// file with others of its folder.
namespace waymo_range_image_test {

using ::testing::AllOf;
using ::testing::HasSubstr;
namespace wod = ::waymo::open_dataset;

std::string Compress(const std::string& bytes) {
  uLongf size = compressBound(bytes.size());
  std::string out(size, '\0');
  EXPECT_EQ(
      compress2(reinterpret_cast<Bytef*>(out.data()), &size,
                reinterpret_cast<const Bytef*>(bytes.data()), bytes.size(), 6),
      Z_OK);
  out.resize(size);
  return out;
}

// zlib of a MatrixFloat of shape `dims` holding `values`.
std::string CompressedMatrix(const std::vector<int>& dims,
                             const std::vector<float>& values) {
  wod::MatrixFloat m;
  for (int d : dims) m.mutable_shape()->add_dims(d);
  for (float v : values) m.add_data(v);
  return Compress(m.SerializeAsString());
}

std::string DecodeError(const std::string& compressed, int channels = 4) {
  try {
    DecodeWaymoRangeImage(compressed, channels, "segment.tfrecord", 3,
                          "laser TOP return 1");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

// A laser 1.8 m up and 0.5 m forward, yawed by `yaw`, tilted a little.
WaymoLaserCalibration Laser(double yaw) {
  WaymoLaserCalibration laser;
  laser.name = WaymoLaserName::kTop;
  laser.beam_inclinations = {-0.3, -0.1, 0.05};  // lowest first, as stored
  Eigen::Matrix4d E = Eigen::Matrix4d::Identity();
  E.topLeftCorner<3, 3>() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  E.topRightCorner<3, 1>() = Eigen::Vector3d(0.5, 0, 1.8);
  laser.vehicle_from_laser = E;
  return laser;
}

TEST(WaymoRangeImage, DecodesShapeAndValues) {
  std::vector<float> values(3 * 8 * 4);
  for (size_t i = 0; i < values.size(); ++i) values[i] = 0.5f * i;
  const WaymoRangeImage image = DecodeWaymoRangeImage(
      CompressedMatrix({3, 8, 4}, values), 4, "f", 0, "laser TOP return 1");
  EXPECT_EQ(image.height, 3);
  EXPECT_EQ(image.width, 8);
  EXPECT_EQ(image.channels, 4);
  EXPECT_EQ(image.at(2, 7, 3), values.back());
  EXPECT_EQ(image.at(1, 2, 1), values[(1 * 8 + 2) * 4 + 1]);
}

TEST(WaymoRangeImage, RowsAndColumnsFollowWaymosConventions) {
  const int H = 3, W = 8;
  for (double yaw : {0.0, 0.3, -2.0, 3.0}) {
    const WaymoLaserCalibration laser = Laser(yaw);
    std::vector<float> values(H * W * 4, 0.0f);
    for (int r = 0; r < H; ++r)
      for (int c = 0; c < W; ++c) values[(r * W + c) * 4] = 10.0f + r + c;
    const WaymoRangeImage image = DecodeWaymoRangeImage(
        CompressedMatrix({H, W, 4}, values), 4, "f", 0, "laser TOP return 1");
    const std::vector<Eigen::Vector3d> points =
        WaymoRangeImagePoints(image, laser);
    ASSERT_EQ(points.size(), static_cast<size_t>(H * W));
    const Eigen::Vector3d origin =
        laser.vehicle_from_laser.topRightCorner<3, 1>();
    for (int r = 0; r < H; ++r) {
      for (int c = 0; c < W; ++c) {
        const Eigen::Vector3d d = points[r * W + c] - origin;
        // The range is the distance from the sensor.
        EXPECT_NEAR(d.norm(), 10.0 + r + c, 1e-5);
        // In the vehicle frame the azimuth of column c is
        // (2 (W - c - 0.5) / W - 1) pi whatever the yaw (up to the 0.01 rad
        // tilt): column 0 just short of +pi (behind), W/4 left, W/2 ahead.
        const double expected = (2.0 * (W - c - 0.5) / W - 1.0) * M_PI;
        double diff = std::atan2(d.y(), d.x()) - expected;
        diff = std::remainder(diff, 2 * M_PI);
        EXPECT_NEAR(diff, 0.0, 0.02) << "yaw " << yaw << " column " << c;
      }
      // Row 0 is the highest beam (0.05 rad), row 2 the lowest (-0.3).
      const double elevation = std::asin((points[r * W] - origin).z() /
                                         (points[r * W] - origin).norm());
      const double kRowInclinations[] = {0.05, -0.1, -0.3};
      EXPECT_NEAR(elevation, kRowInclinations[r], 0.02);
    }
  }
}

TEST(WaymoRangeImage, UniformInclinationsAndEmptyPixels) {
  WaymoLaserCalibration laser = Laser(0.0);
  laser.beam_inclinations.clear();
  laser.beam_inclination_min = -0.4;
  laser.beam_inclination_max = 0.4;
  const std::vector<double> rows = WaymoRowInclinations(laser, 4);
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_NEAR(rows[0], 0.3, 1e-12);  // min + 3.5 / 4 * 0.8, the highest
  EXPECT_NEAR(rows[3], -0.3, 1e-12);
  // Pixels without a return (range <= 0) give no point.
  std::vector<float> values(4 * 2 * 4, 0.0f);
  values[(1 * 2 + 1) * 4] = 7.0f;
  values[(2 * 2 + 0) * 4] = -1.0f;
  const WaymoRangeImage image = DecodeWaymoRangeImage(
      CompressedMatrix({4, 2, 4}, values), 4, "f", 0, "laser TOP return 1");
  EXPECT_EQ(WaymoRangeImagePoints(image, laser).size(), 1u);
}

TEST(WaymoRangeImage, BadRangeImagesNameFileRecordAndLaser) {
  const std::string prefix = "segment.tfrecord: record 3: laser TOP return 1";
  EXPECT_THAT(DecodeError("not zlib at all"),
              AllOf(HasSubstr(prefix), HasSubstr("not valid zlib data")));
  const std::string good = CompressedMatrix({2, 2, 4}, std::vector<float>(16));
  EXPECT_THAT(DecodeError(good.substr(0, good.size() / 2)),
              HasSubstr("not valid zlib data (truncated)"));
  EXPECT_THAT(DecodeError(CompressedMatrix({2, 2, 4}, std::vector<float>(15))),
              HasSubstr("shape [2, 2, 4] needs 16 values, the data has 15"));
  EXPECT_THAT(DecodeError(CompressedMatrix({2, 2, 3}, std::vector<float>(12))),
              HasSubstr("shape [2, 2, 3], expected [H, W, 4]"));
  EXPECT_THAT(DecodeError(good, 6), HasSubstr("expected [H, W, 6]"));
  EXPECT_THAT(DecodeError(Compress("\xff\xff\xff")),
              HasSubstr("not a MatrixFloat message"));
  // No zlib bomb test: deflate cannot exceed 1032:1, under the 1100:1
  // checked while inflating, so a range image costs at most 1032 times its
  // compressed bytes (which the record's size limit bounds).
  // Too few inclinations for the rows.
  const WaymoRangeImage image = DecodeWaymoRangeImage(
      CompressedMatrix({4, 2, 4}, std::vector<float>(32, 1.0f)), 4, "f", 0,
      "laser TOP return 1");
  try {
    WaymoRangeImagePoints(image, Laser(0.0));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(),
                HasSubstr("3 beam inclinations for a range image of 4 rows"));
  }
}

TEST(WaymoRangeImage, TopPixelPosesMovePointsByTheirPose) {
  const int H = 3, W = 4;
  const WaymoLaserCalibration laser = Laser(0.3);
  std::vector<float> values(H * W * 4, 0.0f);
  for (int i = 0; i < H * W; ++i) values[i * 4] = 20.0f + i;
  const WaymoRangeImage image = DecodeWaymoRangeImage(
      CompressedMatrix({H, W, 4}, values), 4, "f", 0, "laser TOP return 1");
  const std::vector<Eigen::Vector3d> still =
      WaymoRangeImagePoints(image, laser);

  // Rz(yaw) Ry(pitch) Rx(roll), written out element by element.
  const double roll = 0.2, pitch = -0.1, yaw = 0.7;
  const double cr = std::cos(roll), sr = std::sin(roll);
  const double cp = std::cos(pitch), sp = std::sin(pitch);
  const double cy = std::cos(yaw), sy = std::sin(yaw);
  Eigen::Matrix4d frame = Eigen::Matrix4d::Identity();
  frame.topLeftCorner<3, 3>() << cy * cp, cy * sp * sr - sy * cr,
      cy * sp * cr + sy * sr,                                   //
      sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr,  //
      -sp, cp * sr, cp * cr;
  frame.topRightCorner<3, 1>() = Eigen::Vector3d(100, -50, 3);

  // Every pixel at the frame pose: the points do not move.
  auto pose_image = [&](const Eigen::Vector3d& shift) {
    std::vector<float> pose(H * W * 6);
    for (int i = 0; i < H * W; ++i) {
      const float p[6] = {float(roll),
                          float(pitch),
                          float(yaw),
                          float(100 + shift.x()),
                          float(-50 + shift.y()),
                          float(3 + shift.z())};
      std::copy(p, p + 6, pose.begin() + 6 * i);
    }
    return DecodeWaymoRangeImage(CompressedMatrix({H, W, 6}, pose), 6, "f", 0,
                                 "laser TOP pose");
  };
  const WaymoRangeImage same = pose_image(Eigen::Vector3d::Zero());
  EXPECT_THAT(WaymoPixelPose(same, 1, 2), test::EigenNear(frame, 1e-6));
  std::vector<Eigen::Vector3d> moved =
      WaymoRangeImagePoints(image, laser, &same, frame);
  ASSERT_EQ(moved.size(), still.size());
  for (size_t i = 0; i < still.size(); ++i)
    EXPECT_THAT(moved[i], test::EigenNear(still[i], 1e-4));

  // Pixels captured 0.5 m further along the world's x: each point is
  // R_frame^T (0.5, 0, 0) further in the vehicle frame.
  const WaymoRangeImage shifted = pose_image(Eigen::Vector3d(0.5, 0, 0));
  moved = WaymoRangeImagePoints(image, laser, &shifted, frame);
  const Eigen::Vector3d offset =
      frame.topLeftCorner<3, 3>().transpose() * Eigen::Vector3d(0.5, 0, 0);
  for (size_t i = 0; i < still.size(); ++i)
    EXPECT_THAT(moved[i],
                test::EigenNear(Eigen::Vector3d(still[i] + offset), 1e-4));

  // A pose image of another size is refused.
  const WaymoRangeImage wrong = DecodeWaymoRangeImage(
      CompressedMatrix({H, W + 1, 6}, std::vector<float>(H * (W + 1) * 6)), 6,
      "f", 0, "laser TOP pose");
  EXPECT_THROW(WaymoRangeImagePoints(image, laser, &wrong, frame), InputError);
}

}  // namespace waymo_range_image_test
}  // namespace geodrive

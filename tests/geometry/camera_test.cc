#include "geometry/camera.h"

#include <gtest/gtest.h>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

using test::EigenNear;

// nuScenes CAM_FRONT-like intrinsics.
PinholeCamera NuscenesFront() { return PinholeCamera(1266.417, 1266.417, 816.267, 491.507, 1600, 900); }

TEST(PinholeCamera, ProjectUnprojectRoundTrip) {
  const PinholeCamera cam = NuscenesFront();
  for (auto conv : {PixelConvention::kIntegerIndex, PixelConvention::kPixelCenter}) {
    const Eigen::Vector3d p(1.2, -0.7, 12.5);
    const Eigen::Vector2d uv = cam.Project(p, conv);
    EXPECT_THAT(cam.Unproject(uv, p.z(), conv), EigenNear(p, 1e-12));
  }
  // Pixel-centre coordinates are the integer-index ones plus 0.5.
  const Eigen::Vector3d p(0.3, 0.2, 5.0);
  EXPECT_THAT((cam.Project(p, PixelConvention::kPixelCenter) -
               cam.Project(p, PixelConvention::kIntegerIndex))
                  .eval(),
              EigenNear(Eigen::Vector2d(0.5, 0.5), 1e-12));
  // The principal point projects the optical axis (integer-index convention, as MonST3R).
  EXPECT_THAT(cam.Project(Eigen::Vector3d(0, 0, 3)), EigenNear(Eigen::Vector2d(cam.cx, cam.cy), 1e-12));
}

TEST(PinholeCamera, KRoundTripAndValidation) {
  const PinholeCamera cam = NuscenesFront();
  const PinholeCamera back = PinholeCamera::FromK(cam.K(), 1600, 900);
  EXPECT_EQ(back.fx, cam.fx);
  EXPECT_EQ(back.cy, cam.cy);
  EXPECT_TRUE(cam.IsValid());
  EXPECT_THROW(PinholeCamera(0, 1, 1, 1, 10, 10).Check(), InputError);
  EXPECT_THROW(PinholeCamera(-5, 5, 1, 1, 10, 10).Check(), InputError);
  EXPECT_THROW(PinholeCamera(5, 5, 1, 1, 0, 10).Check(), InputError);
  EXPECT_THROW(PinholeCamera(5, 5, 1, 1, 20000, 10).Check(), InputError);
  Eigen::Matrix3d bad = cam.K();
  bad(2, 2) = 2;
  EXPECT_THROW(PinholeCamera::FromK(bad, 1600, 900), InputError);
}

// Resizing must map the same 3D point to the resized pixel of the same image content: for the
// integer-index convention, pixel centres satisfy u' + 0.5 = (u + 0.5) * s.
TEST(PinholeCamera, ResizeMapsPixelCentres) {
  const PinholeCamera cam = NuscenesFront();
  const Eigen::Vector3d p(2.0, 1.0, 10.0);
  const Eigen::Vector2d uv = cam.Project(p);
  const PinholeCamera small = ResizeCamera(cam, 512, 288);
  const Eigen::Vector2d uv_small = small.Project(p);
  EXPECT_NEAR(uv_small.x() + 0.5, (uv.x() + 0.5) * 0.32, 1e-9);
  EXPECT_NEAR(uv_small.y() + 0.5, (uv.y() + 0.5) * 0.32, 1e-9);
  // Pixel-centre intrinsics scale without the half-pixel shift.
  const PinholeCamera pc = ResizeCamera(cam, 512, 288, PixelConvention::kPixelCenter);
  EXPECT_NEAR(pc.cx, cam.cx * 0.32, 1e-12);
  EXPECT_NEAR(small.cx, (cam.cx + 0.5) * 0.32 - 0.5, 1e-12);
}

TEST(PinholeCamera, Monst3rSpecFor1600x900Is512x288NoCrop) {
  const ImageResizeSpec spec = ComputeMonst3rResizeSpec(1600, 900);
  EXPECT_EQ(spec.resized_width, 512);
  EXPECT_EQ(spec.resized_height, 288);
  EXPECT_EQ(spec.crop_left, 0);
  EXPECT_EQ(spec.crop_top, 0);
  EXPECT_EQ(spec.width, 512);
  EXPECT_EQ(spec.height, 288);
  const PinholeCamera out = ApplyResizeSpec(NuscenesFront(), spec);
  EXPECT_NEAR(out.fx, 1266.417 * 0.32, 1e-9);
}

TEST(PinholeCamera, Monst3rSpecCropsToMultipleOf16) {
  // KITTI 1242x375 -> 512x155 -> cropped to 512x144 (reference notes A.3).
  const ImageResizeSpec kitti = ComputeMonst3rResizeSpec(1242, 375);
  EXPECT_EQ(kitti.resized_width, 512);
  EXPECT_EQ(kitti.resized_height, 155);
  EXPECT_EQ(kitti.width, 512);
  EXPECT_EQ(kitti.height, 144);
  EXPECT_EQ(kitti.crop_top, 77 - 72);
  // 854x480 (MonST3R demo clip) -> 512x288; 4:3 -> 512x384.
  const ImageResizeSpec demo = ComputeMonst3rResizeSpec(854, 480);
  EXPECT_EQ(demo.width, 512);
  EXPECT_EQ(demo.height, 288);
  const ImageResizeSpec four_three = ComputeMonst3rResizeSpec(640, 480);
  EXPECT_EQ(four_three.width, 512);
  EXPECT_EQ(four_three.height, 384);
}

TEST(PinholeCamera, ResizeTo720x480PlainAndCenterCrop) {
  const PinholeCamera cam = NuscenesFront();
  // Plain resize (GeoDrive training): independent x/y scale.
  const ImageResizeSpec plain = ComputeResizeSpec(1600, 900, 720, 480, ResizeMode::kResize);
  const PinholeCamera a = ApplyResizeSpec(cam, plain);
  EXPECT_NEAR(a.fx, cam.fx * 0.45, 1e-9);
  EXPECT_NEAR(a.fy, cam.fy * 480.0 / 900.0, 1e-9);
  EXPECT_EQ(a.width, 720);
  EXPECT_EQ(a.height, 480);
  // Centre crop (GeoDrive inference): 1600x900 -> 853x480 -> crop 720 wide at left 66.
  const ImageResizeSpec crop = ComputeResizeSpec(1600, 900, 720, 480, ResizeMode::kCenterCrop);
  EXPECT_EQ(crop.resized_width, 853);
  EXPECT_EQ(crop.resized_height, 480);
  EXPECT_EQ(crop.crop_left, 66);
  EXPECT_EQ(crop.crop_top, 0);
  const PinholeCamera b = ApplyResizeSpec(cam, crop);
  const double sx = 853.0 / 1600.0;
  EXPECT_NEAR(b.fx, cam.fx * sx, 1e-9);
  EXPECT_NEAR(b.cx, (cam.cx + 0.5) * sx - 0.5 - 66, 1e-9);
  // A point maps to the same image content: project in the original, transform pixel, compare.
  const Eigen::Vector3d p(-1.0, 0.4, 7.0);
  const Eigen::Vector2d uv = cam.Project(p);
  const Eigen::Vector2d expected((uv.x() + 0.5) * sx - 0.5 - 66, (uv.y() + 0.5) * 480.0 / 900 - 0.5);
  EXPECT_THAT(b.Project(p), EigenNear(expected, 1e-9));
}

TEST(PinholeCamera, ResizeModeParsing) {
  EXPECT_EQ(ParseResizeMode("resize"), ResizeMode::kResize);
  EXPECT_EQ(ParseResizeMode("center-crop"), ResizeMode::kCenterCrop);
  EXPECT_EQ(ToString(ResizeMode::kCenterCrop), "center-crop");
  EXPECT_THROW(ParseResizeMode("stretch"), InputError);
}

}  // namespace
}  // namespace geodrive

// Footprint-aware splats (render/footprint.h): a pointmap seen from closer than
// at capture is drawn without holes, seen as at capture it is the paper's one
// pixel per point, the radius follows the formula and its cap, moving sets
// scale their footprints, and the result does not depend on threads.

#include "render/footprint.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "geometry/util/status.h"
#include "render/renderer.h"
#include "tests/render/render_test_util.h"

namespace geodrive {
namespace {

const PinholeCamera kCamera(300, 300, 159.5, 119.5, 320, 240);

RenderOptions Options(SplatSize splat) {
  RenderOptions o;
  o.width = kCamera.width;
  o.height = kCamera.height;
  o.splat_size = splat;
  o.max_footprint_magnification = 3.0;
  return o;
}

TEST(Footprint, CaptureFootprintIsDepthOverFocal) {
  const PinholeCamera camera(400, 100, 10, 10, 20, 20);  // sqrt(fx fy) = 200
  EXPECT_FLOAT_EQ(CaptureFootprint(camera, 10.0), 0.05f);
  EXPECT_EQ(CaptureFootprint(camera, -1.0), 0.0f);
  PointCloud cloud;
  cloud.positions = {{0, 0, 3}, {1, 2, 7}, {0, 0, -2}};
  // Camera 1 m behind the world origin: depth z + 1.
  SetCaptureFootprints(
      camera, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 1)),
      &cloud);
  ASSERT_EQ(cloud.footprints.size(), 3u);
  EXPECT_FLOAT_EQ(cloud.footprints[0], 4.0f / 200);
  EXPECT_FLOAT_EQ(cloud.footprints[1], 8.0f / 200);
  EXPECT_EQ(cloud.footprints[2], 0.0f);  // behind the camera: one pixel
}

TEST(Footprint, HalfExtentFollowsMagnificationWithMarginAndCap) {
  // L = s f / z; half-extent min(L, cap) / 2 once L > 1.05.
  EXPECT_EQ(FootprintHalfExtent(0.01f, 100, 1.0f, 3), 0.0f);    // L = 1
  EXPECT_EQ(FootprintHalfExtent(0.0104f, 100, 1.0f, 3), 0.0f);  // L = 1.04
  EXPECT_NEAR(FootprintHalfExtent(0.02f, 100, 1.0f, 3), 1.0, 1e-6);
  EXPECT_NEAR(FootprintHalfExtent(0.1f, 100, 1.0f, 3), 1.5, 1e-6);
  EXPECT_EQ(FootprintHalfExtent(0.1f, 100, 1.0f, 1), 0.0f);  // cap 1: off
}

// Pixels drawn for one point with footprint s at depth 10 straight ahead,
// projected onto the centre of pixel (160, 120): the box of half-extent h
// covers the pixels whose centres are within h on both axes.
int DrawnPixels(float footprint, double max_magnification, double scale = 1) {
  const PinholeCamera camera(100, 100, 160, 120, 320, 240);
  RenderOptions o = Options(SplatSize::kFootprint);
  o.max_footprint_magnification = max_magnification;
  PointCloud point;
  point.positions = {{0, 0, 0}};
  point.colors = {Color3u8(200, 100, 50)};
  point.footprints = {footprint};
  RenderResult result;
  if (scale == 1) {
    point.positions[0] = Eigen::Vector3f(0, 0, 10);
    RenderFramesInto(point, {camera}, {Rigid3d()}, o, &result);
  } else {
    // As a moving set scaled by `scale` about its origin, placed at z = 10.
    MovingPointSet set;
    set.points = point;
    Matrix3x4d a = Matrix3x4d::Zero();
    a.leftCols<3>() = scale * Eigen::Matrix3d::Identity();
    a.col(3) = Eigen::Vector3d(0, 0, 10);
    set.world_from_set = {a};
    o.splat_size = SplatSize::kFixed;  // sets use their footprints anyway
    RenderFramesWithMovingSets(PointCloud(), {set}, {camera}, {Rigid3d()}, o,
                               &result);
  }
  return static_cast<int>(result.frames[0].num_valid);
}

TEST(Footprint, DiskPixelCountsMatchTheRadius) {
  // f = 100, z = 10: L = 10 s.
  EXPECT_EQ(DrawnPixels(0.1f, 3), 1);   // L = 1: one pixel
  EXPECT_EQ(DrawnPixels(0.2f, 3), 9);   // L = 2, h = 1: 3 x 3
  EXPECT_EQ(DrawnPixels(0.4f, 5), 25);  // L = 4, h = 2: 5 x 5
  EXPECT_EQ(DrawnPixels(1.0f, 3), 9);   // L = 10 capped at 3, h = 1.5
  EXPECT_EQ(DrawnPixels(1.0f, 1), 1);   // cap 1: one pixel
  // A moving set scaled x2 doubles its footprints: L = 2 from s = 0.1.
  EXPECT_EQ(DrawnPixels(0.1f, 3, 2.0), 9);
  EXPECT_EQ(DrawnPixels(0.1f, 3, 1.0), 1);
}

struct CloserView {
  PointCloud cloud;  // the frame-0 pointmap, with or without footprints
  test::RayCastScene truth;
  Rigid3d cam_from_world;
};

// The ray-cast scene's frame-0 pointmap and the truth seen 5 m further ahead:
// the box face (z = 12) is magnified 12 / 7 = 1.7x, the wall 40 / 35. (The
// ground, seen at a grazing angle, is stretched along the view by about the
// square of that: the isotropic footprint does not know the surface's slope,
// so the test scores the frontal face.)
CloserView MakeCloserView() {
  CloserView v;
  const test::RayCastScene frame0 = test::RayCast(kCamera, Rigid3d());
  v.cloud = test::Unproject(kCamera, Rigid3d(), frame0.depth, frame0.rgb);
  const Rigid3d world_from_cam(Eigen::Quaterniond::Identity(),
                               Eigen::Vector3d(0.2, 0, 5));
  v.truth = test::RayCast(kCamera, world_from_cam);
  v.cam_from_world = world_from_cam.Inverse();
  return v;
}

TEST(Footprint, CloserViewOfAPointmapHasNoHolesOnTheMagnifiedFace) {
  const CloserView v = MakeCloserView();
  // Pixels where the truth sees the box face (depth 12 - 5 = 7, above the
  // ground row at that depth: camera y = (j - cy) z / fy < 1.55).
  cv::Mat face = (v.truth.depth > 6.99) & (v.truth.depth < 7.01);
  face.rowRange(static_cast<int>(kCamera.cy + 1.55 * kCamera.fy / 7.0),
                face.rows) = 0;
  const int face_pixels = cv::countNonZero(face);
  ASSERT_GT(face_pixels, 5000);
  // Pixels where the truth sees the ground (camera y = 1.6 at their depth).
  cv::Mat ground(v.truth.depth.size(), CV_8U, cv::Scalar(0));
  for (int j = 0; j < ground.rows; ++j)
    for (int i = 0; i < ground.cols; ++i) {
      const float d = v.truth.depth.at<float>(j, i);
      ground.at<uint8_t>(j, i) =
          d > 0 && std::abs((j - kCamera.cy) / kCamera.fy * d - 1.6) < 1e-3
              ? 255
              : 0;
    }
  const int ground_pixels = cv::countNonZero(ground);
  ASSERT_GT(ground_pixels, 10000);
  PointCloud square = v.cloud, surface = v.cloud;
  SetCaptureFootprints(kCamera, Rigid3d(), &square, /*surface_axes=*/false);
  SetCaptureFootprints(kCamera, Rigid3d(), &surface);
  ASSERT_EQ(surface.footprint_u.size(), surface.size());
  const RenderedFrame fixed = RenderFrame(v.cloud, kCamera, v.cam_from_world,
                                          Options(SplatSize::kFixed));
  const RenderedFrame splat_square = RenderFrame(
      square, kCamera, v.cam_from_world, Options(SplatSize::kFootprint));
  const RenderedFrame splat = RenderFrame(surface, kCamera, v.cam_from_world,
                                          Options(SplatSize::kFootprint));
  auto cover = [](const RenderedFrame& f, const cv::Mat& where) {
    return cv::countNonZero(where & (f.mask == kMaskValid)) /
           double(cv::countNonZero(where));
  };
  std::printf(
      "face (1.7x): coverage one pixel %.3f, square footprints %.3f, surface "
      "footprints %.3f; ground: %.3f, %.3f, %.3f\n",
      cover(fixed, face), cover(splat_square, face), cover(splat, face),
      cover(fixed, ground), cover(splat_square, ground), cover(splat, ground));
  // One pixel per point covers about 1 / 1.7² of a 1.7x magnified face;
  // either footprint covers all of it.
  EXPECT_LT(cover(fixed, face), 0.5);
  EXPECT_GT(cover(splat_square, face), 0.999);
  EXPECT_GT(cover(splat, face), 0.999);
  // The ground is stretched along the view by up to (z0 / z)², 7x in the
  // bottom rows (frame-0 depth 8 m seen from 3 m): only the surface axes know
  // it, up to the cap (3x by default, 8x here).
  RenderOptions cap8 = Options(SplatSize::kFootprint);
  cap8.max_footprint_magnification = 8;
  const RenderedFrame splat8 =
      RenderFrame(surface, kCamera, v.cam_from_world, cap8);
  std::printf("ground with the cap at 8x: %.3f\n", cover(splat8, ground));
  EXPECT_GT(cover(splat, ground), cover(splat_square, ground) + 0.2);
  EXPECT_GT(cover(splat8, ground), 0.98);
  // Every face pixel shows the face at its depth (holes would show the wall
  // or nothing; splat edges may take a neighbour's depth, within 2 %).
  int wrong_depth_fixed = 0, wrong_depth_splat = 0;
  for (int j = 0; j < face.rows; ++j) {
    for (int i = 0; i < face.cols; ++i) {
      if (!face.at<uint8_t>(j, i)) continue;
      wrong_depth_splat += std::abs(splat.depth.at<float>(j, i) - 7.0f) > 0.15f;
      wrong_depth_fixed += std::abs(fixed.depth.at<float>(j, i) - 7.0f) > 0.15f;
    }
  }
  EXPECT_EQ(wrong_depth_splat, 0);
  EXPECT_GT(wrong_depth_fixed, face_pixels / 2);  // holes: empty or the wall
  // Colour against the ray-cast truth on the face (frontal, sampled at one
  // point per capture pixel; the ground far ahead is sampled once per metre
  // or more and looks blocky when approached).
  const double psnr = test::MaskedPsnr(splat.rgb, v.truth.rgb, face);
  std::printf("PSNR against the ray-cast truth on the face %.1f dB\n", psnr);
  EXPECT_GT(psnr, 20.0);
  // The static cloud without footprints under kFootprint is taken as seen by
  // frame 0 of the render (here: the closer camera), so it draws one pixel per
  // point, exactly as kFixed.
  const RenderedFrame no_fp = RenderFrame(v.cloud, kCamera, v.cam_from_world,
                                          Options(SplatSize::kFootprint));
  EXPECT_TRUE(test::SameBytes(no_fp.rgb, fixed.rgb));
}

// Seen from the capture pose, a pointmap is drawn one pixel per point with
// either footprint (its pixels are not magnified); seen from farther away,
// with the camera-facing square too. (Surface axes seen from another
// direction may be magnified although farther: a footprint stretched along
// the capture ray, the far road, turns sideways with the parallax.)
TEST(Footprint, SeenAsAtCaptureOrFartherItIsOnePixelPerPointByteForByte) {
  const CloserView v = MakeCloserView();
  PointCloud surface = v.cloud, square = v.cloud;
  SetCaptureFootprints(kCamera, Rigid3d(), &surface);
  SetCaptureFootprints(kCamera, Rigid3d(), &square, /*surface_axes=*/false);
  ASSERT_EQ(surface.footprint_u.size(), surface.size());
  const Rigid3d farther =
      Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.3, -0.2, -4))
          .Inverse();
  for (const auto& [cloud, cam_from_world] :
       {std::pair<const PointCloud*, Rigid3d>{&surface, Rigid3d()},
        {&square, Rigid3d()},
        {&square, farther}}) {
    const RenderedFrame fixed = RenderFrame(v.cloud, kCamera, cam_from_world,
                                            Options(SplatSize::kFixed));
    const RenderedFrame splat = RenderFrame(*cloud, kCamera, cam_from_world,
                                            Options(SplatSize::kFootprint));
    EXPECT_TRUE(test::SameBytes(fixed.rgb, splat.rgb));
    EXPECT_TRUE(test::SameBytes(fixed.depth, splat.depth));
    EXPECT_TRUE(test::SameBytes(fixed.mask, splat.mask));
    EXPECT_EQ(fixed.num_projected, splat.num_projected);
  }
  // kFixed ignores the footprints (the paper preset keeps one pixel).
  const RenderedFrame fixed_with = RenderFrame(
      surface, kCamera, v.cam_from_world, Options(SplatSize::kFixed));
  const RenderedFrame fixed_without = RenderFrame(
      v.cloud, kCamera, v.cam_from_world, Options(SplatSize::kFixed));
  EXPECT_TRUE(test::SameBytes(fixed_with.rgb, fixed_without.rgb));
}

TEST(Footprint, OutputDoesNotDependOnThreadsOrPointOrder) {
  const CloserView v = MakeCloserView();
  PointCloud with = v.cloud;
  SetCaptureFootprints(kCamera, Rigid3d(), &with);
  std::vector<Rigid3d> poses;
  for (int f = 0; f < 6; ++f)
    poses.push_back(Rigid3d(Eigen::Quaterniond::Identity(),
                            Eigen::Vector3d(0.1 * f, 0, 1.2 * f))
                        .Inverse());
  RenderOptions o = Options(SplatSize::kFootprint);
  o.num_threads = 1;
  const RenderResult one = RenderFrames(with, {kCamera}, poses, o);
  o.num_threads = 2;
  const RenderResult two = RenderFrames(with, {kCamera}, poses, o);
  // Reversed point order: ties in depth go to the smaller index, so only the
  // index output may differ; colours of equal-depth points may differ only
  // where two points have exactly the same depth at a pixel (none here).
  PointCloud reversed = with;
  std::reverse(reversed.positions.begin(), reversed.positions.end());
  std::reverse(reversed.colors.begin(), reversed.colors.end());
  std::reverse(reversed.footprints.begin(), reversed.footprints.end());
  std::reverse(reversed.footprint_u.begin(), reversed.footprint_u.end());
  std::reverse(reversed.footprint_v.begin(), reversed.footprint_v.end());
  const RenderResult rev = RenderFrames(reversed, {kCamera}, poses, o);
  for (size_t f = 0; f < poses.size(); ++f) {
    EXPECT_TRUE(test::SameBytes(one.frames[f].rgb, two.frames[f].rgb)) << f;
    EXPECT_TRUE(test::SameBytes(one.frames[f].depth, two.frames[f].depth)) << f;
    EXPECT_TRUE(test::SameBytes(one.frames[f].depth, rev.frames[f].depth)) << f;
  }
}

TEST(Footprint, BadOptionsAndFootprintsAreRejected) {
  RenderOptions o = Options(SplatSize::kFootprint);
  o.mode = RenderMode::kSoft;
  EXPECT_THROW(o.Check(), InputError);
  o = Options(SplatSize::kFootprint);
  o.max_footprint_magnification = 0.5;
  EXPECT_THROW(o.Check(), InputError);
  o.max_footprint_magnification = std::nan("");
  EXPECT_THROW(o.Check(), InputError);
  PointCloud cloud;
  cloud.positions = {{0, 0, 5}, {0, 0, 6}};
  cloud.footprints = {0.01f};
  EXPECT_THROW(cloud.Check(), InputError);  // size
  cloud.footprints = {0.01f, -0.5f};
  EXPECT_THROW(cloud.Check(), InputError);  // negative
  o = Options(SplatSize::kFootprint);
  o.radius_px = 2;  // footprints size every point
  EXPECT_THROW(o.Check(), InputError);
  cloud.footprints = {0.01f, 0.02f};
  cloud.footprint_u = {Eigen::Vector3f::Zero()};  // without footprint_v
  EXPECT_THROW(cloud.Check(), InputError);
  EXPECT_EQ(ParseSplatSize("footprint"), SplatSize::kFootprint);
  EXPECT_EQ(ToString(SplatSize::kFixed), "fixed");
  EXPECT_THROW(ParseSplatSize("big"), InputError);
}

}  // namespace
}  // namespace geodrive

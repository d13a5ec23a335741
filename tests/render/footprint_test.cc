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

bool SameBytes(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && a.isContinuous() &&
         b.isContinuous() &&
         std::memcmp(a.data, b.data, a.total() * a.elemSize()) == 0;
}

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

TEST(Footprint, RadiusFollowsMagnificationWithMarginAndCap) {
  // L = s f / z; r² = min(L, cap)² / 2.
  EXPECT_EQ(FootprintRadius2(0.01f, 100, 1.0f, 3), 0.0f);    // L = 1
  EXPECT_EQ(FootprintRadius2(0.0104f, 100, 1.0f, 3), 0.0f);  // L = 1.04
  EXPECT_NEAR(FootprintRadius2(0.02f, 100, 1.0f, 3), 2.0, 1e-5);
  EXPECT_NEAR(FootprintRadius2(0.1f, 100, 1.0f, 3), 4.5, 1e-5);
  EXPECT_EQ(FootprintRadius2(0.1f, 100, 1.0f, 1), 0.0f);  // cap 1: off
}

// Pixels drawn for one point with footprint s at depth 10 straight ahead,
// projected onto the centre of pixel (160, 120): the disk of radius r covers
// the pixels whose centres are within r.
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
  EXPECT_EQ(DrawnPixels(0.2f, 3), 9);   // L = 2, r = 1.414: d² <= 2
  EXPECT_EQ(DrawnPixels(1.0f, 3), 13);  // L = 10 capped at 3, r = 2.12
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
  PointCloud with = v.cloud;
  SetCaptureFootprints(kCamera, Rigid3d(), &with);
  const RenderedFrame fixed = RenderFrame(v.cloud, kCamera, v.cam_from_world,
                                          Options(SplatSize::kFixed));
  const RenderedFrame splat = RenderFrame(with, kCamera, v.cam_from_world,
                                          Options(SplatSize::kFootprint));
  const double fixed_cover =
      cv::countNonZero(face & (fixed.mask == kMaskValid)) / double(face_pixels);
  const double splat_cover =
      cv::countNonZero(face & (splat.mask == kMaskValid)) / double(face_pixels);
  // One pixel per point covers about 1 / 1.7² of a 1.7x magnified face.
  EXPECT_LT(fixed_cover, 0.5);
  EXPECT_GT(splat_cover, 0.999);
  // Where a face pixel shows a point that is not of the face (a hole through
  // which the wall shows), the depth is wrong: with footprints, every face
  // pixel has the face's depth (splat edges may take a neighbour's, ±2 %).
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
  // Colour against the ray-cast truth on the face: the splats reproduce the
  // texture at least as well as the one-pixel render where it has a point.
  const double psnr = test::MaskedPsnr(splat.rgb, v.truth.rgb, face);
  EXPECT_GT(psnr, 20.0);
  // The static cloud without footprints under kFootprint is taken as seen by
  // frame 0 of the render (here: the closer camera), so it draws one pixel per
  // point, exactly as kFixed.
  const RenderedFrame no_fp = RenderFrame(v.cloud, kCamera, v.cam_from_world,
                                          Options(SplatSize::kFootprint));
  EXPECT_TRUE(SameBytes(no_fp.rgb, fixed.rgb));
}

TEST(Footprint, SeenAsAtCaptureOrFartherItIsOnePixelPerPointByteForByte) {
  const CloserView v = MakeCloserView();
  PointCloud with = v.cloud;
  SetCaptureFootprints(kCamera, Rigid3d(), &with);
  // The capture pose itself, and one 4 m behind it (everything smaller).
  for (const Rigid3d& world_from_cam :
       {Rigid3d(), Rigid3d(Eigen::Quaterniond::Identity(),
                           Eigen::Vector3d(0.3, -0.2, -4))}) {
    const Rigid3d cam_from_world = world_from_cam.Inverse();
    const RenderedFrame fixed = RenderFrame(v.cloud, kCamera, cam_from_world,
                                            Options(SplatSize::kFixed));
    const RenderedFrame splat = RenderFrame(with, kCamera, cam_from_world,
                                            Options(SplatSize::kFootprint));
    EXPECT_TRUE(SameBytes(fixed.rgb, splat.rgb));
    EXPECT_TRUE(SameBytes(fixed.depth, splat.depth));
    EXPECT_TRUE(SameBytes(fixed.mask, splat.mask));
    EXPECT_EQ(fixed.num_projected, splat.num_projected);
  }
  // kFixed ignores the footprints (the paper preset keeps one pixel).
  const RenderedFrame fixed_with =
      RenderFrame(with, kCamera, v.cam_from_world, Options(SplatSize::kFixed));
  const RenderedFrame fixed_without = RenderFrame(
      v.cloud, kCamera, v.cam_from_world, Options(SplatSize::kFixed));
  EXPECT_TRUE(SameBytes(fixed_with.rgb, fixed_without.rgb));
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
  const RenderResult rev = RenderFrames(reversed, {kCamera}, poses, o);
  for (size_t f = 0; f < poses.size(); ++f) {
    EXPECT_TRUE(SameBytes(one.frames[f].rgb, two.frames[f].rgb)) << f;
    EXPECT_TRUE(SameBytes(one.frames[f].depth, two.frames[f].depth)) << f;
    EXPECT_TRUE(SameBytes(one.frames[f].depth, rev.frames[f].depth)) << f;
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
  EXPECT_EQ(ParseSplatSize("footprint"), SplatSize::kFootprint);
  EXPECT_EQ(ToString(SplatSize::kFixed), "fixed");
  EXPECT_THROW(ParseSplatSize("big"), InputError);
}

}  // namespace
}  // namespace geodrive

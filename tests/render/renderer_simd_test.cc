// The radius-0 z-buffer's AVX2 projection and 16-pixel resolve against the
// scalar kernels at the edges the main renderer tests do not reach: point
// counts that leave a tail of fewer than 8 points per block, image sizes that
// leave a tail of fewer than 16 pixels, points exactly on pixel borders, on the
// near and far planes, behind the camera and off the image, and runs split by
// hidden points.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <random>

#include "render/renderer.h"
#include "tests/render/render_test_util.h"

namespace geodrive {
namespace {

// Points in front of a camera at the origin (x right, y down, z forward),
// with exact ties, points on pixel borders (u = i + 0.5 in the integer-index
// convention), on the near and far planes, behind the camera and far off the
// image.
PointCloud EdgeCaseCloud(int n, const PinholeCamera& camera) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  PointCloud cloud;
  for (int i = 0; i < n; ++i) {
    float z = 0.5f + 20.0f * unit(rng);
    switch (i % 9) {
      case 0:
        z = 1.0f;
        break;  // near plane (options.near = 1)
      case 1:
        z = 30.0f;
        break;  // far plane
      case 2:
        z = -2.0f;
        break;  // behind the camera
      default:
        break;
    }
    float u = -5.0f + (camera.width + 10.0f) * unit(rng);
    float v = -5.0f + (camera.height + 10.0f) * unit(rng);
    if (i % 7 == 3) u = std::floor(u) + 0.5f;  // on a pixel border
    if (i % 11 == 4) v = std::floor(v) - 0.5f;
    if (i % 13 == 5) u = 1e6f;  // far off the image
    const float x =
        (u - static_cast<float>(camera.cx)) * z / static_cast<float>(camera.fx);
    const float y =
        (v - static_cast<float>(camera.cy)) * z / static_cast<float>(camera.fy);
    cloud.positions.emplace_back(x, y, z);
    cloud.colors.emplace_back(static_cast<uint8_t>(i),
                              static_cast<uint8_t>(i >> 8),
                              static_cast<uint8_t>(3 * i));
    if (i % 17 == 6 && i > 0) {  // an exact duplicate of the previous point
      cloud.positions.back() = cloud.positions[cloud.positions.size() - 2];
    }
  }
  return cloud;
}

// Options for EdgeCaseCloud: the camera's size, near = 1 and far = 30 (the
// planes its points sit on).
RenderOptions EdgeCaseOptions(const PinholeCamera& camera) {
  RenderOptions options;
  options.width = camera.width;
  options.height = camera.height;
  options.near = 1.0;
  options.far = 30.0;
  return options;
}

void ExpectSameFrames(const RenderResult& a,
                      const RenderResult& b,
                      const std::string& what) {
  ASSERT_EQ(a.frames.size(), b.frames.size()) << what;
  for (size_t f = 0; f < a.frames.size(); ++f) {
    const RenderedFrame& x = a.frames[f];
    const RenderedFrame& y = b.frames[f];
    const std::string at = what + " frame " + std::to_string(f);
    EXPECT_EQ(x.num_projected, y.num_projected) << at;
    EXPECT_EQ(x.num_valid, y.num_valid) << at;
    EXPECT_TRUE(test::SameBytes(x.rgb, y.rgb)) << at;
    EXPECT_TRUE(test::SameBytes(x.depth, y.depth)) << at;
    EXPECT_TRUE(test::SameBytes(x.mask, y.mask)) << at;
    EXPECT_TRUE(test::SameBytes(x.index, y.index)) << at;
  }
}

TEST(RendererSimd, RadiusZeroTailsBordersAndPlanesMatchScalar) {
  // 37 x 23 = 851 pixels: 53 chunks of 16 and a tail of 3.
  const PinholeCamera camera(30, 28, 18.0, 11.0, 37, 23);
  std::vector<Rigid3d> poses;
  poses.push_back(Rigid3d());
  poses.push_back(
      Rigid3d(QuaternionFromAngleAxis(Eigen::Vector3d(0.01, -0.02, 0.005)),
              Eigen::Vector3d(0.05, -0.02, 0.1)));
  for (const int n : {1, 7, 8, 9, 517, 1029, 3001}) {
    const PointCloud cloud = EdgeCaseCloud(n, camera);
    for (const bool with_index : {false, true}) {
      RenderOptions options = EdgeCaseOptions(camera);
      options.output_index = with_index;
      options.num_threads = 1;
      const std::string what =
          "n " + std::to_string(n) + (with_index ? " index" : "");
      const bool previous = SetRendererSimdEnabled(true);
      RenderResult simd;
      RenderFramesInto(cloud, {camera}, poses, options, &simd);
      SetRendererSimdEnabled(false);
      RenderResult scalar;
      RenderFramesInto(cloud, {camera}, poses, options, &scalar);
      SetRendererSimdEnabled(previous);
      ExpectSameFrames(simd, scalar, what);
      if (n >= 517) {  // not vacuous: about a third of the points are drawn
        EXPECT_GT(simd.frames[0].num_projected, n / 5) << what;
        EXPECT_GT(simd.frames[0].num_valid, camera.width * camera.height / 10)
            << what;
      }
      // Runs of 1..12 points between hidden points (tails of every length).
      std::vector<size_t> hidden;
      for (size_t i = 3, step = 2; i < cloud.size();
           i += step, step = step % 12 + 1)
        hidden.push_back(i);
      SetRendererSimdEnabled(true);
      RenderResult simd_hidden;
      RenderFramesWithMovingSets(cloud, {}, {camera}, poses, options,
                                 &simd_hidden, hidden);
      SetRendererSimdEnabled(false);
      RenderResult scalar_hidden;
      RenderFramesWithMovingSets(cloud, {}, {camera}, poses, options,
                                 &scalar_hidden, hidden);
      SetRendererSimdEnabled(previous);
      ExpectSameFrames(simd_hidden, scalar_hidden, what + " hidden");
    }
  }
}

// Points in groups of 256 (the culling's groups) that each hug one side of
// the view, on either side of it: the image's four sides at offsets from 1
// pixel down to 1e-5 pixel (about one float ulp at u = 64), the near and far
// planes at relative offsets from 1e-2 down to 1e-7, and exactly on them; so
// some groups lie just outside and others hold points just inside.
// With `margin_px`, the image's sides are those of the image grown by it.
PointCloud BoundaryCloud(const PinholeCamera& camera,
                         double near,
                         double far,
                         double margin_px = 0.0) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double offsets[] = {-1e-2, -1e-4, -1e-6, -1e-7, 0.0, 1e-7, 1e-6, 1e-4};
  PointCloud cloud;
  for (int group = 0; group < 96; ++group) {
    const int side = group % 6;
    const double offset = offsets[(group / 6) % 8];
    for (int i = 0; i < 256; ++i) {
      // Pixel-centre coordinates u, v (border of pixel 0 at -0.5) and depth.
      double u = -0.5 + (camera.width) * unit(rng);
      double v = -0.5 + (camera.height) * unit(rng);
      double z = near + (far - near) * unit(rng);
      const double scale = i % 5 == 0 ? 1.0 : unit(rng);  // spread inward
      // Sides 0-3: before the first / past the last column, then row;
      // 4, 5: the near and far planes.
      const double d = offset * scale;
      if (side < 4) {
        double& c = side < 2 ? u : v;
        const double size = side < 2 ? camera.width : camera.height;
        c = side % 2 == 0 ? -0.5 - margin_px - d * 100
                          : size - 0.5 + margin_px + d * 100;
      } else {
        z = side == 4 ? near * (1 - d) : far * (1 + d);
      }
      cloud.positions.emplace_back(
          static_cast<float>((u - camera.cx) * z / camera.fx),
          static_cast<float>((v - camera.cy) * z / camera.fy),
          static_cast<float>(z));
      cloud.colors.emplace_back(static_cast<uint8_t>(group),
                                static_cast<uint8_t>(i), 7);
    }
  }
  return cloud;
}

// Frustum culling skips groups of points whose box lies outside the view; it
// must never skip a point the per-point test draws. Same bytes and counts
// with culling on and off, on both kernels, for boxes hugging every side of
// the view from a few ulps to 1e-2, seen from the capture pose and from moved
// and rotated ones (world boxes then cut the view at an angle), and for a
// moving set whose first points share a group with the static cloud's last
// ones, in another coordinate frame (the box holds both).
TEST(RendererSimd, CullingSkipsOnlyPointsThatAreNotDrawn) {
  const PinholeCamera camera(52, 48, 31.5, 23.5, 64, 48);
  const double near = 0.5, far = 40.0;
  const PointCloud cloud = BoundaryCloud(camera, near, far);
  std::vector<Rigid3d> poses = {Rigid3d()};
  poses.push_back(Rigid3d(QuaternionFromAngleAxis(Eigen::Vector3d(0, 0.3, 0)),
                          Eigen::Vector3d(0.5, 0, 0)));
  poses.push_back(
      Rigid3d(QuaternionFromAngleAxis(Eigen::Vector3d(0.02, -0.01, 0.7)),
              Eigen::Vector3d(0, 0.2, -0.3)));
  // A set of 300 points behind the camera in its own frame, moved 25 in
  // front: the static cloud's last 16 points (behind the camera) share its
  // group.
  PointCloud statics;
  for (int i = 0; i < 272; ++i) {
    statics.positions.emplace_back(0.01f * i, 0.0f, -5.0f);
    statics.colors.emplace_back(1, 2, 3);
  }
  MovingPointSet set;
  for (int i = 0; i < 300; ++i) {
    set.points.positions.emplace_back(0.02f * (i % 20) - 0.2f,
                                      0.02f * (i / 20) - 0.15f, -10.0f);
    set.points.colors.emplace_back(200, 100, static_cast<uint8_t>(i));
  }
  Matrix3x4d world_from_set = Matrix3x4d::Identity();
  world_from_set(2, 3) = 25.0;
  set.world_from_set.assign(poses.size(), world_from_set);
  for (const bool simd : {true, false}) {
    RenderOptions options;
    options.width = camera.width;
    options.height = camera.height;
    options.near = near;
    options.far = far;
    options.output_index = true;
    options.num_threads = 1;
    const bool previous_simd = SetRendererSimdEnabled(simd);
    const std::string what = simd ? "simd" : "scalar";
    RenderResult culled, unculled;
    RenderFramesInto(cloud, {camera}, poses, options, &culled);
    bool previous = SetRendererCullingEnabled(false);
    RenderFramesInto(cloud, {camera}, poses, options, &unculled);
    SetRendererCullingEnabled(previous);
    ExpectSameFrames(culled, unculled, what);
    // Not vacuous: the boundary groups put points on both sides of the test.
    EXPECT_GT(culled.frames[0].num_projected, 2000) << what;
    EXPECT_LT(culled.frames[0].num_projected,
              static_cast<int64_t>(cloud.size()) - 2000)
        << what;
    RenderResult with_set, with_set_unculled;
    RenderFramesWithMovingSets(statics, {set}, {camera}, poses, options,
                               &with_set);
    previous = SetRendererCullingEnabled(false);
    RenderFramesWithMovingSets(statics, {set}, {camera}, poses, options,
                               &with_set_unculled);
    SetRendererCullingEnabled(previous);
    ExpectSameFrames(with_set, with_set_unculled, what + " moving set");
    EXPECT_EQ(with_set.frames[0].num_projected, 300) << what;
    SetRendererSimdEnabled(previous_simd);
  }
}

// The disk and footprint paths cull with their reach: the image grown by the
// largest half-extent they draw plus one pixel. Same bytes and counts with
// culling on and off for boxes hugging every side of the grown view, for
// disks of radius 1 and 2.5, and for footprints (magnified up to the cap of
// 8, camera-facing and with surface axes).
TEST(RendererSimd, DiskAndFootprintCullingSkipsOnlyPointsThatAreNotDrawn) {
  const PinholeCamera camera(52, 48, 31.5, 23.5, 64, 48);
  const double near = 0.5, far = 40.0;
  const std::vector<Rigid3d> poses = {
      Rigid3d(), Rigid3d(QuaternionFromAngleAxis(Eigen::Vector3d(0, 0.3, 0)),
                         Eigen::Vector3d(0.5, 0, 0))};
  struct Case {
    const char* name;
    double radius;
    bool footprints;
    bool axes;
  };
  const Case cases[] = {{"disk r=1", 1.0, false, false},
                        {"disk r=2.5", 2.5, false, false},
                        {"footprint", 0.0, true, false},
                        {"footprint, axes", 0.0, true, true}};
  const double max_magnification = 8.0;
  for (const Case& c : cases) {
    const double reach =
        c.footprints ? std::max({c.radius, 0.5, 0.5 * max_magnification})
                     : c.radius;
    PointCloud cloud = BoundaryCloud(camera, near, far, reach + 1.0);
    if (c.footprints) {
      // Footprints from 0.5 to 12 capture pixels at the point's depth, so
      // some points are drawn magnified up to the cap; axes as two
      // perpendicular patch vectors of that length.
      std::mt19937 rng(5);
      std::uniform_real_distribution<float> pixels(0.5f, 12.0f);
      for (const Eigen::Vector3f& p : cloud.positions) {
        const float fp = pixels(rng) * std::abs(p.z()) / 52.0f;
        cloud.footprints.push_back(fp);
        if (c.axes) {
          cloud.footprint_u.emplace_back(fp, 0.0f, 0.3f * fp);
          cloud.footprint_v.emplace_back(0.0f, fp, 0.0f);
        }
      }
    }
    for (const bool simd : {true, false}) {
      RenderOptions options;
      options.width = camera.width;
      options.height = camera.height;
      options.near = near;
      options.far = far;
      options.radius_px = c.radius;
      options.output_index = true;
      options.num_threads = 1;
      if (c.footprints) {
        options.splat_size = SplatSize::kFootprint;
        options.max_footprint_magnification = max_magnification;
      }
      const bool previous_simd = SetRendererSimdEnabled(simd);
      const std::string what =
          std::string(c.name) + (simd ? " simd" : " scalar");
      RenderResult culled, unculled;
      RenderFramesInto(cloud, {camera}, poses, options, &culled);
      const bool previous = SetRendererCullingEnabled(false);
      RenderFramesInto(cloud, {camera}, poses, options, &unculled);
      SetRendererCullingEnabled(previous);
      SetRendererSimdEnabled(previous_simd);
      ExpectSameFrames(culled, unculled, what);
      // Not vacuous: points on both sides of the grown view are drawn and
      // skipped.
      EXPECT_GT(culled.frames[0].num_projected, 2000) << what;
      EXPECT_LT(culled.frames[0].num_projected,
                static_cast<int64_t>(cloud.size()) - 2000)
          << what;
    }
  }
}

// The packed colours (AVX2: eight points at a time, a scalar tail) against
// the cloud: every drawn pixel has the colour of the point its index names,
// the default grey (200, 200, 200) when the cloud has no colours, and the
// depth of that point; SIMD and scalar agree.
TEST(RendererSimd, DrawnPixelsCarryTheirPointsColourAndDepth) {
  const PinholeCamera camera(30, 28, 18.0, 11.0, 37, 23);
  for (const bool with_colors : {true, false}) {
    for (const int n : {9, 10, 17, 1029}) {
      PointCloud cloud = EdgeCaseCloud(n, camera);
      if (!with_colors) cloud.colors.clear();
      RenderOptions options = EdgeCaseOptions(camera);
      options.output_index = true;
      const std::string what =
          (with_colors ? "colours n " : "no colours n ") + std::to_string(n);
      const bool previous = SetRendererSimdEnabled(true);
      RenderResult simd;
      RenderFramesInto(cloud, {camera}, {Rigid3d()}, options, &simd);
      SetRendererSimdEnabled(false);
      RenderResult scalar;
      RenderFramesInto(cloud, {camera}, {Rigid3d()}, options, &scalar);
      SetRendererSimdEnabled(previous);
      ExpectSameFrames(simd, scalar, what);
      const RenderedFrame& f = simd.frames[0];
      int drawn = 0;
      for (int y = 0; y < camera.height; ++y) {
        for (int x = 0; x < camera.width; ++x) {
          const int32_t i = f.index.at<int32_t>(y, x);
          if (i < 0) continue;
          ++drawn;
          const cv::Vec3b rgb = f.rgb.at<cv::Vec3b>(y, x);
          const Color3u8 want =
              with_colors ? cloud.colors[i] : Color3u8(200, 200, 200);
          ASSERT_EQ(rgb[0], want[0]) << what << " at " << x << "," << y;
          ASSERT_EQ(rgb[1], want[1]) << what << " at " << x << "," << y;
          ASSERT_EQ(rgb[2], want[2]) << what << " at " << x << "," << y;
          ASSERT_EQ(f.depth.at<float>(y, x), cloud.positions[i].z())
              << what << " at " << x << "," << y;
        }
      }
      if (n == 1029) {
        EXPECT_GT(drawn, 100) << what;
      }
    }
  }
}

// The resolve also resets the key buffer (tails included), so rendering again
// into reused outputs, with the thread's scratch reused, gives the same bytes.
TEST(RendererSimd, ReusedOutputsGiveTheSameBytes) {
  const PinholeCamera camera(30, 28, 18.0, 11.0, 37, 23);
  const PointCloud cloud = EdgeCaseCloud(2000, camera);
  RenderOptions options = EdgeCaseOptions(camera);
  RenderResult first, reused;
  RenderFramesInto(cloud, {camera}, {Rigid3d()}, options, &first);
  RenderFramesInto(cloud, {camera}, {Rigid3d()}, options, &reused);
  RenderFramesInto(cloud, {camera}, {Rigid3d()}, options, &reused);
  ExpectSameFrames(first, reused, "reused");
}

// A call whose outputs exceed 32 MiB (renderer_internal's
// kStreamOutputBytes) writes them with streaming stores from an L1 staging
// block, 64 pixels at a time; the frames must be those of single-frame calls
// (ordinary stores) and of the scalar kernels. 1000 x 700 pixels leave a tail
// of 32 pixels after the last whole block; the index output rides along.
TEST(RendererSimd, StreamedOutputsGiveTheBytesOfOrdinaryStores) {
  const PinholeCamera camera(800, 800, 499.5, 349.5, 1000, 700);
  const PointCloud cloud = EdgeCaseCloud(300000, camera);
  RenderOptions options = EdgeCaseOptions(camera);
  options.output_index = true;
  std::vector<Rigid3d> poses;
  for (int f = 0; f < 4; ++f) {
    poses.emplace_back(
        QuaternionFromAngleAxis(Eigen::Vector3d(0, 0.002 * f, 0.001 * f)),
        Eigen::Vector3d(0.01 * f, 0, -0.05 * f));
  }
  ASSERT_GE(poses.size() * RenderedFrameBytes(options), uint64_t{32} << 20);
  const RenderResult streamed = RenderFrames(cloud, {camera}, poses, options);
  RenderResult single, scalar;
  for (const Rigid3d& pose : poses) {
    single.frames.push_back(RenderFrame(cloud, camera, pose, options));
  }
  const bool previous = SetRendererSimdEnabled(false);
  scalar = RenderFrames(cloud, {camera}, poses, options);
  SetRendererSimdEnabled(previous);
  ExpectSameFrames(streamed, single, "streamed against single frames");
  ExpectSameFrames(streamed, scalar, "streamed against scalar");
  for (const RenderedFrame& frame : streamed.frames)
    EXPECT_GT(frame.num_valid, 700000 / 10);
}

}  // namespace
}  // namespace geodrive

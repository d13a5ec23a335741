#include "render/renderer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <tuple>

#include "geometry/util/status.h"
#include "render/presets.h"
#include "tests/common/test_util.h"
#include "tests/render/render_test_util.h"

namespace geodrive {
namespace {

// A non-trivial world_from_cam so that the tests exercise the pose maths.
Rigid3d SomePose() {
  return Rigid3d(QuaternionFromAngleAxis(Eigen::Vector3d(0.05, -0.3, 0.02)),
                 Eigen::Vector3d(4.0, -1.0, 7.5));
}

// ---- Exactness: frame-0 pointmap rendered from frame 0 reproduces the frame-0
// image. ----

TEST(Renderer, Frame0PointmapReproducesImageZBuffer) {
  const PinholeCamera camera(300, 300, 159.5, 119.5, 320, 240);
  const Rigid3d world_from_cam = SomePose();
  const test::RayCastScene scene = test::RayCast(camera, world_from_cam);
  const PointCloud cloud =
      test::Unproject(camera, world_from_cam, scene.depth, scene.rgb);
  const cv::Mat has_depth = scene.depth > 0;
  const double depth_fraction =
      cv::countNonZero(has_depth) / double(camera.width * camera.height);
  ASSERT_GT(depth_fraction, 0.9);

  RenderOptions options;
  options.width = camera.width;
  options.height = camera.height;
  options.output_index = true;
  const RenderedFrame frame =
      RenderFrame(cloud, camera, world_from_cam.Inverse(), options);
  const cv::Mat valid = frame.mask == kMaskValid;
  const cv::Mat both = valid & has_depth;
  const double psnr = test::MaskedPsnr(frame.rgb, scene.rgb, both);
  const double coverage =
      cv::countNonZero(both) / double(cv::countNonZero(has_depth));
  double max_depth_err = 0;
  for (int j = 0; j < camera.height; ++j) {
    for (int i = 0; i < camera.width; ++i) {
      if (!both.at<uint8_t>(j, i)) continue;
      max_depth_err = std::max<double>(
          max_depth_err,
          std::abs(frame.depth.at<float>(j, i) - scene.depth.at<float>(j, i)));
    }
  }
  std::cout << "[exactness] PSNR over valid pixels " << psnr
            << " dB, coverage of depth pixels " << coverage
            << ", max depth error " << max_depth_err << "\n";
  EXPECT_GE(psnr, 60.0);
  EXPECT_GE(coverage, 0.95);
  EXPECT_LT(max_depth_err, 1e-3);
  // No pixel without depth is rendered valid (no stray points).
  EXPECT_EQ(cv::countNonZero(valid & ~has_depth), 0);
}

TEST(Renderer, Frame0PointmapReproducesImagePixelCenterConvention) {
  const PinholeCamera camera(200, 210, 96.0, 64.0, 192, 128);
  const Rigid3d world_from_cam = SomePose();
  // kPixelCenter reads K as PyTorch3D screen coordinates: pixel i's centre is
  // at u = i + 0.5 (the released pipeline's reading of MonST3R's K).
  const double conv = 0.5;
  const test::RayCastScene scene = test::RayCast(camera, world_from_cam, conv);
  const PointCloud cloud =
      test::Unproject(camera, world_from_cam, scene.depth, scene.rgb, conv);
  RenderOptions options;
  options.width = camera.width;
  options.height = camera.height;
  options.pixel_convention = PixelConvention::kPixelCenter;
  const RenderedFrame frame =
      RenderFrame(cloud, camera, world_from_cam.Inverse(), options);
  const cv::Mat has_depth = scene.depth > 0;
  const cv::Mat both = (frame.mask == kMaskValid) & has_depth;
  const double coverage =
      cv::countNonZero(both) / double(cv::countNonZero(has_depth));
  EXPECT_GE(test::MaskedPsnr(frame.rgb, scene.rgb, both), 60.0);
  EXPECT_GE(coverage, 0.95);
}

// ---- Soft mode against a slow reference of PyTorch3D's rasteriser +
// AlphaCompositor. ----

// PyTorch3D rasterize_points CPU: pixel centre of index i along a side of
// length S1 (other S2).
double PixToNonSquareNdc(int i, int s1, int s2) {
  const double range = s1 > s2 ? 2.0 * s1 / s2 : 2.0;
  const double offset = range / 2.0;
  return -offset + (range * i + offset) / s1;
}

// Reference: PerspectiveCameras(in_ndc=False) maps screen (u, v) = (fx X/Z +
// cx, fy Y/Z + cy) to NDC ((W/2 - u) / s, (H/2 - v) / s), s = min(W, H) / 2 (+X
// left, +Y up); pixel (xi, yi) of the output image has NDC centre
// (PixToNonSquareNdc(W-1-xi, W, H), PixToNonSquareNdc(H-1-yi, H, W)). For each
// pixel: points with z >= 0 and d² < r², the K smallest by (z, index), weights
// 1 - d²/r², C = Σ w_k Π_{j<k}(1 - w_j) c_k.
cv::Mat ReferenceSoft(const PointCloud& cloud,
                      const PinholeCamera& cam,
                      const Rigid3d& cam_from_world,
                      double radius,
                      int k_max) {
  const int w = cam.width, h = cam.height;
  const double s = std::min(w, h) / 2.0;
  cv::Mat out(h, w, CV_64FC3, cv::Scalar::all(0));
  for (int yi = 0; yi < h; ++yi) {
    for (int xi = 0; xi < w; ++xi) {
      const double xf = PixToNonSquareNdc(w - 1 - xi, w, h);
      const double yf = PixToNonSquareNdc(h - 1 - yi, h, w);
      std::vector<std::tuple<double, size_t, double>> hits;  // (z, index, d2)
      for (size_t p = 0; p < cloud.size(); ++p) {
        const Eigen::Vector3d pc =
            cam_from_world * cloud.positions[p].cast<double>();
        if (pc.z() < 0) continue;
        const double u = cam.fx * pc.x() / pc.z() + cam.cx;
        const double v = cam.fy * pc.y() / pc.z() + cam.cy;
        const double xn = (w / 2.0 - u) / s, yn = (h / 2.0 - v) / s;
        const double d2 = (xn - xf) * (xn - xf) + (yn - yf) * (yn - yf);
        if (d2 < radius * radius) hits.emplace_back(pc.z(), p, d2);
      }
      std::sort(hits.begin(), hits.end());
      if (static_cast<int>(hits.size()) > k_max) hits.resize(k_max);
      double cum = 1.0;
      cv::Vec3d c(0, 0, 0);
      for (const auto& [z, p, d2] : hits) {
        const double alpha = 1.0 - d2 / (radius * radius);
        for (int ch = 0; ch < 3; ++ch)
          c[ch] += cum * alpha * cloud.colors[p][ch] / 255.0;
        cum *= 1.0 - alpha;
      }
      out.at<cv::Vec3d>(yi, xi) = c;
    }
  }
  return out;
}

PointCloud RandomOverlappingCloud(int n) {
  std::uniform_real_distribution<double> xy(-1.5, 1.5), zd(3.0, 6.0);
  std::uniform_int_distribution<int> col(0, 255);
  PointCloud cloud;
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3f p(xy(test::Rng()), xy(test::Rng()), zd(test::Rng()));
    cloud.positions.push_back(p);
    cloud.colors.push_back(
        Color3u8(col(test::Rng()), col(test::Rng()), col(test::Rng())));
    if (i % 7 == 0) {  // an exact duplicate (same z: tie broken by index) with
                       // another colour
      cloud.positions.push_back(p);
      cloud.colors.push_back(
          Color3u8(col(test::Rng()), col(test::Rng()), col(test::Rng())));
    }
    if (i % 11 == 0) {  // a nearby point slightly behind: overlapping splats
      cloud.positions.push_back(p + Eigen::Vector3f(0.01f, -0.005f, 0.05f));
      cloud.colors.push_back(
          Color3u8(col(test::Rng()), col(test::Rng()), col(test::Rng())));
    }
  }
  return cloud;
}

TEST(Renderer, SoftMatchesPyTorch3dReference) {
  const PointCloud cloud = RandomOverlappingCloud(400);
  // Non-square, principal point off-centre, non-identity pose.
  const PinholeCamera camera(30, 32, 22.0, 13.0, 40, 28);
  const Rigid3d cam_from_world(
      QuaternionFromAngleAxis(Eigen::Vector3d(0.02, 0.05, -0.03)),
      Eigen::Vector3d(0.1, -0.05, 0.3));
  for (int k_max : {3, 10}) {
    for (double radius : {0.08, 0.2}) {
      RenderOptions options;
      options.mode = RenderMode::kSoft;
      options.width = camera.width;
      options.height = camera.height;
      options.radius_ndc = radius;
      options.points_per_pixel = k_max;
      options.near = 0;
      options.far = std::numeric_limits<double>::infinity();
      options.pixel_convention = PixelConvention::kPixelCenter;
      options.output_float_rgb = true;
      const RenderedFrame frame =
          RenderFrame(cloud, camera, cam_from_world, options);
      const cv::Mat ref =
          ReferenceSoft(cloud, camera, cam_from_world, radius, k_max);
      double max_err = 0;
      int nonzero = 0;
      for (int j = 0; j < camera.height; ++j) {
        for (int i = 0; i < camera.width; ++i) {
          const cv::Vec3f a = frame.rgb_float.at<cv::Vec3f>(j, i);
          const cv::Vec3d b = ref.at<cv::Vec3d>(j, i);
          for (int c = 0; c < 3; ++c)
            max_err = std::max(max_err, std::abs(a[c] - b[c]));
          nonzero += (b[0] + b[1] + b[2]) > 0;
        }
      }
      std::cout << "[soft vs reference] K=" << k_max << " r=" << radius
                << " max abs error " << max_err << " over " << nonzero
                << " non-black pixels\n";
      EXPECT_LE(max_err, 1e-5);
      EXPECT_GT(nonzero, camera.width * camera.height / 4);
    }
  }
}

// ---- Occlusion ----

PointCloud TwoPlanes() {
  PointCloud cloud;
  // Far plane z = 10 (green), covering the whole view; near plane z = 5 (red),
  // a central square.
  for (double y = -6; y <= 6; y += 0.02) {
    for (double x = -8; x <= 8; x += 0.02) {
      cloud.positions.emplace_back(x, y, 10.0);
      cloud.colors.push_back(Color3u8(0, 255, 0));
    }
  }
  for (double y = -1; y <= 1; y += 0.005) {
    for (double x = -1; x <= 1; x += 0.005) {
      cloud.positions.emplace_back(x, y, 5.0);
      cloud.colors.push_back(Color3u8(255, 0, 0));
    }
  }
  return cloud;
}

TEST(Renderer, NearPlaneHidesFarPlaneInBothModes) {
  const PointCloud cloud = TwoPlanes();
  const PinholeCamera camera(60, 60, 39.5, 29.5, 80, 60);
  for (RenderMode mode : {RenderMode::kZBuffer, RenderMode::kSoft}) {
    for (double radius_px : {0.0, 1.5}) {
      RenderOptions options;
      options.mode = mode;
      options.width = 80;
      options.height = 60;
      options.radius_px = radius_px;
      options.radius_ndc = 0.05;
      const RenderedFrame frame =
          RenderFrame(cloud, camera, Rigid3d(), options);
      // The near square spans +-12 px around the centre: check the inner +-9
      // px.
      for (int j = 30 - 9; j <= 30 + 9; ++j) {
        for (int i = 40 - 9; i <= 40 + 9; ++i) {
          const cv::Vec3b c = frame.rgb.at<cv::Vec3b>(j, i);
          ASSERT_EQ(c[1], 0) << ToString(mode) << " pixel " << i << "," << j;
          ASSERT_GT(c[0], 0);
          ASSERT_NEAR(frame.depth.at<float>(j, i), 5.0, 1e-4);
        }
      }
      // The far plane is visible outside.
      EXPECT_GT(frame.rgb.at<cv::Vec3b>(5, 5)[1], 0);
      EXPECT_NEAR(frame.depth.at<float>(5, 5), 10.0, 1e-4);
    }
  }
}

// ---- Splat footprint, near/far, index outputs ----

TEST(Renderer, DiskSplatCoversPixelsWithinRadius) {
  PointCloud cloud;
  // Projects exactly onto pixel centre (10, 10) (integer-index convention).
  cloud.positions.emplace_back(0.0f, 0.0f, 2.0f);
  cloud.colors.push_back(Color3u8(10, 20, 30));
  const PinholeCamera camera(100, 100, 10, 10, 21, 21);
  RenderOptions options;
  options.width = 21;
  options.height = 21;
  options.output_index = true;
  options.radius_px = 1.5;  // offsets with dx² + dy² <= 2.25: the 3x3 block
  RenderedFrame frame = RenderFrame(cloud, camera, Rigid3d(), options);
  EXPECT_EQ(frame.num_valid, 9);
  EXPECT_EQ(frame.mask.at<uint8_t>(11, 11), kMaskValid);
  EXPECT_EQ(frame.mask.at<uint8_t>(10, 12), kMaskInvalid);
  EXPECT_EQ(frame.index.at<int32_t>(9, 9), 0);
  EXPECT_EQ(frame.index.at<int32_t>(0, 0), -1);
  options.radius_px = 2.0;  // adds (±2, 0), (0, ±2): 13 pixels
  frame = RenderFrame(cloud, camera, Rigid3d(), options);
  EXPECT_EQ(frame.num_valid, 13);
  options.radius_px = 0;
  frame = RenderFrame(cloud, camera, Rigid3d(), options);
  EXPECT_EQ(frame.num_valid, 1);
  EXPECT_EQ(frame.rgb.at<cv::Vec3b>(10, 10), cv::Vec3b(10, 20, 30));
}

TEST(Renderer, NearFarRangeAndTieBreakByIndex) {
  PointCloud cloud;
  cloud.positions = {Eigen::Vector3f(0, 0, 0.05f), Eigen::Vector3f(0, 0, 150.f),
                     Eigen::Vector3f(0, 0, 3.f), Eigen::Vector3f(0, 0, 3.f)};
  cloud.colors = {Color3u8(1, 1, 1), Color3u8(2, 2, 2), Color3u8(3, 3, 3),
                  Color3u8(4, 4, 4)};
  cloud.instance_ids = {7, 8, 9, 10};
  const PinholeCamera camera(10, 10, 2, 2, 5, 5);
  RenderOptions options;
  options.width = 5;
  options.height = 5;
  options.output_instance = true;
  for (RenderMode mode : {RenderMode::kZBuffer, RenderMode::kSoft}) {
    options.mode = mode;
    const RenderedFrame f = RenderFrame(cloud, camera, Rigid3d(), options);
    // z = 0.05 < near and z = 150 > far are dropped; equal depths: the smaller
    // index wins.
    EXPECT_FLOAT_EQ(f.depth.at<float>(2, 2), 3.0f);
    EXPECT_EQ(f.instance.at<int32_t>(2, 2), 9);
    EXPECT_EQ(f.instance.at<int32_t>(0, 0), -1);
    if (mode == RenderMode::kZBuffer) {
      EXPECT_EQ(f.rgb.at<cv::Vec3b>(2, 2), cv::Vec3b(3, 3, 3));
    }
  }
}

// ---- Hole filling ----

TEST(Renderer, HoleFillingIsOffByDefaultAndFillsSmallHoles) {
  const PinholeCamera camera(150, 150, 79.5, 59.5, 160, 120);
  const test::RayCastScene scene = test::RayCast(camera, Rigid3d());
  const PointCloud cloud =
      test::Unproject(camera, Rigid3d(), scene.depth, scene.rgb);
  // Move forward 1 m: the near ground stretches and opens one-pixel cracks.
  const Rigid3d cam_from_world(Eigen::Quaterniond::Identity(),
                               Eigen::Vector3d(0, 0, -1.0));
  RenderOptions options;
  options.width = camera.width;
  options.height = camera.height;
  const RenderedFrame plain =
      RenderFrame(cloud, camera, cam_from_world, options);
  EXPECT_EQ(plain.num_filled, 0);
  EXPECT_EQ(cv::countNonZero(plain.mask == kMaskFilled), 0);
  options.hole_fill = true;
  const RenderedFrame filled =
      RenderFrame(cloud, camera, cam_from_world, options);
  std::cout << "[hole fill] valid " << plain.num_valid << " -> valid+filled "
            << filled.num_valid + filled.num_filled << "\n";
  EXPECT_GT(filled.num_filled, 0);
  EXPECT_EQ(filled.num_valid, plain.num_valid);
  EXPECT_EQ(cv::countNonZero(filled.mask == kMaskFilled), filled.num_filled);
  // Filled colours agree with the ray-cast truth better than black does.
  const test::RayCastScene truth =
      test::RayCast(camera, cam_from_world.Inverse());
  const cv::Mat filled_px = filled.mask == kMaskFilled;
  EXPECT_GT(test::MaskedPsnr(filled.rgb, truth.rgb, filled_px),
            test::MaskedPsnr(plain.rgb, truth.rgb, filled_px) + 3.0);
}

// ---- Determinism across thread counts ----

TEST(Renderer, ByteIdenticalWithOneOrManyThreads) {
  const PinholeCamera camera(150, 150, 79.5, 59.5, 160, 120);
  const test::RayCastScene scene = test::RayCast(camera, Rigid3d());
  const PointCloud cloud =
      test::Unproject(camera, Rigid3d(), scene.depth, scene.rgb);
  std::vector<Rigid3d> poses;
  for (int f = 0; f < 9; ++f) {
    poses.emplace_back(QuaternionFromAngleAxis(Eigen::Vector3d(0, 0.01 * f, 0)),
                       Eigen::Vector3d(0.2 * f, 0, -0.5 * f));
  }
  for (RenderMode mode : {RenderMode::kZBuffer, RenderMode::kSoft}) {
    RenderOptions options;
    options.mode = mode;
    options.width = 160;
    options.height = 120;
    options.radius_px = 1.5;
    options.hole_fill = mode == RenderMode::kZBuffer;
    options.output_index = true;
    options.num_threads = 1;
    const RenderResult one = RenderFrames(cloud, {camera}, poses, options);
    options.num_threads = 4;
    const RenderResult many = RenderFrames(cloud, {camera}, poses, options);
    ASSERT_EQ(one.frames.size(), many.frames.size());
    for (size_t f = 0; f < poses.size(); ++f) {
      EXPECT_TRUE(test::SameBytes(one.frames[f].rgb, many.frames[f].rgb)) << f;
      EXPECT_TRUE(test::SameBytes(one.frames[f].depth, many.frames[f].depth))
          << f;
      EXPECT_TRUE(test::SameBytes(one.frames[f].mask, many.frames[f].mask))
          << f;
      EXPECT_TRUE(test::SameBytes(one.frames[f].index, many.frames[f].index))
          << f;
    }
  }
}

// ---- SIMD and scalar kernels agree ----

TEST(Renderer, SimdAndScalarKernelsGiveIdenticalBytes) {
  const PointCloud cloud = RandomOverlappingCloud(3000);
  const PinholeCamera camera(60, 64, 44.0, 26.0, 80, 56);
  const Rigid3d cam_from_world(
      QuaternionFromAngleAxis(Eigen::Vector3d(0.02, 0.05, -0.03)),
      Eigen::Vector3d(0.1, -0.05, 0.3));
  struct Config {
    RenderMode mode;
    double radius_px, radius_ndc;
    int k;
  };
  // Radii spanning one and several 4- / 8-column chunks.
  const Config configs[] = {{RenderMode::kZBuffer, 0.0, 0.01, 1},
                            {RenderMode::kZBuffer, 1.5, 0.01, 1},
                            {RenderMode::kZBuffer, 5.3, 0.01, 1},
                            {RenderMode::kSoft, 0, 0.05, 3},
                            {RenderMode::kSoft, 0, 0.3, 10}};
  for (const Config& cfg : configs) {
    for (const bool with_index : {true, false}) {
      RenderOptions options;
      options.mode = cfg.mode;
      options.width = camera.width;
      options.height = camera.height;
      options.radius_px = cfg.radius_px;
      options.radius_ndc = cfg.radius_ndc;
      options.points_per_pixel = cfg.k;
      options.output_index = with_index;
      options.output_float_rgb = true;
      const bool previous = SetRendererSimdEnabled(true);
      const RenderedFrame simd =
          RenderFrame(cloud, camera, cam_from_world, options);
      SetRendererSimdEnabled(false);
      const RenderedFrame scalar =
          RenderFrame(cloud, camera, cam_from_world, options);
      SetRendererSimdEnabled(previous);
      const std::string what = ToString(cfg.mode) + " r_px " +
                               std::to_string(cfg.radius_px) + " r_ndc " +
                               std::to_string(cfg.radius_ndc);
      EXPECT_GT(simd.num_valid, camera.width * camera.height / 4) << what;
      EXPECT_EQ(simd.num_projected, scalar.num_projected) << what;
      EXPECT_TRUE(test::SameBytes(simd.rgb, scalar.rgb)) << what;
      EXPECT_TRUE(test::SameBytes(simd.rgb_float, scalar.rgb_float)) << what;
      EXPECT_TRUE(test::SameBytes(simd.depth, scalar.depth)) << what;
      EXPECT_TRUE(test::SameBytes(simd.mask, scalar.mask)) << what;
      if (with_index) {
        EXPECT_TRUE(test::SameBytes(simd.index, scalar.index)) << what;
      }
    }
  }
}

// ---- Static cloud plus moving point sets ----

// Static cloud + sets as one cloud for frame f: each drawn set mapped by its
// transform (in double, rounded once to float), undrawn sets' points moved
// behind the camera so that every point keeps its index.
PointCloud ConcatenateForFrame(const PointCloud& static_cloud,
                               const std::vector<MovingPointSet>& sets,
                               const Rigid3d& cam_from_world,
                               int f) {
  PointCloud all = static_cloud;
  all.instance_ids.assign(static_cloud.size(), -1);
  const Rigid3d world_from_cam = cam_from_world.Inverse();
  for (const MovingPointSet& set : sets) {
    const std::optional<Matrix3x4d>& a = set.world_from_set[f];
    for (size_t i = 0; i < set.points.size(); ++i) {
      const Eigen::Vector3d p = set.points.positions[i].cast<double>();
      const Eigen::Vector3d w =
          a ? Eigen::Vector3d(a->leftCols<3>() * p + a->col(3))
            : world_from_cam * Eigen::Vector3d(0, 0, -10);
      all.positions.push_back(w.cast<float>());
      all.colors.push_back(set.points.colors[i]);
      all.instance_ids.push_back(set.instance_id);
    }
  }
  return all;
}

RenderOptions MovingSetOptions(const PinholeCamera& camera, RenderMode mode) {
  RenderOptions options;
  options.mode = mode;
  options.width = camera.width;
  options.height = camera.height;
  options.radius_px = 1.5;
  options.radius_ndc = 0.05;
  options.output_index = true;
  options.output_instance = true;
  options.num_threads = 2;
  return options;
}

// Five camera poses moving forward and turning slightly.
std::vector<Rigid3d> MovingSetCameraPoses() {
  std::vector<Rigid3d> poses;
  for (int f = 0; f < 5; ++f)
    poses.emplace_back(QuaternionFromAngleAxis(Eigen::Vector3d(0, 0.01 * f, 0)),
                       Eigen::Vector3d(0.05 * f, 0, -0.1 * f));
  return poses;
}

TEST(Renderer, MovingSetsWithIdentityPosesEqualTheConcatenatedCloudExactly) {
  // Identity transforms compose to exactly the camera's projection, so the
  // result must be byte-identical: index layout, ties (static first, then
  // set order; the random clouds hold exact duplicates), colours, instances,
  // frames where a set is not drawn.
  const PinholeCamera camera(60, 64, 44.0, 26.0, 80, 56);
  const PointCloud static_cloud = RandomOverlappingCloud(1500);
  const std::vector<Rigid3d> poses = MovingSetCameraPoses();
  std::vector<MovingPointSet> sets(2);
  for (int k = 0; k < 2; ++k) {
    sets[k].points = RandomOverlappingCloud(300);
    sets[k].instance_id = 7 + k;
    sets[k].world_from_set.resize(poses.size());
    for (int f = 0; f < 5; ++f)
      if (f != 3 - k) sets[k].world_from_set[f] = Rigid3d().ToMatrix3x4();
  }
  // A point of set 1 exactly on a static point and on a set-0 point: the
  // static one must win, then set 0.
  sets[0].points.positions[5] = static_cloud.positions[10];
  sets[1].points.positions[6] = static_cloud.positions[10];
  // Hidden static points: runs at the start, in the middle and at the end,
  // and single points; the reference moves them behind the camera.
  std::vector<size_t> hidden;
  for (size_t i = 0; i < static_cloud.size(); ++i)
    if (i < 3 || (i >= 200 && i < 260) || i % 97 == 5 ||
        i + 2 >= static_cloud.size())
      hidden.push_back(i);
  for (RenderMode mode : {RenderMode::kZBuffer, RenderMode::kSoft}) {
    const RenderOptions options = MovingSetOptions(camera, mode);
    RenderResult moving;
    RenderFramesWithMovingSets(static_cloud, sets, {camera}, poses, options,
                               &moving, hidden);
    ASSERT_EQ(moving.frames.size(), poses.size());
    int set_pixels[2] = {0, 0};
    for (size_t f = 0; f < poses.size(); ++f) {
      PointCloud all = ConcatenateForFrame(static_cloud, sets, poses[f],
                                           static_cast<int>(f));
      for (size_t i : hidden)
        all.positions[i] =
            (poses[f].Inverse() * Eigen::Vector3d(0, 0, -10)).cast<float>();
      const RenderedFrame ref = RenderFrame(all, camera, poses[f], options);
      const RenderedFrame& got = moving.frames[f];
      EXPECT_TRUE(test::SameBytes(ref.rgb, got.rgb))
          << ToString(mode) << " " << f;
      EXPECT_TRUE(test::SameBytes(ref.depth, got.depth)) << f;
      EXPECT_TRUE(test::SameBytes(ref.index, got.index)) << f;
      EXPECT_TRUE(test::SameBytes(ref.instance, got.instance)) << f;
      EXPECT_EQ(ref.num_projected, got.num_projected) << f;
      for (int k = 0; k < 2; ++k)
        set_pixels[k] += cv::countNonZero(got.instance == 7 + k);
    }
    EXPECT_GT(set_pixels[0], 100) << ToString(mode);
    EXPECT_GT(set_pixels[1], 100) << ToString(mode);
  }
}

TEST(Renderer, MovingSetsFollowTheirTransforms) {
  // Rotated, scaled and translated sets against the concatenated cloud mapped
  // in double: the composed float projection rounds differently, which can
  // move a disk edge across a pixel centre, so a few pixels may differ.
  const PinholeCamera camera(60, 64, 44.0, 26.0, 80, 56);
  const PointCloud static_cloud = RandomOverlappingCloud(1500);
  const std::vector<Rigid3d> poses = MovingSetCameraPoses();
  std::vector<MovingPointSet> sets(2);
  for (int k = 0; k < 2; ++k) {
    PointCloud c = RandomOverlappingCloud(300);
    for (Eigen::Vector3f& p : c.positions) p -= Eigen::Vector3f(0, 0, 4.5f);
    sets[k].points = c;  // centred near the origin of the set's frame
    sets[k].instance_id = 7 + k;
    sets[k].world_from_set.resize(poses.size());
    for (int f = 0; f < 5; ++f) {
      if (f == 3 && k == 0) continue;  // not drawn
      Matrix3x4d a;
      a.leftCols<3>() =
          QuaternionFromAngleAxis(Eigen::Vector3d(0.1 * f, 0.2 * k, 0.05))
              .toRotationMatrix() *
          Eigen::Vector3d(0.5, 0.6 + 0.1 * f, 0.4).asDiagonal();
      a.col(3) = Eigen::Vector3d(0.3 * f - 0.5 + k, 0.1 * k, 4.0 + 0.3 * k);
      sets[k].world_from_set[f] = a;
    }
  }
  for (RenderMode mode : {RenderMode::kZBuffer, RenderMode::kSoft}) {
    const RenderOptions options = MovingSetOptions(camera, mode);
    RenderResult moving;
    RenderFramesWithMovingSets(static_cloud, sets, {camera}, poses, options,
                               &moving);
    int64_t same = 0, total = 0, set_pixels = 0;
    double max_depth_error = 0;
    for (size_t f = 0; f < poses.size(); ++f) {
      const PointCloud all = ConcatenateForFrame(static_cloud, sets, poses[f],
                                                 static_cast<int>(f));
      const RenderedFrame ref = RenderFrame(all, camera, poses[f], options);
      const RenderedFrame& got = moving.frames[f];
      for (int j = 0; j < got.index.rows; ++j) {
        for (int i = 0; i < got.index.cols; ++i) {
          ++total;
          const int32_t a = got.index.at<int32_t>(j, i);
          if (a != ref.index.at<int32_t>(j, i)) continue;
          ++same;
          set_pixels += got.instance.at<int32_t>(j, i) >= 7;
          if (a >= 0)
            max_depth_error = std::max<double>(
                max_depth_error, std::abs(got.depth.at<float>(j, i) -
                                          ref.depth.at<float>(j, i)));
        }
      }
    }
    std::printf(
        "%s: %lld of %lld pixels keep the same point, %lld on sets, "
        "max depth difference %.2g\n",
        ToString(mode).c_str(), static_cast<long long>(same),
        static_cast<long long>(total), static_cast<long long>(set_pixels),
        max_depth_error);
    EXPECT_GE(same, total * 995 / 1000) << ToString(mode);
    EXPECT_GT(set_pixels, 500) << ToString(mode);
    EXPECT_LT(max_depth_error, 1e-5) << ToString(mode);
    EXPECT_EQ(cv::countNonZero(moving.frames[3].instance == 7), 0);
  }
}

// The static cloud's positions are tested as they are packed: the first
// point that is not finite is named, in every mode, and a cloud whose
// attribute sizes disagree is rejected before anything is packed.
TEST(Renderer, CloudThatIsNotFiniteIsAnError) {
  const PinholeCamera camera(60, 64, 44.0, 26.0, 80, 56);
  const std::vector<Rigid3d> poses(2);
  const PointCloud good = RandomOverlappingCloud(300);
  struct Case {
    RenderMode mode;
    SplatSize splat;
    double radius;
  };
  for (const Case& c : {Case{RenderMode::kZBuffer, SplatSize::kFixed, 0.0},
                        Case{RenderMode::kZBuffer, SplatSize::kFixed, 1.5},
                        Case{RenderMode::kZBuffer, SplatSize::kFootprint, 0.0},
                        Case{RenderMode::kSoft, SplatSize::kFixed, 0.0}}) {
    RenderOptions options;
    options.width = camera.width;
    options.height = camera.height;
    options.mode = c.mode;
    options.splat_size = c.splat;
    options.radius_px = c.radius;
    RenderResult r;
    RenderFramesInto(good, {camera}, poses, options, &r);
    EXPECT_GT(r.frames[0].num_valid, 0);
    for (int coordinate = 0; coordinate < 3; ++coordinate) {
      for (const float bad : {NAN, INFINITY, -INFINITY}) {
        PointCloud cloud = good;
        cloud.positions[211][coordinate] = bad;
        cloud.positions[250][0] = NAN;  // a later one is not reported
        try {
          RenderFramesInto(cloud, {camera}, poses, options, &r);
          ADD_FAILURE() << "no error, mode " << ToString(c.mode);
        } catch (const InputError& e) {
          EXPECT_NE(std::string(e.what()).find(
                        "render: point cloud: point 211 is not finite"),
                    std::string::npos)
              << e.what();
        }
        // The same cloud as the static part of a scene with a moving set.
        MovingPointSet set;
        set.points = RandomOverlappingCloud(30);
        set.world_from_set.assign(poses.size(), Rigid3d().ToMatrix3x4());
        try {
          RenderFramesWithMovingSets(cloud, {set}, {camera}, poses, options,
                                     &r);
          ADD_FAILURE() << "no error with a moving set, mode "
                        << ToString(c.mode);
        } catch (const InputError& e) {
          EXPECT_NE(std::string(e.what()).find(
                        "render: static point cloud: point 211 is not finite"),
                    std::string::npos)
              << e.what();
        }
      }
    }
    PointCloud short_colors = good;
    short_colors.colors.resize(10);
    short_colors.positions[5].x() = NAN;
    try {
      RenderFramesInto(short_colors, {camera}, poses, options, &r);
      ADD_FAILURE() << "no error for 10 colours";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("'colors' has 10 entries"),
                std::string::npos)
          << e.what();
    }
  }
}

TEST(Renderer, MovingSetsBadInputIsAnError) {
  const PinholeCamera camera(60, 64, 44.0, 26.0, 80, 56);
  const std::vector<Rigid3d> poses(3);
  RenderOptions options;
  options.width = camera.width;
  options.height = camera.height;
  MovingPointSet set;
  set.points = RandomOverlappingCloud(50);
  set.world_from_set.assign(3, Rigid3d().ToMatrix3x4());
  // Only moving points (no static cloud) render.
  RenderResult only;
  RenderFramesWithMovingSets(PointCloud(), {set}, {camera}, poses, options,
                             &only);
  EXPECT_GT(only.frames[0].num_valid, 0);
  auto throws_with = [&](const MovingPointSet& bad, const std::string& text) {
    RenderResult r;
    try {
      RenderFramesWithMovingSets(PointCloud(), {bad}, {camera}, poses, options,
                                 &r);
      ADD_FAILURE() << "no error for " << text;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos)
          << e.what();
    }
  };
  MovingPointSet nan_point = set;
  nan_point.points.positions[4].z() = NAN;
  throws_with(nan_point, "point 4 is not finite");
  MovingPointSet short_poses = set;
  short_poses.world_from_set.resize(2);
  throws_with(short_poses, "2 poses for 3 frames");
  MovingPointSet inf_pose = set;
  (*inf_pose.world_from_set[1])(0, 3) = INFINITY;
  throws_with(inf_pose, "frame 1 transform has NaN or Inf");
  // Hidden static indices out of order or out of range.
  const PointCloud static_cloud = RandomOverlappingCloud(20);
  for (const std::vector<size_t>& hidden :
       {std::vector<size_t>{3, 2}, std::vector<size_t>{4, 4},
        std::vector<size_t>{static_cloud.size()}}) {
    RenderResult r;
    EXPECT_THROW(RenderFramesWithMovingSets(static_cloud, {set}, {camera},
                                            poses, options, &r, hidden),
                 InputError);
  }
}

// ---- Camera resizing to the output size ----

TEST(Renderer, CameraIsRescaledToOutputSize) {
  const PinholeCamera camera(300, 300, 159.5, 119.5, 320, 240);
  const test::RayCastScene scene = test::RayCast(camera, Rigid3d());
  const PointCloud cloud =
      test::Unproject(camera, Rigid3d(), scene.depth, scene.rgb);
  RenderOptions options;
  options.width = 160;
  options.height = 120;
  const RenderedFrame half = RenderFrame(cloud, camera, Rigid3d(), options);
  EXPECT_EQ(half.rgb.cols, 160);
  EXPECT_EQ(half.rgb.rows, 120);
  // Every output pixel receives some of the 4 points that map into it.
  const double depth_fraction =
      cv::countNonZero(scene.depth > 0) / double(320 * 240);
  EXPECT_GE(half.coverage(), depth_fraction - 0.02);
}

// ---- Presets ----

TEST(RenderPresets, GeodriveCompatUpsamplesAndReplacesFrame0) {
  const RenderOptions o = PresetRenderOptions(RenderPreset::kGeodriveCompat);
  EXPECT_EQ(o.mode, RenderMode::kSoft);
  EXPECT_EQ(o.width, 512);
  EXPECT_EQ(o.height, 288);
  EXPECT_DOUBLE_EQ(o.radius_ndc, 0.01);
  EXPECT_EQ(o.points_per_pixel, 10);
  const PinholeCamera camera(400, 400, 256, 144, 512, 288);
  const test::RayCastScene scene = test::RayCast(camera, Rigid3d());
  const PointCloud cloud =
      test::Unproject(camera, Rigid3d(), scene.depth, scene.rgb);
  const RenderResult result = RenderFrames(
      cloud, {camera},
      {Rigid3d(),
       Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, -1))},
      o);
  const cv::Mat real(288, 512, CV_8UC3, cv::Scalar(1, 2, 3));
  const std::vector<cv::Mat> frames =
      FinalFrames(result, RenderPreset::kGeodriveCompat, real);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[1].cols, 1024);
  EXPECT_EQ(frames[1].rows, 576);
  EXPECT_EQ(frames[0].at<cv::Vec3b>(100, 100), cv::Vec3b(1, 2, 3));
  // Upsampled pixels inside a smooth region equal the low-res render there (±1
  // rounding).
  const cv::Vec3b lo = result.frames[1].rgb.at<cv::Vec3b>(200, 256);
  const cv::Vec3b hi = frames[1].at<cv::Vec3b>(400, 512);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(lo[c], hi[c], 40);
  EXPECT_EQ(ParseRenderPreset("paper"), RenderPreset::kPaper);
  EXPECT_THROW(ParseRenderPreset("nope"), InputError);
}

// ---- Bad input ----

TEST(RendererBadInput, ClearErrors) {
  PointCloud cloud;
  const PinholeCamera camera(100, 100, 50, 50, 100, 100);
  RenderOptions options;
  options.width = 100;
  options.height = 100;
  EXPECT_THROW(RenderFrame(cloud, camera, Rigid3d(), options),
               InputError);  // empty cloud
  cloud.positions.emplace_back(0, 0, 5);
  cloud.colors.push_back(Color3u8(1, 2, 3));
  EXPECT_NO_THROW(RenderFrame(cloud, camera, Rigid3d(), options));

  PinholeCamera bad = camera;
  bad.fx = 0;
  EXPECT_THROW(RenderFrame(cloud, bad, Rigid3d(), options), InputError);
  bad.fx = -100;
  EXPECT_THROW(RenderFrame(cloud, bad, Rigid3d(), options), InputError);

  Rigid3d nan_pose;
  nan_pose.translation.x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(RenderFrame(cloud, camera, nan_pose, options), InputError);
  Rigid3d skew_pose;
  skew_pose.rotation.coeffs() << 0.1, 0.0, 0.0,
      1.2;  // |q| != 1: not a rotation
  try {
    RenderFrames(cloud, {camera}, {Rigid3d(), skew_pose}, options);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("frame 1"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("orthonormal"), std::string::npos)
        << e.what();
  }

  for (auto [w, h] : {std::pair{0, 100}, std::pair{100, 0},
                      std::pair{16385, 100}, std::pair{100, 16385}}) {
    RenderOptions o = options;
    o.width = w;
    o.height = h;
    EXPECT_THROW(RenderFrame(cloud, camera, Rigid3d(), o), InputError)
        << w << "x" << h;
  }
  PointCloud nan_cloud = cloud;
  nan_cloud.positions[0].x() = std::numeric_limits<float>::infinity();
  EXPECT_THROW(RenderFrame(nan_cloud, camera, Rigid3d(), options), InputError);
  EXPECT_THROW(RenderFrames(cloud, {camera, camera},
                            {Rigid3d(), Rigid3d(), Rigid3d()}, options),
               InputError);
  EXPECT_THROW(ParseRenderMode("fancy"), InputError);
}

TEST(RendererBadInput, AllPointsBehindCameraGiveAllInvalidFrameReported) {
  PointCloud cloud;
  for (int i = 0; i < 100; ++i) {
    cloud.positions.emplace_back(0.01f * i, 0.0f, -1.0f - i);
    cloud.colors.push_back(Color3u8(255, 255, 255));
  }
  const PinholeCamera camera(100, 100, 50, 50, 100, 100);
  for (RenderMode mode : {RenderMode::kZBuffer, RenderMode::kSoft}) {
    RenderOptions options;
    options.mode = mode;
    options.width = 100;
    options.height = 100;
    const RenderResult r =
        RenderFrames(cloud, {camera}, {Rigid3d(), Rigid3d()}, options);
    EXPECT_EQ(r.frames[0].num_valid, 0);
    EXPECT_EQ(cv::countNonZero(r.frames[0].mask), 0);
    EXPECT_EQ(r.summary.empty_frames, (std::vector<int>{0, 1}));
    EXPECT_NE(r.summary.BriefReport().find("all-invalid"), std::string::npos);
  }
}

}  // namespace
}  // namespace geodrive

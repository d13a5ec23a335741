// Depth completion (geometry/depth_completion.h) and the lidar-dense scene
// source: exact truth on synthetic depth images, held-out LiDAR
// returns and frame-0 coverage on the real nuScenes scene-0916.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>

#include "dataset/build_dataset.h"
#include "dataset/drive_dataset.h"
#include "dataset/pairs.h"
#include "dataset/scene/lidar_sweeps.h"
#include "dataset/scene_source.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "dataset/synthetic/synthetic_world.h"
#include "geometry/depth_completion.h"
#include "geometry/image_io.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"
#include "render/presets.h"
#include "render/renderer.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace lidar_dense_test {
namespace {

// A wall at 20 m seen through scan lines every 9 rows from row 60 down to the
// bottom, one return every 2 columns, and a box at 8 m in front of it.
cv::Mat ScanLines(int height, int width) {
  cv::Mat sparse(height, width, CV_32F, cv::Scalar(0));
  for (int y = 60; y < height; y += 9)
    for (int x = 0; x < width; x += 2)
      sparse.at<float>(y, x) = (x >= 100 && x < 160 && y >= 120) ? 8.f : 20.f;
  return sparse;
}

TEST(DepthCompletion, WallAndBoxFromScanLines) {
  const int h = 240, w = 320;
  DepthCompletionReport report;
  const cv::Mat dense = CompleteDepth(ScanLines(h, w), {}, &report);
  // Rows above the top scan line have no support and stay empty.
  for (int y = 0; y < 60; ++y)
    for (int x = 0; x < w; ++x) ASSERT_EQ(dense.at<float>(y, x), 0.f);
  EXPECT_NEAR(report.supported_fraction, (h - 60.0) / h, 1e-12);
  // Every supported pixel is filled (scan lines 9 rows apart, the last at
  // row 231: the large fill reaches 15 rows below it).
  EXPECT_EQ(report.coverage_of_supported, 1.0);
  EXPECT_NEAR(report.coverage, (h - 60.0) / h, 1e-12);
  EXPECT_EQ(report.input_pixels, 20 * (w / 2));
  // Away from the box edges (beyond the reach of the dilations, 2 + 3 + 15
  // pixels, plus the blurs' 2 on each side of the box's columns 100..159), the
  // wall and the box keep their depth (float rounding of the inversion
  // 100 - d + 0.001 and back: < 1e-4 m).
  for (int y = 60; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const bool near_edge = (x > 70 && x < 190 && y > 90);
      const bool in_box = (x >= 116 && x < 144 && y >= 136);
      if (!near_edge) {
        ASSERT_NEAR(dense.at<float>(y, x), 20.f, 1e-4) << x << "," << y;
      } else if (in_box) {
        ASSERT_NEAR(dense.at<float>(y, x), 8.f, 1e-4) << x << "," << y;
      }
    }
  }
  // The dilations keep the nearest surface: near the box's edges the fill
  // takes 8 m, never a depth between the two surfaces beyond the blur.
  int between = 0;
  for (int y = 60; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float d = dense.at<float>(y, x);
      between += d > 8.5f && d < 19.5f;
    }
  // Only the 5x5 median/Gaussian blur mixes the two: a band of a few pixels
  // along the box's outline (3 edges x ~120 px x 4 px).
  EXPECT_LT(between, 3 * 120 * 4);
}

TEST(DepthCompletion, FillAboveEnvelopeIsOptional) {
  DepthCompletionOptions o;
  o.fill_above_envelope = true;
  DepthCompletionReport report;
  const cv::Mat dense = CompleteDepth(ScanLines(240, 320), o, &report);
  EXPECT_NEAR(dense.at<float>(0, 10), 20.f, 1e-4);
  EXPECT_EQ(report.coverage, 1.0);
  EXPECT_NEAR(report.supported_fraction, 180.0 / 240, 1e-12);
}

TEST(DepthCompletion, BadInputIsAnInputError) {
  EXPECT_THROW(CompleteDepth(cv::Mat(4, 4, CV_64F, cv::Scalar(1)), {}),
               InputError);
  cv::Mat nan(4, 4, CV_32F, cv::Scalar(0));
  nan.at<float>(1, 1) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(CompleteDepth(nan, {}), InputError);
  DepthCompletionOptions even;
  even.large_fill_kernel = 30;
  EXPECT_FALSE(even.Check());
  EXPECT_THROW(CompleteDepth(ScanLines(240, 320), even), InputError);
  EXPECT_THROW(HoldOutAccuracy(ScanLines(240, 320), 1.5, 1, {}), InputError);
}

TEST(DepthCompletion, HoldOutOnTheSyntheticWallIsExact) {
  const DepthCompletionAccuracy a =
      HoldOutAccuracy(ScanLines(240, 320), 0.2, 7, {});
  // 20 % of 3,200 returns, each seeded: the count is near 640.
  EXPECT_GT(a.held_out, 540);
  EXPECT_LT(a.held_out, 740);
  EXPECT_EQ(a.covered, a.held_out);
  // Held-out wall returns are filled from their wall neighbours, box returns
  // from the box, except near its outline (blur): most are exact.
  EXPECT_GT(a.within_5_percent, 0.9);
  EXPECT_EQ(HoldOutAccuracy(ScanLines(240, 320), 0.2, 7, {}).mae_m, a.mae_m);
}

// ---- Real data: nuScenes scene-0916 (41 keyframes, three 25-frame clips) ----

constexpr char kVersion[] = "v1.0-mini-extract";

std::unique_ptr<DriveDataset> OpenScene0916() {
  DriveDatasetOptions o;
  o.root = test::RealDataPath("nuscenes_scene0916");
  o.version = kVersion;
  o.frames = ClipFrameSource::kKeyframes;
  return OpenDriveDataset(o);
}

// Held-out returns of the frame-0 sweep, completed from the rest of it (as
// KITTI depth completion measures), per keyframe clip, at 800x450.
TEST(LidarDenseReal, HeldOutReturnsOfTheFrame0Sweep) {
  const auto d = OpenScene0916();
  for (const std::string& id : d->ClipIds()) {
    const DriveClip clip = d->LoadClip(id);
    ASSERT_TRUE(clip.lidar && clip.frames.front().keyframe_sweep);
    const DriveFrame& f0 = clip.frames.front();
    const int64_t ts = clip.lidar->Sweeps()[*f0.keyframe_sweep].timestamp_us;
    std::vector<int64_t> times;
    const PointCloud sweep = AggregateStaticSweeps(clip, ts, ts, &times);
    const PinholeCamera cam = ResizeCamera(f0.camera, 800, 450);
    const cv::Mat sparse = SparseDepthImage(sweep.positions, cam);
    const DepthCompletionAccuracy a = HoldOutAccuracy(sparse, 0.2, 2026, {});
    std::printf("%s: %s\n", id.c_str(), a.BriefReport().c_str());
    EXPECT_GT(a.held_out, 500);
    EXPECT_GT(static_cast<double>(a.covered) / a.held_out, 0.9);
    EXPECT_GT(a.within_10_percent, 0.80);
    EXPECT_LT(a.mae_m, 2.0);
  }
}

// Frame-0 support and coverage of the lidar-dense source (causal window).
TEST(LidarDenseReal, CoversTheSupportedAreaOfFrame0) {
  const auto d = OpenScene0916();
  for (const std::string& id : d->ClipIds()) {
    const DriveClip clip = d->LoadClip(id);
    SceneInputs in;
    in.clip = &clip;
    const ConditionScene scene =
        BuildConditionScene("lidar-dense", in, SceneSourceOptions());
    ASSERT_TRUE(scene.completion);
    const DepthCompletionReport& r = *scene.completion;
    std::printf("%s: %s, %zu points\n", id.c_str(), r.BriefReport().c_str(),
                scene.cloud.size());
    EXPECT_TRUE(scene.metric());
    EXPECT_GT(r.supported_fraction, 0.4);
    EXPECT_LT(r.supported_fraction, 0.9);
    EXPECT_GE(r.coverage_of_supported, 0.9);
    EXPECT_EQ(static_cast<int64_t>(scene.cloud.size()),
              std::llround(r.coverage * 800 * 450));
  }
}

}  // namespace
}  // namespace lidar_dense_test
}  // namespace geodrive

namespace geodrive {
namespace lidar_dense_test {
namespace {

// ---- Synthetic world: the completed frame-0 depth against the exact depth
// ----

TEST(LidarDenseSynthetic, CompletedDepthAgainstTheTrueDepth) {
  SyntheticDatasetOptions o;
  o.num_scenes = 1;
  o.seed = 22;
  o.image_width = 800;
  o.image_height = 450;
  o.scene_duration_s = 3.0;
  const std::string root = test::MakeTempDir("lidar_dense_synth");
  WriteSyntheticDataset(o, root);
  DriveDatasetOptions d;
  d.root = root;
  d.version = o.version;
  const auto dataset = OpenDriveDataset(d);
  const DriveClip clip = dataset->LoadClip(dataset->ClipIds().front());
  SceneInputs in;
  in.clip = &clip;
  SceneSourceOptions options;
  options.dense_width = 800;  // the camera's own grid: pixel for pixel
  const ConditionScene scene = BuildConditionScene("lidar-dense", in, options);
  ASSERT_TRUE(scene.completion);
  std::printf("synthetic: %s\n", scene.completion->BriefReport().c_str());

  const SyntheticWorld world(SyntheticWorldOptionsFor(o, 0));
  const SyntheticTimeline timeline = MakeSyntheticTimeline(o, 0);
  const DriveFrame& f0 = clip.frames.front();
  const RenderedView truth = world.RenderCamera(
      f0.camera, f0.world_from_cam, timeline.Seconds(f0.timestamp_us));
  // Each point back to its pixel: compare its depth with the truth there,
  // over static pixels (the source drops the boxes' points).
  double abs_sum = 0, sq_sum = 0;
  int64_t n = 0, within_5 = 0;
  for (const Eigen::Vector3f& p : scene.cloud.positions) {
    const Eigen::Vector2d uv = scene.camera.Project(p.cast<double>());
    const int x = static_cast<int>(std::lround(uv.x()));
    const int y = static_cast<int>(std::lround(uv.y()));
    ASSERT_TRUE(x >= 0 && y >= 0 && x < 800 && y < 450);
    if (truth.instance.at<uint16_t>(y, x) != kStaticInstance) continue;
    const double t = truth.depth.at<float>(y, x);
    const double e = std::abs(p.z() - t);
    abs_sum += e;
    sq_sum += e * e;
    within_5 += e <= 0.05 * t;
    ++n;
  }
  ASSERT_GT(n, 100000);
  const double mae = abs_sum / n, rmse = std::sqrt(sq_sum / n);
  std::printf(
      "synthetic: %lld static points, MAE %.3f m, RMSE %.3f m, "
      "within 5 %% %.3f\n",
      static_cast<long long>(n), mae, rmse, static_cast<double>(within_5) / n);
  // Measured (seed 22): coverage 0.964 of the supported area, MAE 1.51 m,
  // RMSE 6.9 m, 0.833 within 5 %: the error sits at depth edges (poles and
  // building outlines, where the dilations extend the nearer surface by up
  // to half a kernel) and on far facades between scan lines. Floors with a
  // margin for other seeds and OpenCV versions:
  EXPECT_GT(scene.completion->coverage_of_supported, 0.9);
  EXPECT_LT(mae, 2.0);
  EXPECT_GT(static_cast<double>(within_5) / n, 0.8);
}

}  // namespace
}  // namespace lidar_dense_test
}  // namespace geodrive

namespace geodrive {
namespace lidar_dense_test {
namespace {

// ---- Synthetic world: renders along the true trajectory against the
// ray-cast frames, lidar-dense side by side with MonST3R ----

struct TrajectoryScore {
  double coverage0 = 0, mean_coverage = 0;  // of the static truth pixels
  double psnr0 = 0, mean_psnr = 0;          // over covered static pixels
};

// Renders `scene` along the clip's true poses (in camera 0's frame) with
// `preset` at the camera's size and scores every frame against the world
// ray-cast at that pose and time, over its static pixels.
TrajectoryScore ScoreAlongTrueTrajectory(const ConditionScene& scene,
                                         const DriveClip& clip,
                                         const SyntheticWorld& world,
                                         const SyntheticTimeline& timeline,
                                         RenderPreset preset) {
  const DriveFrame& f0 = clip.frames.front();
  const PinholeCamera camera = f0.camera;
  const Rigid3d cam0_from_world = f0.world_from_cam.Inverse();
  std::vector<Rigid3d> cam_from_cam0;
  for (const DriveFrame& f : clip.frames)
    cam_from_cam0.push_back((cam0_from_world * f.world_from_cam).Inverse());
  RenderOptions ro = PresetRenderOptions(preset);
  ro.width = camera.width;
  ro.height = camera.height;
  ro.far = 1000;
  const RenderResult r = RenderFrames(
      scene.cloud,
      {scene.CameraAt(camera.width, camera.height, ResizeMode::kResize)},
      cam_from_cam0, ro);
  TrajectoryScore score;
  int psnr_frames = 0;
  for (size_t t = 0; t < clip.frames.size(); ++t) {
    const RenderedView truth =
        world.RenderCamera(camera, clip.frames[t].world_from_cam,
                           timeline.Seconds(clip.frames[t].timestamp_us));
    const cv::Mat is_static =
        (truth.instance == kStaticInstance) & (truth.depth > 0);
    const cv::Mat covered = is_static & (r.frames[t].mask == kMaskValid);
    const double coverage =
        cv::countNonZero(covered) / double(cv::countNonZero(is_static));
    double se = 0;
    int64_t n = 0;
    for (int y = 0; y < covered.rows; ++y)
      for (int x = 0; x < covered.cols; ++x) {
        if (!covered.at<uint8_t>(y, x)) continue;
        const cv::Vec3b a = r.frames[t].rgb.at<cv::Vec3b>(y, x);
        const cv::Vec3b b = truth.rgb.at<cv::Vec3b>(y, x);
        for (int c = 0; c < 3; ++c) se += (double(a[c]) - b[c]) * (a[c] - b[c]);
        n += 3;
      }
    const double psnr = n ? 10 * std::log10(255.0 * 255.0 * n / se) : 0;
    if (t == 0) score.coverage0 = coverage, score.psnr0 = psnr;
    score.mean_coverage += coverage / clip.frames.size();
    if (n) score.mean_psnr += psnr, ++psnr_frames;
  }
  if (psnr_frames) score.mean_psnr /= psnr_frames;
  return score;
}

TEST(LidarDenseSynthetic, RendersAlongTheTrueTrajectoryBesideMonst3r) {
  SyntheticDatasetOptions o;
  o.num_scenes = 1;
  o.seed = 22;
  o.image_width = 640;
  o.image_height = 360;
  o.scene_duration_s = 3.0;
  o.write_monst3r = true;
  o.monst3r_depth_noise = 0.01;
  o.monst3r_pose_noise_deg = 0.1;
  o.monst3r_pose_noise_m = 0.02;
  const std::string root = test::MakeTempDir("lidar_dense_vs_monst3r");
  WriteSyntheticDataset(o, root);
  DriveDatasetOptions d;
  d.root = root;
  d.version = o.version;
  const auto dataset = OpenDriveDataset(d);
  const std::string id = dataset->ClipIds().front();
  const DriveClip clip = dataset->LoadClip(id);
  const SyntheticWorld world(SyntheticWorldOptionsFor(o, 0));
  const SyntheticTimeline timeline = MakeSyntheticTimeline(o, 0);
  SceneInputs in;
  in.clip = &clip;
  SceneSourceOptions options;
  options.dense_width = o.image_width;
  const ConditionScene dense = BuildConditionScene("lidar-dense", in, options);
  in.path = root + "/monst3r/" + id;
  const ConditionScene monst3r = BuildConditionScene("monst3r", in, options);
  ASSERT_TRUE(monst3r.metric()) << monst3r.scale.report;
  TrajectoryScore s[2][2];
  const ConditionScene* scenes[2] = {&dense, &monst3r};
  const char* names[2] = {"lidar-dense", "monst3r"};
  for (int k = 0; k < 2; ++k) {
    for (int p = 0; p < 2; ++p) {
      s[k][p] = ScoreAlongTrueTrajectory(
          *scenes[k], clip, world, timeline,
          p == 0 ? RenderPreset::kPaper : RenderPreset::kFootprint);
      std::printf(
          "synthetic %s, %s preset, %zu frames along the true trajectory: "
          "static coverage frame 0 %.3f mean %.3f; PSNR frame 0 %.1f dB mean "
          "%.1f dB\n",
          names[k], p == 0 ? "paper" : "footprint", clip.frames.size(),
          s[k][p].coverage0, s[k][p].mean_coverage, s[k][p].psnr0,
          s[k][p].mean_psnr);
    }
  }
  // Measured (seed 22, 640x360): lidar-dense frame 0 covers 0.813 of the
  // static pixels at 35.4 dB; along the 25 frames the footprint preset keeps
  // 0.688 of them on average (paper 0.296), MonST3R 0.801 (paper 0.234: its
  // 512x288 pointmap is magnified 1.25x at 640x360 already in frame 0,
  // covering 0.629 -> 0.929). Floors with a margin:
  EXPECT_GT(s[0][1].psnr0, 30.0);
  EXPECT_GT(s[0][1].coverage0, 0.75);
  for (int k = 0; k < 2; ++k)
    EXPECT_GT(s[k][1].mean_coverage, s[k][0].mean_coverage + 0.3) << names[k];
  EXPECT_GT(s[1][1].coverage0, 0.9);
  EXPECT_GT(s[0][1].mean_psnr, 18.0);
}

// The support over the real keyframes as frame 0 (two-frame clips at stride
// 1: keyframes 0..39 of the 41, each with its own keyframe sweep): the LiDAR
// reaches the lower part of CAM_FRONT only (its top beam is about 10 degrees
// above the horizon).
TEST(LidarDenseReal, SupportedAreaOverEveryKeyframe) {
  DriveDatasetOptions o;
  o.root = test::RealDataPath("nuscenes_scene0916");
  o.version = kVersion;
  o.frames = ClipFrameSource::kKeyframes;
  o.clip_frames = 2;  // the least a clip may have
  o.clip_stride = 1;
  const auto d = OpenDriveDataset(o);
  double sum = 0, lo = 1, hi = 0, covered_min = 1, covered_sum = 0;
  int n = 0;
  for (const std::string& id : d->ClipIds()) {
    const DriveClip clip = d->LoadClip(id);
    SceneInputs in;
    in.clip = &clip;
    const ConditionScene scene =
        BuildConditionScene("lidar-dense", in, SceneSourceOptions());
    const double f = scene.completion->supported_fraction;
    sum += f, lo = std::min(lo, f), hi = std::max(hi, f), ++n;
    covered_min =
        std::min(covered_min, scene.completion->coverage_of_supported);
    covered_sum += scene.completion->coverage_of_supported;
    if (scene.completion->coverage_of_supported < 0.95)
      std::printf("%s: %s\n", id.c_str(),
                  scene.completion->BriefReport().c_str());
  }
  std::printf(
      "%d keyframes: supported %.3f of the image on average (%.3f-%.3f), "
      "%.3f of it completed on average, at least %.3f\n",
      n, sum / n, lo, hi, covered_sum / n, covered_min);
  EXPECT_EQ(n, 40);
  EXPECT_GT(sum / n, 0.5);
  EXPECT_LT(sum / n, 0.85);
  EXPECT_GE(covered_min, 0.99);  // 0.836 before step 5b
}

// --lidar-objects frame0: the returns inside the boxes of the frame-0 sweep
// (pedestrians at the bus stop, parked cars) are kept, from that sweep only.
TEST(LidarDenseReal, ObjectsOfTheFrame0SweepAreKeptOnRequest) {
  const auto d = OpenScene0916();
  const DriveClip clip = d->LoadClip("scene-0916_0006_kf");
  ASSERT_TRUE(clip.lidar && clip.frames.front().keyframe_sweep);
  const size_t s0 = *clip.frames.front().keyframe_sweep;
  const int64_t ts = clip.lidar->Sweeps()[s0].timestamp_us;
  std::vector<int64_t> times;
  const size_t without = AggregateStaticSweeps(clip, ts, ts, &times).size();
  times.clear();
  const size_t with = AggregateStaticSweeps(clip, ts, ts, &times, s0).size();
  std::printf("frame-0 sweep: %zu static returns, %zu in boxes\n", without,
              with - without);
  EXPECT_GT(with, without + 500);  // measured: 2,000+ returns in boxes
  SceneInputs in;
  in.clip = &clip;
  SceneSourceOptions options;
  const ConditionScene removed =
      BuildConditionScene("lidar-dense", in, options);
  options.dense_objects = LidarObjects::kFrame0;
  const ConditionScene kept = BuildConditionScene("lidar-dense", in, options);
  ASSERT_TRUE(removed.completion && kept.completion);
  EXPECT_GT(kept.completion->input_pixels, removed.completion->input_pixels);
  EXPECT_NE(kept.description.find("objects frame0"), std::string::npos);
  EXPECT_EQ(ParseLidarObjects("frame0"), LidarObjects::kFrame0);
  EXPECT_THROW(ParseLidarObjects("keep"), InputError);
}

// The acceptance command on the real scene: every keyframe clip builds with
// lidar-dense, meta.json records support and coverage, and frame 0 is
// covered where the LiDAR reaches (vs 0.13-0.18 for the sparse source).
TEST(LidarDenseReal, KeyframeClipsBuildWithLidarDense) {
  for (LidarWindow window : {LidarWindow::kCausal, LidarWindow::kClip}) {
    const std::string out = test::MakeTempDir("lidar_dense_build");
    BuildDatasetOptions o;
    o.dataroot = test::RealDataPath("nuscenes_scene0916");
    o.version = kVersion;
    o.frames = ClipFrameSource::kKeyframes;
    o.geometry = "lidar-dense";
    o.lidar_dense_window = window;
    o.out = out;
    o.threads = 2;
    o.quiet = true;
    const BuildDatasetSummary s = BuildDataset(o);
    ASSERT_EQ(s.built, 3) << s.BriefReport();
    // The summary prints the frame-0 figures of the pairs built.
    EXPECT_EQ(s.quality.pairs, 3);
    EXPECT_EQ(s.quality.completion_pairs, 3);
    EXPECT_EQ(s.quality.holdout_pairs, 3);
    EXPECT_NE(s.BriefReport().find("held-out returns: MAE"), std::string::npos)
        << s.BriefReport();
    // report.html: the frame-0 coverage histogram of the source and the
    // before / after picture of one pair.
    const std::string report = ReadFileText(out + "/report.html");
    EXPECT_NE(report.find("frame-0 coverage per pair, --geometry lidar-dense"),
              std::string::npos);
    EXPECT_NE(report.find("/completion.png"), std::string::npos);
    for (const ManifestEntry& e : ReadManifest(out + "/manifest.jsonl")) {
      const PairMeta m = ReadPairMeta(out + "/" + e.pair_dir);
      ASSERT_TRUE(m.quality.supported_fraction &&
                  m.quality.coverage_of_supported);
      // Held-out returns of the frame-0 sweep, recorded per pair (the same
      // measure as HeldOutReturnsOfTheFrame0Sweep, whatever the window).
      ASSERT_TRUE(m.quality.completion_holdout.has_value());
      EXPECT_GT(m.quality.completion_holdout->held_out, 500);
      EXPECT_GT(m.quality.completion_holdout->within_10_percent, 0.80);
      EXPECT_LT(m.quality.completion_holdout->mae_m, 2.0);
      ASSERT_EQ(m.files.count("completion_preview"), 1u);
      const cv::Mat preview =
          ReadImageRgb(out + "/" + e.pair_dir + "/completion.png");
      EXPECT_EQ(preview.cols, 1200);
      std::printf(
          "%s window %s: frame-0 coverage %.3f, supported %.3f, "
          "%.3f of it completed, PSNR frame 0 %.1f dB\n",
          m.clip_id.c_str(), ToString(window).c_str(),
          m.quality.coverage.front(), *m.quality.supported_fraction,
          *m.quality.coverage_of_supported,
          m.quality.psnr_static.front().value_or(0));
      EXPECT_GE(*m.quality.coverage_of_supported, 0.9);
      // Rendered at 720x480 from the 800x450 completion: the frame-0 render
      // covers about the supported area.
      EXPECT_GT(m.quality.coverage.front(), 0.6);
      EXPECT_GT(m.quality.psnr_static.front().value_or(0), 25.0);
    }
  }
}

// Footprint-aware splats on the real scene. The builder's paper preset
// draws disks of radius 1 px (--splat-radius, for pointmaps sparser than the
// output); the footprint preset draws one pixel per point where frame 0 sees
// the points as captured (sharper: higher frame-0 PSNR) and grows them as the
// car approaches (more of the scene kept in later frames).
TEST(LidarDenseReal, FootprintPresetCoversMoreOfTheApproachedScene) {
  PairQuality quality[2];
  for (int k = 0; k < 2; ++k) {
    const std::string out = test::MakeTempDir("lidar_dense_footprint");
    BuildDatasetOptions o;
    o.dataroot = test::RealDataPath("nuscenes_scene0916");
    o.version = kVersion;
    o.frames = ClipFrameSource::kKeyframes;
    o.geometry = "lidar-dense";
    o.preset = k == 0 ? RenderPreset::kPaper : RenderPreset::kFootprint;
    o.clips = {"scene-0916_0006_kf"};
    o.out = out;
    o.quiet = true;
    ASSERT_EQ(BuildDataset(o).built, 1);
    quality[k] = ReadPairMeta(out + "/pairs/scene-0916_0006_kf").quality;
  }
  const std::vector<double>& paper = quality[0].coverage;
  const std::vector<double>& footprint = quality[1].coverage;
  ASSERT_EQ(paper.size(), footprint.size());
  for (size_t t = 0; t < 8; ++t) {
    std::printf("frame %zu coverage paper %.3f footprint %.3f\n", t, paper[t],
                footprint[t]);
  }
  // Measured: frame 0 PSNR 30.2 -> 35.1 dB; coverage of frames 2-7
  // 0.606 0.531 0.507 0.496 0.455 0.404 -> 0.732 0.746 0.748 0.765 0.751
  // 0.713.
  ASSERT_TRUE(quality[0].psnr_static[0] && quality[1].psnr_static[0]);
  EXPECT_GT(*quality[1].psnr_static[0], *quality[0].psnr_static[0] + 3.0);
  for (size_t t = 2; t < 8; ++t)
    EXPECT_GT(footprint[t], paper[t]) << "frame " << t;
  for (size_t t = 4; t < 8; ++t)
    EXPECT_GT(footprint[t], paper[t] + 0.2) << "frame " << t;
}

}  // namespace
}  // namespace lidar_dense_test
}  // namespace geodrive

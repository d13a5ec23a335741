// LiDAR alignment measured on the synthetic world (true scale and poses in the
// sidecar).

#include "dataset/lidar_alignment.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "dataset/drive_dataset.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "geometry/npy.h"
#include "geometry/point_cloud_io.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

namespace fs = std::filesystem;

struct AlignWorld {
  std::string root;
  SyntheticDatasetSummary summary;
};

AlignWorld MakeAlignWorld(const std::string& name,
                          double depth_noise,
                          double pose_noise_m) {
  AlignWorld w;
  w.root = test::MakeTempDir(name);
  SyntheticDatasetOptions o;
  o.num_scenes = 1;
  o.seed = 11;
  o.image_width = 800;
  o.image_height = 450;
  o.scene_duration_s = 4.5;
  o.write_monst3r = true;
  o.monst3r_depth_noise = depth_noise;
  o.monst3r_pose_noise_m = pose_noise_m;
  o.lidar_azimuth_steps = 720;
  w.summary = WriteSyntheticDataset(o, w.root);
  return w;
}

double TrueMetresPerUnit(const AlignWorld& w, const std::string& clip_id) {
  std::ifstream in(w.root + "/monst3r_gt/" + clip_id + ".json");
  return nlohmann::json::parse(in)["metres_per_unit"].get<double>();
}

// The clip through the nuScenes adapter (every start, so any id resolves).
DriveClip LoadClip(const std::string& root, const std::string& clip_id) {
  DriveDatasetOptions o;
  o.root = root;
  o.clip_stride = 1;
  return OpenDriveDataset(o)->LoadClip(clip_id);
}

// 10 % outlier LiDAR returns: half hit "a vehicle that MonST3R's depth misses"
// (30-70 % of the range along the same ray), half are random far returns
// (80-120 m along the ray).
void CorruptSweeps(const std::string& root, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  for (const auto& e : fs::recursive_directory_iterator(root)) {
    const std::string p = e.path().string();
    if (p.find("LIDAR_TOP") == std::string::npos ||
        e.path().extension() != ".bin")
      continue;
    PointCloud c = ReadNuscenesLidarBin(p);
    for (auto& pt : c.positions) {
      if (unit(rng) >= 0.10) continue;
      const float r = pt.norm();
      const float target =
          unit(rng) < 0.5 ? r * (0.3 + 0.4 * unit(rng)) : 80 + 40 * unit(rng);
      pt *= target / r;
    }
    WriteNuscenesLidarBin(p, c);
  }
}

const AlignWorld& NoiseFreeWorld() {
  // Shared between test processes: the world is generated once (under a lock)
  // and reused.
  static const AlignWorld w = [] {
    AlignWorld out;
    out.root =
        test::SharedFixtureDir("lidar_align_exact", [](const std::string& dir) {
          SyntheticDatasetOptions o;
          o.num_scenes = 1;
          o.seed = 11;
          o.image_width = 800;
          o.image_height = 450;
          o.scene_duration_s = 4.5;
          o.write_monst3r = true;
          WriteSyntheticDataset(o, dir);
        });
    for (const auto& e : fs::directory_iterator(out.root + "/monst3r")) {
      out.summary.monst3r_clip_ids.push_back(e.path().filename().string());
    }
    std::sort(out.summary.monst3r_clip_ids.begin(),
              out.summary.monst3r_clip_ids.end());
    return out;
  }();
  return w;
}

TEST(LidarAlignmentSynthetic, ExactScaleAndTrajectoryWithoutNoise) {
  const AlignWorld& w = NoiseFreeWorld();
  ASSERT_FALSE(w.summary.monst3r_clip_ids.empty());
  const std::string root = w.root;
  const std::string id = w.summary.monst3r_clip_ids.front();
  const Monst3rFolder folder = Monst3rFolder::Open(w.root + "/monst3r/" + id);
  const ClipScaleReport r = FitClipLidarScale(LoadClip(root, id), folder, {});
  ASSERT_TRUE(r.success) << r.message;
  const double truth = TrueMetresPerUnit(w, id);
  const double rel = std::abs(r.clip_fit.scale / truth - 1);
  std::printf("noise-free: scale %.6f true %.6f (rel %.5f %%); %s\n",
              r.clip_fit.scale, truth, 100 * rel, r.BriefReport().c_str());
  EXPECT_LT(rel, 1e-3);
  // Metric trajectory: the scaled MonST3R poses reproduce the ego-pose camera
  // trajectory.
  EXPECT_LT(r.trajectory_error.ate.max, 0.01);
  for (const auto& f : r.frames) EXPECT_TRUE(f.used) << f.skip_reason;
}

// The measurement: 3 % depth noise + 10 % outlier LiDAR returns ->
// within 0.5 %.
TEST(LidarAlignmentSynthetic, ScaleWithin05PercentUnderNoiseAndOutliers) {
  const AlignWorld w = MakeAlignWorld("lidar_align_noisy", 0.03, 0.05);
  CorruptSweeps(w.root, 5);
  const std::string root = w.root;
  for (const std::string& id : w.summary.monst3r_clip_ids) {
    const Monst3rFolder folder = Monst3rFolder::Open(w.root + "/monst3r/" + id);
    LidarScaleOptions options;
    options.alignment = AlignmentType::kSE3;
    const ClipScaleReport r =
        FitClipLidarScale(LoadClip(root, id), folder, options);
    ASSERT_TRUE(r.success) << r.message;
    const double truth = TrueMetresPerUnit(w, id);
    const double rel = std::abs(r.clip_fit.scale / truth - 1);
    // Injected pose noise: 5 cm per axis on frames 1..24 -> expected ATE rms ~
    // sqrt(3) * 5 cm (less after SE(3) alignment absorbs part of it).
    std::printf(
        "%s: 3%% depth noise + 10%% LiDAR outliers: scale %.5f true %.5f (rel "
        "%.3f %%), "
        "inliers %.1f %%, ATE rms %.4f m (pose noise 0.05 m/axis)\n",
        id.c_str(), r.clip_fit.scale, truth, 100 * rel,
        100 * r.clip_fit.inlier_fraction, r.trajectory_error.ate.rms);
    EXPECT_LT(rel, 0.005);
    EXPECT_GT(r.trajectory_error.ate.rms, 0.03);
    EXPECT_LT(r.trajectory_error.ate.rms, 0.12);
  }
}

TEST(LidarAlignmentSynthetic, FramesWithoutLidarAreSkippedWithReason) {
  const AlignWorld& w = NoiseFreeWorld();
  const std::string root = w.root;
  const std::string id = w.summary.monst3r_clip_ids.front();
  const Monst3rFolder folder = Monst3rFolder::Open(w.root + "/monst3r/" + id);
  LidarScaleOptions options;
  options.max_time_gap_s =
      1e-6;  // no sweep is that close: every frame is skipped
  const ClipScaleReport r =
      FitClipLidarScale(LoadClip(root, id), folder, options);
  EXPECT_FALSE(r.success);
  for (const auto& f : r.frames) {
    EXPECT_FALSE(f.used);
    EXPECT_NE(f.skip_reason.find("ms away"), std::string::npos)
        << f.skip_reason;
  }
  // A clip whose frame count differs from the folder's is rejected.
  DriveClip shorter = LoadClip(root, id);
  shorter.frames.pop_back();
  EXPECT_THROW(FitClipLidarScale(shorter, folder, {}), InputError);
}

// No overlap between LiDAR and valid depth (every MonST3R depth invalid): every
// frame is skipped with a reason, the clip fit fails with a message, nothing is
// thrown.
TEST(LidarAlignmentSynthetic, NoValidDepthIsReportedNotThrown) {
  const AlignWorld& w = NoiseFreeWorld();
  const std::string id = w.summary.monst3r_clip_ids.front();
  const std::string copy = test::MakeTempDir("lidar_align_no_depth");
  fs::copy(w.root + "/monst3r/" + id, copy, fs::copy_options::recursive);
  for (int i = 0; i < 25; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "/frame_%04d.npy", i);
    NpyArray depth = ReadNpy(copy + name);
    float* d = depth.MutableData<float>();
    for (int64_t k = 0; k < depth.NumElements(); ++k)
      d[k] = 0.0f;  // MonST3R: depth > 0 valid
    WriteNpy(copy + name, depth);
  }
  const std::string root = w.root;
  const ClipScaleReport r =
      FitClipLidarScale(LoadClip(root, id), Monst3rFolder::Open(copy), {});
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.message.find("too few valid depth pairs"), std::string::npos)
      << r.message;
  for (const auto& f : r.frames) {
    EXPECT_FALSE(f.used);
    EXPECT_NE(f.skip_reason.find("too few"), std::string::npos)
        << f.skip_reason;
  }
}

}  // namespace
}  // namespace geodrive

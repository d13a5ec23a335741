#include "geometry/fusion.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"
#include "tests/geometry/synthetic_pointmaps.h"

namespace geodrive {
namespace fusion_test {
namespace {

double Median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

struct SurfaceStats {
  double median = 0;
  double outlier_fraction = 0;
};

// Distances of the cloud to the true static surface; outliers are farther than
// `outlier_dist`.
SurfaceStats Measure(const test::SyntheticClip& clip,
                     const PointCloud& cloud,
                     double outlier_dist) {
  std::vector<double> d;
  for (const auto& p : cloud.positions)
    d.push_back(clip.DistanceToStaticSurface(p.cast<double>()));
  SurfaceStats s;
  s.median = Median(d);
  s.outlier_fraction =
      static_cast<double>(std::count_if(
          d.begin(), d.end(), [&](double x) { return x > outlier_dist; })) /
      d.size();
  return s;
}

TEST(Fusion, StaticCloudOfAClipLiesOnTheTrueSurface) {
  const test::SyntheticClip clip =
      test::MakeSyntheticClip();  // 25 frames, 256x144
  const std::string dir = test::MakeTempDir("fusion_clip");
  test::Monst3rWriteOptions w;
  w.depth_noise = 0.003;
  w.bad_depth_fraction = 0.08;
  test::WriteMonst3rFolder(clip, dir, w);
  const Monst3rFolder folder = Monst3rFolder::Open(dir);
  std::vector<Pointmap> pms;
  for (const auto& f :
       folder.LoadFrames(ParseFrameList("all", folder.num_frames()))) {
    pms.push_back(BuildPointmap(f));
  }
  PointmapFilterOptions filter;
  filter.selection = PixelSelection::kStaticOnly;
  FusionOptions fusion;
  const double outlier_dist = 0.05 * clip.median_depth;

  FusedCloud after = FusePointmaps(pms, filter, fusion);
  PointmapFilterOptions no_conf = filter;
  no_conf.min_confidence = 0;
  FusedCloud before = FusePointmaps(pms, no_conf, fusion);
  FusionOptions raw = fusion;
  raw.statistical_outlier_removal = false;
  FusedCloud before_raw = FusePointmaps(pms, no_conf, raw);
  FusedCloud after_raw = FusePointmaps(pms, filter, raw);

  const SurfaceStats s_after = Measure(clip, after.cloud, outlier_dist);
  const SurfaceStats s_before = Measure(clip, before.cloud, outlier_dist);
  const SurfaceStats s_before_raw =
      Measure(clip, before_raw.cloud, outlier_dist);
  const SurfaceStats s_after_raw = Measure(clip, after_raw.cloud, outlier_dist);
  std::printf(
      "median depth %.3f; fused (tau 0.65 + SOR): %zu points, median distance "
      "%.4f "
      "(%.3f%% of median depth)\n",
      clip.median_depth, after.cloud.size(), s_after.median,
      100 * s_after.median / clip.median_depth);
  std::printf(
      "outlier fraction (> 5%% of median depth): no SOR %.2f%% -> %.2f%% with "
      "confidence "
      "filter; with SOR %.2f%% -> %.2f%%\n",
      100 * s_before_raw.outlier_fraction, 100 * s_after_raw.outlier_fraction,
      100 * s_before.outlier_fraction, 100 * s_after.outlier_fraction);
  std::printf("summary: %s\n", after.summary.ToString().c_str());
  EXPECT_LE(s_after.median, 0.01 * clip.median_depth);
  EXPECT_LT(s_after_raw.outlier_fraction, 0.5 * s_before_raw.outlier_fraction);
  EXPECT_LT(s_after.outlier_fraction, s_before.outlier_fraction);
  EXPECT_LT(after.summary.after_voxel, after.summary.input_points);
  EXPECT_EQ(after.cloud.colors.size(), after.cloud.size());
}

TEST(Fusion, ProvenancePointsBackIntoTheVoxel) {
  test::SyntheticClipOptions o;
  o.width = 96;
  o.height = 54;
  o.focal = 86;
  o.num_frames = 4;
  const test::SyntheticClip clip = test::MakeSyntheticClip(o);
  const std::string dir = test::MakeTempDir("fusion_prov");
  test::WriteMonst3rFolder(clip, dir);
  const Monst3rFolder folder = Monst3rFolder::Open(dir);
  std::vector<Pointmap> pms;
  for (const auto& f : folder.LoadFrames({1, 3}))
    pms.push_back(BuildPointmap(f));
  FusionOptions fusion;
  fusion.keep_provenance = true;
  fusion.voxel_size = 0.3;
  fusion.radius_outlier_removal = true;
  const FusedCloud fused = FusePointmaps(pms, {}, fusion);
  ASSERT_EQ(fused.provenance.size(), fused.cloud.size());
  ASSERT_GT(fused.cloud.size(), 100u);
  for (size_t i = 0; i < fused.cloud.size(); ++i) {
    const PointProvenance& p = fused.provenance[i];
    ASSERT_TRUE(p.frame == 1 || p.frame == 3);
    const Pointmap& pm = pms[p.frame == 1 ? 0 : 1];
    const cv::Vec3f& x = pm.points_in_world.at<cv::Vec3f>(p.v, p.u);
    // The representative lies in the same voxel as the centroid: within one
    // voxel diagonal.
    EXPECT_LE(
        (Eigen::Vector3f(x[0], x[1], x[2]) - fused.cloud.positions[i]).norm(),
        0.3f * std::sqrt(3.f) + 1e-4f);
  }
}

TEST(Fusion, VoxelAveragesColoursAndRemovesIsolatedPoints) {
  PointCloud cloud;
  // A dense 20x20 patch on z = 0 (spacing 0.1) plus one far point.
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 20; ++j) {
      cloud.positions.emplace_back(0.1f * i + 0.05f, 0.1f * j + 0.05f, 0.05f);
      cloud.colors.emplace_back((i + j) % 2 ? 255 : 0, 100, 0);
    }
  }
  cloud.positions.emplace_back(50.f, 50.f, 50.f);
  cloud.colors.emplace_back(1, 2, 3);
  FusionOptions opt;
  opt.voxel_size = 0.2;  // 2x2 points per voxel
  opt.statistical_outlier_removal = false;
  opt.radius_outlier_removal = true;
  opt.ror_radius = 0.5;
  opt.ror_min_neighbors = 2;
  const FusedCloud fused = FuseCloud(cloud, nullptr, nullptr, opt);
  EXPECT_EQ(fused.summary.after_voxel, 101);
  EXPECT_EQ(fused.cloud.size(), 100u);
  for (const auto& c : fused.cloud.colors) {
    EXPECT_EQ(
        c, Color3u8(128, 100, 0));  // mean of 0, 255, 255, 0 = 127.5, rounded
  }
  FusionOptions sor;
  sor.voxel_size = -1;
  sor.sor_mean_k = 8;
  const FusedCloud cleaned = FuseCloud(cloud, nullptr, nullptr, sor);
  EXPECT_EQ(cleaned.cloud.size(), 400u);  // only the far point goes
  FusionOptions bad;
  bad.sor_mean_k = 0;
  EXPECT_THROW(FuseCloud(cloud, nullptr, nullptr, bad), InputError);
}

}  // namespace
}  // namespace fusion_test
}  // namespace geodrive

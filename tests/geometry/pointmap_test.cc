#include "geometry/pointmap.h"

#include <gtest/gtest.h>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"
#include "tests/geometry/synthetic_pointmaps.h"

namespace geodrive {
namespace {

Monst3rFrame LoadSynthFrame(const std::string& name,
                            int index,
                            double bad_fraction,
                            test::SyntheticClip* clip_out) {
  test::SyntheticClipOptions o;
  o.width = 96;
  o.height = 54;
  o.focal = 86;
  o.num_frames = index + 1;
  *clip_out = test::MakeSyntheticClip(o);
  const std::string dir = test::MakeTempDir(name);
  test::Monst3rWriteOptions w;
  w.bad_depth_fraction = bad_fraction;
  test::WriteMonst3rFolder(*clip_out, dir, w);
  return Monst3rFolder::Open(dir).LoadFrame(index);
}

TEST(Pointmap, IntegerIndexUnprojectionMatchesTheTrueSurface) {
  test::SyntheticClip clip;
  const Monst3rFrame frame =
      LoadSynthFrame("pointmap_unproject", 3, 0.0, &clip);
  const Pointmap pm = BuildPointmap(frame);
  double max_err = 0, max_err_half = 0;
  const Rigid3d& pose = clip.world_from_cam[3];
  for (int v = 0; v < pm.height(); v += 3) {
    for (int u = 0; u < pm.width(); u += 3) {
      const test::RayHit hit = clip.Cast(3, u, v);
      const cv::Vec3f& p = pm.points_in_world.at<cv::Vec3f>(v, u);
      max_err = std::max(
          max_err,
          (Eigen::Vector3d(p[0], p[1], p[2]) - hit.point_in_world).norm() /
              hit.depth);
      // The +0.5 (pixel-centre) convention is off by half a pixel.
      const Eigen::Vector3d half =
          pose * clip.camera.Unproject(Eigen::Vector2d(u, v), hit.depth,
                                       PixelConvention::kPixelCenter);
      max_err_half = std::max(max_err_half,
                              (half - hit.point_in_world).norm() / hit.depth);
    }
  }
  std::printf(
      "max relative point error: integer-index %.2e, pixel-centre %.2e\n",
      max_err, max_err_half);
  EXPECT_LT(max_err, 1e-5);  // float32 depth
  EXPECT_GT(max_err_half, 0.4 / clip.camera.fx);
}

TEST(Pointmap, FiltersCountEveryPixelOnce) {
  test::SyntheticClip clip;
  const Monst3rFrame frame = LoadSynthFrame("pointmap_filters", 2, 0.2, &clip);
  const Pointmap pm = BuildPointmap(frame);
  PointmapFilterOptions opt;
  opt.max_depth = 40;  // the back wall (z ~ 70) is out of range
  PointmapFilterStats s;
  const cv::Mat valid = ComputeValidMask(pm, opt, &s);
  EXPECT_EQ(s.total, pm.width() * pm.height());
  EXPECT_EQ(s.total, s.kept + s.non_finite + s.out_of_range + s.low_confidence +
                         s.masked);
  EXPECT_EQ(s.kept, cv::countNonZero(valid));
  EXPECT_GT(s.out_of_range, 0);
  // ~20% bad pixels have conf01 < 0.6; good ones >= 0.73.
  EXPECT_NEAR(
      static_cast<double>(s.low_confidence) / (s.total - s.out_of_range), 0.2,
      0.05);
  for (int v = 0; v < pm.height(); ++v) {
    for (int u = 0; u < pm.width(); ++u) {
      if (!valid.at<uint8_t>(v, u)) continue;
      EXPECT_GE(pm.confidence.at<float>(v, u), 0.65f);
      EXPECT_LE(pm.depth.at<float>(v, u), 40.f);
    }
  }
  std::printf("%s\n", s.ToString().c_str());
}

TEST(Pointmap, StaticDynamicSplit) {
  test::SyntheticClip clip;
  const Monst3rFrame frame = LoadSynthFrame("pointmap_split", 4, 0.0, &clip);
  const Pointmap pm = BuildPointmap(frame);
  const int dynamic = cv::countNonZero(clip.dynamic_mask[4]);
  ASSERT_GT(dynamic, 20) << "the vehicle must be visible";
  PointmapFilterOptions opt;
  opt.min_confidence = 0;
  opt.selection = PixelSelection::kDynamicOnly;
  opt.mask_kind = DynamicMaskKind::kPlain;
  PointmapFilterStats s_dyn, s_static, s_static_enl;
  ComputeValidMask(pm, opt, &s_dyn);
  EXPECT_EQ(s_dyn.kept, dynamic);
  opt.selection = PixelSelection::kStaticOnly;
  const cv::Mat stat = ComputeValidMask(pm, opt, &s_static);
  EXPECT_EQ(s_static.kept + s_dyn.kept, s_static.total);
  EXPECT_EQ(cv::countNonZero(stat & clip.dynamic_mask[4]), 0);
  opt.mask_kind = DynamicMaskKind::kEnlarged;
  ComputeValidMask(pm, opt, &s_static_enl);
  EXPECT_LT(s_static_enl.kept,
            s_static.kept);  // the 3x3 dilation removes the border ring
  std::printf("dynamic %ld, static (plain) %ld, static (enlarged) %ld\n",
              static_cast<long>(s_dyn.kept), static_cast<long>(s_static.kept),
              static_cast<long>(s_static_enl.kept));
}

TEST(Pointmap, ExtractKeepsProvenanceAndColours) {
  test::SyntheticClip clip;
  const Monst3rFrame frame = LoadSynthFrame("pointmap_extract", 1, 0.1, &clip);
  const Pointmap pm = BuildPointmap(frame);
  const cv::Mat valid = ComputeValidMask(pm, {});
  std::vector<PointProvenance> prov;
  const PointCloud cloud = ExtractPoints(pm, valid, &prov);
  ASSERT_EQ(prov.size(), cloud.size());
  ASSERT_TRUE(cloud.HasColors() && cloud.HasConfidence());
  for (size_t i = 0; i < cloud.size(); i += 97) {
    EXPECT_EQ(prov[i].frame, 1);
    const cv::Vec3f& p = pm.points_in_world.at<cv::Vec3f>(prov[i].v, prov[i].u);
    EXPECT_EQ(cloud.positions[i], Eigen::Vector3f(p[0], p[1], p[2]));
    const cv::Vec3b& c = clip.rgb[1].at<cv::Vec3b>(prov[i].v, prov[i].u);
    EXPECT_EQ(cloud.colors[i], Color3u8(c[0], c[1], c[2]));
  }
}

TEST(Pointmap, OptionsCheck) {
  PointmapFilterOptions o;
  o.Check();
  o.min_confidence = 1.5;
  EXPECT_THROW(o.Check(), InputError);
  o = {};
  o.max_depth = 0.05;
  EXPECT_THROW(o.Check(), InputError);
  o = {};
  o.stride = 0;
  EXPECT_THROW(o.Check(), InputError);
}

}  // namespace
}  // namespace geodrive

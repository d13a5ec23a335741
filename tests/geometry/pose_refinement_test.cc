#include "geometry/pose_refinement.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "geometry/monst3r.h"
#include "geometry/pointmap.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"
#include "tests/geometry/synthetic_pointmaps.h"

namespace geodrive {
namespace pose_refinement_test {
namespace {

double Median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

struct ClipErrors {
  double rotation_deg = 0;     // median over frames
  double translation_rel = 0;  // median camera-centre error / scene scale
  double initial_rotation_deg = 0, initial_translation_rel = 0;
};

// A 25-frame clip whose pts3d_{i}.npy pointmaps carry 0.5 px pixel noise and
// 10% outliers, and whose pred_traj.txt poses are perturbed by 2 deg and 5% of
// the scene scale (median depth).
struct Scenario {
  test::SyntheticClip clip;
  Monst3rFolder folder;
  double scene_scale = 0;
};

Scenario MakeScenario(const std::string& name,
                      double dynamic_lag,
                      int frames = 25,
                      double outlier_fraction = 0.10,
                      double vehicle_lateral_speed = 0.0) {
  test::SyntheticClipOptions o;
  o.num_frames = frames;
  o.vehicle_lateral_speed = vehicle_lateral_speed;
  Scenario s{test::MakeSyntheticClip(o), {}, 0};
  s.scene_scale = s.clip.median_depth;
  test::Monst3rWriteOptions w;
  w.write_pointmaps = true;
  w.pointmap_pixel_noise = 0.5;
  w.pointmap_outlier_fraction = outlier_fraction;
  w.dynamic_lag_frames = dynamic_lag;
  for (int t = 0; t < o.num_frames; ++t) {
    w.world_from_cam.push_back(test::PerturbPose(
        s.clip.world_from_cam[t], 2.0, 0.05 * s.scene_scale, 100 + t));
  }
  const std::string dir = test::MakeTempDir(name);
  test::WriteMonst3rFolder(s.clip, dir, w);
  s.folder = Monst3rFolder::Open(dir);
  return s;
}

std::vector<PoseRefinementInput> Inputs(const Scenario& s,
                                        PixelSelection selection,
                                        bool with_initial = true) {
  Monst3rLoadOptions lo;
  lo.raw_pointmaps = true;
  lo.rgb = false;
  std::vector<PoseRefinementInput> inputs;
  for (int t = 0; t < s.folder.num_frames(); ++t) {
    const Monst3rFrame f = s.folder.LoadFrame(t, lo);
    PoseRefinementInput in;
    in.frame_index = t;
    in.points_in_world = f.raw_points_in_world;
    in.camera = f.camera;
    if (with_initial) in.initial_world_from_cam = f.world_from_cam;
    if (selection != PixelSelection::kAll) {
      // Static pixels by the (enlarged) dynamic mask; confidence is not part of
      // this scenario.
      cv::Mat static_mask;
      cv::bitwise_not(f.enlarged_dynamic_mask, static_mask);
      in.valid_mask = static_mask;
    }
    inputs.push_back(in);
  }
  return inputs;
}

ClipErrors Measure(const Scenario& s,
                   const std::vector<PoseRefinementResult>& results,
                   const std::vector<PoseRefinementInput>& inputs) {
  std::vector<double> rot, trans, rot0, trans0;
  for (size_t t = 0; t < results.size(); ++t) {
    EXPECT_FALSE(results[t].summary.skipped) << results[t].summary.skip_reason;
    const Rigid3d& truth = s.clip.world_from_cam[t];
    rot.push_back(RotationDistanceDeg(results[t].world_from_cam.rotation,
                                      truth.rotation));
    trans.push_back(
        (results[t].world_from_cam.translation - truth.translation).norm() /
        s.scene_scale);
    if (inputs[t].initial_world_from_cam) {
      rot0.push_back(RotationDistanceDeg(
          inputs[t].initial_world_from_cam->rotation, truth.rotation));
      trans0.push_back(
          (inputs[t].initial_world_from_cam->translation - truth.translation)
              .norm() /
          s.scene_scale);
    }
  }
  ClipErrors e;
  e.rotation_deg = Median(rot);
  e.translation_rel = Median(trans);
  if (!rot0.empty())
    e.initial_rotation_deg = Median(rot0),
    e.initial_translation_rel = Median(trans0);
  return e;
}

TEST(PoseRefinement, RecoversPerturbedPosesOverStaticPixels) {
  const Scenario s = MakeScenario("refine_static", 0);
  const auto inputs = Inputs(s, PixelSelection::kStaticOnly);
  for (RobustLoss loss : {RobustLoss::kHuber, RobustLoss::kCauchy}) {
    PoseRefinementOptions opt;
    opt.loss = loss;
    const auto results = RefineClipPoses(inputs, opt, /*joint=*/false);
    const ClipErrors e = Measure(s, results, inputs);
    std::printf(
        "[%s] median over %zu frames: rotation %.3f -> %.4f deg, translation "
        "%.3f%% -> "
        "%.4f%% of scene scale (%.2f)\n",
        ToString(loss).c_str(), results.size(), e.initial_rotation_deg,
        e.rotation_deg, 100 * e.initial_translation_rel,
        100 * e.translation_rel, s.scene_scale);
    std::printf("  %s\n", results[12].summary.BriefReport().c_str());
    EXPECT_LE(e.rotation_deg, 0.05);
    EXPECT_LE(e.translation_rel, 0.001);
    for (const auto& r : results) {
      EXPECT_TRUE(r.summary.usable);
      EXPECT_LT(r.summary.final_median_px, r.summary.initial_median_px);
      EXPECT_GT(r.summary.num_inliers,
                0.8 * r.summary.num_residuals);  // 10% outliers
      EXPECT_EQ(r.summary.num_residuals, 4096);
      EXPECT_LT(r.summary.final_inlier_rms_px,
                1.0);  // 0.5 px noise: rms ~0.7 px
    }
  }
}

TEST(PoseRefinement, MovingVehicleBiasesAllPixelsButNotStaticOnly) {
  // A van crossing at 0.3 units/frame sideways; the reconstruction places its
  // points where it was half a frame earlier (a static-world aligner lags
  // moving objects). No random outliers here, so the bias is not hidden under
  // the outlier noise floor.
  const Scenario s =
      MakeScenario("refine_dynamic", /*dynamic_lag=*/0.5, 25,
                   /*outlier_fraction=*/0.0, /*vehicle_lateral_speed=*/0.3);
  PoseRefinementOptions opt;
  const auto all_in = Inputs(s, PixelSelection::kAll);
  const auto static_in = Inputs(s, PixelSelection::kStaticOnly);
  const ClipErrors all =
      Measure(s, RefineClipPoses(all_in, opt, false), all_in);
  const ClipErrors stat =
      Measure(s, RefineClipPoses(static_in, opt, false), static_in);
  std::printf(
      "moving vehicle: all pixels rotation %.4f deg, translation %.4f%%; "
      "static only "
      "rotation %.4f deg, translation %.4f%%\n",
      all.rotation_deg, 100 * all.translation_rel, stat.rotation_deg,
      100 * stat.translation_rel);
  EXPECT_LE(stat.rotation_deg, 0.05);
  EXPECT_LE(stat.translation_rel, 0.001);
  EXPECT_GT(all.translation_rel, 3 * stat.translation_rel);
}

TEST(PoseRefinement, PnpInitialisationWithoutOrFarFromAPose) {
  const Scenario s = MakeScenario("refine_pnp", 0, 6);
  auto inputs = Inputs(s, PixelSelection::kStaticOnly, /*with_initial=*/false);
  inputs[2].initial_world_from_cam =
      test::PerturbPose(s.clip.world_from_cam[2], 40, 5, 9);
  const auto results = RefineClipPoses(inputs, {}, false);
  const ClipErrors e = Measure(s, results, inputs);
  std::printf("PnP start: rotation %.4f deg, translation %.4f%%; frame 2: %s\n",
              e.rotation_deg, 100 * e.translation_rel,
              results[2].summary.BriefReport().c_str());
  EXPECT_EQ(results[0].summary.initialization, "pnp-ransac");
  EXPECT_EQ(results[2].summary.initialization,
            "pnp-ransac (given pose far off)");
  EXPECT_LE(e.rotation_deg, 0.05);
  EXPECT_LE(e.translation_rel, 0.001);
}

TEST(PoseRefinement, RefinesFocal) {
  const Scenario s = MakeScenario("refine_focal", 0, 4);
  auto inputs = Inputs(s, PixelSelection::kStaticOnly);
  for (auto& in : inputs) in.camera.fx *= 1.03, in.camera.fy *= 1.03;
  PoseRefinementOptions opt;
  opt.refine_focal = true;
  const auto results = RefineClipPoses(inputs, opt, /*joint=*/true);
  const double focal = results[0].camera.fx;
  std::printf("focal: true %.2f, start %.2f, refined %.3f (joint, shared)\n",
              s.clip.camera.fx, inputs[0].camera.fx, focal);
  EXPECT_NEAR(focal / s.clip.camera.fx, 1.0, 1e-3);
  EXPECT_DOUBLE_EQ(results[3].camera.fx, focal);
  const ClipErrors e = Measure(s, results, inputs);
  EXPECT_LE(e.rotation_deg, 0.05);
}

TEST(PoseRefinement, JointModeWithSmoothness) {
  const Scenario s = MakeScenario("refine_joint", 0, 10);
  const auto inputs = Inputs(s, PixelSelection::kStaticOnly);
  PoseRefinementOptions opt;
  opt.num_samples = 1024;
  opt.smoothness_translation_weight = 1.0;
  opt.smoothness_rotation_weight = 10.0;
  const auto results = RefineClipPoses(inputs, opt, /*joint=*/true);
  const ClipErrors e = Measure(s, results, inputs);
  std::printf(
      "joint (10 frames, smoothness on): rotation %.4f deg, translation "
      "%.4f%%, %s\n",
      e.rotation_deg, 100 * e.translation_rel,
      results[0].summary.termination.c_str());
  EXPECT_LE(e.rotation_deg, 0.05);
  EXPECT_LE(e.translation_rel, 0.002);
}

TEST(PoseRefinement, DegenerateFrameIsSkippedWithAReason) {
  const Scenario s = MakeScenario("refine_degenerate", 0, 2);
  auto inputs = Inputs(s, PixelSelection::kStaticOnly);
  inputs[1].valid_mask.setTo(0);
  const auto results = RefineClipPoses(inputs, {}, false);
  EXPECT_FALSE(results[0].summary.skipped);
  EXPECT_TRUE(results[1].summary.skipped);
  EXPECT_NE(results[1].summary.skip_reason.find("only 0 static"),
            std::string::npos);
  EXPECT_NE(results[1].summary.BriefReport().find("skipped"),
            std::string::npos);
  PoseRefinementOptions bad;
  bad.loss_scale_px = -1;
  EXPECT_THROW(RefineFramePose(inputs[0], bad), InputError);
  EXPECT_THROW(ParseRobustLoss("l2"), InputError);
}

TEST(PixelSampler, StratifiedAndSeeded) {
  cv::Mat valid(144, 256, CV_8UC1, cv::Scalar(255));
  valid(cv::Rect(0, 0, 128, 144)).setTo(0);  // left half invalid
  valid.at<uint8_t>(10, 5) = 255;  // one lone valid pixel in the invalid half
  const auto a = SamplePixelsStratified(valid, 1024, 7);
  const auto b = SamplePixelsStratified(valid, 1024, 7);
  const auto c = SamplePixelsStratified(valid, 1024, 8);
  ASSERT_EQ(a.size(), 1024u);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  bool lone = false;
  cv::Mat hist(4, 4, CV_32SC1, cv::Scalar(0));
  for (const auto& p : a) {
    ASSERT_TRUE(valid.at<uint8_t>(p.y(), p.x()));
    lone |= p == Eigen::Vector2i(5, 10);
    if (p.x() >= 128) hist.at<int>(p.y() * 4 / 144, (p.x() - 128) * 4 / 128)++;
  }
  EXPECT_TRUE(lone) << "every non-empty cell is visited";
  double lo, hi;
  cv::minMaxLoc(hist, &lo, &hi);
  EXPECT_LT(hi / lo, 1.6) << "uniform over the valid half";
  // No duplicates.
  auto sorted = a;
  std::sort(sorted.begin(), sorted.end(), [](const auto& x, const auto& y) {
    return std::make_pair(x.y(), x.x()) < std::make_pair(y.y(), y.x());
  });
  EXPECT_EQ(std::adjacent_find(sorted.begin(), sorted.end()), sorted.end());
}

}  // namespace
}  // namespace pose_refinement_test
}  // namespace geodrive

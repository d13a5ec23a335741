// Visibility on the real scene-0916: the logged front camera sees the
// condition cloud; a candidate that drives out of the LiDAR's reach loses it.

#include <gtest/gtest.h>

#include "dataset/drive_dataset.h"
#include "planning/clip_scene.h"
#include "planning/visibility.h"
#include "tests/common/test_util.h"

namespace plan_visibility_test {

TEST(PlanVisibility, CoverageFallsWhereTheSceneHasNoGeometry) {
  geodrive::DriveDatasetOptions dso;
  dso.root = geodrive::test::RealDataPath("nuscenes_scene0916");
  dso.version = "v1.0-mini-extract";
  dso.clip_stride = 1;
  dso.frames = geodrive::ClipFrameSource::kKeyframes;
  const auto dataset = geodrive::OpenDriveDataset(dso);
  const geodrive::DriveClip clip = dataset->LoadClip("scene-0916_0000_kf");
  const geodrive::PlanningScene scene = geodrive::PlanningSceneFromClip(clip);
  // The logged trajectory, and a straight run at 15 m/s for 12 s (180 m:
  // beyond the sweeps around frame 0).
  geodrive::Candidate far;
  far.name = far.source = "far";
  for (int i = 0; i <= 24; ++i)
    far.ego0_from_ego.Add(0.5 * i, geodrive::EgoPose(7.5 * i, 0, 0, 0));
  const std::vector<geodrive::Candidate> candidates = {
      geodrive::LoggedCandidate(scene), far};
  geodrive::PlanResult result = geodrive::ScoreCandidates(scene, candidates);
  const geodrive::VisibilityOptions options;
  const geodrive::ConditionScene condition =
      geodrive::VisibilityScene(clip, options);
  geodrive::ScoreVisibility(condition, clip, candidates, options, &result);
  const geodrive::CandidateScores& logged = result.candidates[0];
  const geodrive::CandidateScores& gone = result.candidates[1];
  EXPECT_GT(logged.min_coverage, 0.0);
  EXPECT_LE(logged.mean_coverage, 1.0);
  EXPECT_LT(gone.min_coverage, 0.5 * logged.min_coverage);
  EXPECT_LT(gone.mean_coverage, logged.mean_coverage);
}

}  // namespace plan_visibility_test

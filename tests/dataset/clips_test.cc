// Clip selection on the fixture (scenes of 55 CAM_FRONT frames at 12 Hz).

#include "dataset/nuscenes_clips.h"

#include <gtest/gtest.h>

#include <set>

#include "dataset/clip_id.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"
#include "tests/dataset/nuscenes_fixture.h"

namespace geodrive {
namespace {

Nuscenes LoadFixture(const std::string& name, int samples_per_scene = 10) {
  test::NuscenesFixture fx;
  fx.samples_per_scene = samples_per_scene;
  fx.tables.clear();
  fx.counter = 1;
  fx.Build();
  NuscenesOptions options;
  options.dataroot = fx.Write(test::MakeTempDir(name));
  return Nuscenes(options);
}

TEST(Clips, ConsecutiveFramesWithStrideNeverCrossScenes) {
  const Nuscenes nusc = LoadFixture("clips_stride");
  ClipOptions options;  // 25 frames, stride 6
  ClipSelectionSummary summary;
  const auto clips = SelectClips(nusc, options, &summary);
  // 55 frames per scene: starts 0, 6, ..., 30 (30 + 25 = 55) -> 6 clips per
  // scene.
  ASSERT_EQ(clips.size(), 12u);
  EXPECT_EQ(summary.clips, 12);
  EXPECT_EQ(summary.scenes, 2);
  std::set<std::string> ids;
  for (const Clip& clip : clips) {
    const auto chain = nusc.Chain(clip.scene, "CAM_FRONT");
    ASSERT_EQ(clip.sample_data.size(), 25u);
    EXPECT_EQ(clip.id,
              MakeClipId(nusc.scenes()[clip.scene].name, clip.start_index));
    EXPECT_EQ(clip.start_index % 6, 0);
    for (int k = 0; k < 25; ++k) {
      EXPECT_EQ(clip.sample_data[k], chain[clip.start_index + k]);
      EXPECT_EQ(
          nusc.samples()[nusc.sample_data()[clip.sample_data[k]].sample].scene,
          clip.scene);
      if (k > 0) {
        EXPECT_GT(clip.timestamps[k], clip.timestamps[k - 1]);
      }
    }
    ids.insert(clip.id);
  }
  EXPECT_EQ(ids.size(), clips.size());
  EXPECT_EQ(clips.front().id, "scene-0001_0000");
  EXPECT_EQ(clips.back().id, "scene-0002_0030");
  // Stable across runs and loads.
  const auto again = SelectClips(LoadFixture("clips_stride_again"), options);
  ASSERT_EQ(again.size(), clips.size());
  for (size_t i = 0; i < clips.size(); ++i) EXPECT_EQ(again[i].id, clips[i].id);

  options.stride = 1;
  EXPECT_EQ(SelectClips(nusc, options).size(), 2u * 31);
  options.start_at_keyframe = true;
  options.stride = 1;
  // Keyframes at 0, 6, ..., 54: starts 0..30 that are keyframes -> 6 per scene.
  for (const Clip& c : SelectClips(nusc, options)) {
    EXPECT_TRUE(nusc.sample_data()[c.sample_data[0]].is_key_frame);
  }
  EXPECT_EQ(SelectClips(nusc, options).size(), 12u);
}

TEST(Clips, ShortScenesGiveNoClip) {
  const Nuscenes nusc = LoadFixture("clips_short", 4);  // 19 frames per scene
  ClipSelectionSummary summary;
  EXPECT_TRUE(SelectClips(nusc, ClipOptions(), &summary).empty());
  EXPECT_EQ(summary.scenes_too_short, 2);
}

TEST(Clips, ResampledTo10HzPicksNearestFrames) {
  const Nuscenes nusc = LoadFixture("clips_resample");
  ClipOptions options;
  options.target_rate_hz = 10;
  const auto clips = SelectClips(nusc, options);
  ASSERT_FALSE(clips.empty());
  for (const Clip& clip : clips) {
    EXPECT_EQ(clip.id,
              MakeClipId(nusc.scenes()[clip.scene].name, clip.start_index, 10));
    ASSERT_EQ(clip.timestamps.size(), 25u);
    // 24 steps of 100 ms = 2.4 s, which 55 frames at 12 Hz (4.5 s) cover from
    // starts <= 25.
    EXPECT_LE(clip.start_index, 25);
    for (int k = 0; k < 25; ++k) {
      const double target = clip.timestamps[0] + k * 1e5;
      // Nearest 12 Hz frame: within half a source period (41.7 ms).
      EXPECT_LE(std::abs(clip.timestamps[k] - target), 1e6 / 24 + 1)
          << clip.id << " " << k;
      if (k > 0) {
        EXPECT_GT(clip.sample_data[k], clip.sample_data[k - 1]);
      }
    }
  }
  // 0, 6, 12, 18, 24 per scene.
  EXPECT_EQ(clips.size(), 10u);
  options.target_rate_hz = 24;  // above the source rate: frames would repeat
  EXPECT_TRUE(SelectClips(nusc, options).empty());
}

TEST(Clips, OptionsAreChecked) {
  const Nuscenes nusc = LoadFixture("clips_options");
  ClipOptions options;
  options.stride = 0;
  EXPECT_THROW(SelectClips(nusc, options), InputError);
  options = ClipOptions();
  options.channel = "CAM_BACK";
  EXPECT_THROW(SelectClips(nusc, options), InputError);
}

}  // namespace
}  // namespace geodrive

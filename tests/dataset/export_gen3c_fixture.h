#pragma once
// The GEN3C export's shared fixture (tests/dataset/export_gen3c_test.cc and
// gen3c_round_trip_test.cc): one synthetic scene at the full 12 Hz camera
// rate, 10.5 s (126 frames: one 121-frame clip), 320x180 images, built with
// LiDAR geometry and exported as GEN3C (the export renders at 1280x704
// whatever the pair's size). Built once per test binary build
// (test::SharedFixtureDir).

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "dataset/build_dataset.h"
#include "dataset/drive_dataset.h"
#include "dataset/exporter.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace export_gen3c_fixture {

constexpr int kFrames = 121, kWidth = 1280, kHeight = 704;
constexpr char kClip[] = "scene-0001_0000";

// Small images keep the build short.
inline const SyntheticDatasetOptions& WorldOptions() {
  static const SyntheticDatasetOptions o = [] {
    SyntheticDatasetOptions w;
    w.num_scenes = 1;
    w.seed = 7;
    w.image_width = 320;
    w.image_height = 180;
    w.scene_duration_s = 10.5;
    return w;
  }();
  return o;
}

inline const std::string& World() {
  static const std::string root =
      test::SharedFixtureDir("export_gen3c_world", [](const std::string& dir) {
        WriteSyntheticDataset(WorldOptions(), dir);
      });
  return root;
}

inline BuildDatasetOptions Options(const std::string& out) {
  BuildDatasetOptions o;
  o.dataroot = World();
  o.geometry = "lidar";
  o.out = out;
  o.quiet = true;
  o.clip_frames = kFrames;
  o.clips = {kClip};
  o.exports = {ExportFormat::kGen3c};
  // The pair itself at the source size (its 121 frames are not what is
  // tested here; the export renders at 1280x704 whatever the pair's size).
  o.width = 320;
  o.height = 180;
  return o;
}

// OUT of the build: pairs/<clip>/ and gen3c/<clip>/.
inline const std::string& Export() {
  static const std::string out =
      test::SharedFixtureDir("export_gen3c_out", [](const std::string& dir) {
        const BuildDatasetSummary s = BuildDataset(Options(dir));
        std::printf("gen3c export: %s\n", s.BriefReport().c_str());
        EXPECT_EQ(s.built, 1) << test::ReadFile(dir + "/failures.jsonl");
      });
  return out;
}

// The clip as the builder loads it (121 frames).
inline DriveClip LoadClip() {
  DriveDatasetOptions dopt;
  dopt.root = World();
  dopt.clip_frames = kFrames;
  DriveClip clip = OpenDriveDataset(dopt)->LoadClip(kClip);
  EXPECT_EQ(clip.num_frames(), kFrames);
  return clip;
}

inline std::string ClipDir() { return Export() + "/gen3c/" + kClip; }

}  // namespace export_gen3c_fixture
}  // namespace geodrive

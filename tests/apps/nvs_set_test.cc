// `geodrive nvs-set` on synthetic Waymo segments: one pair per segment and
// offset, the condition's camera along the trajectory shifted in the ego
// frame (checked against the ego poses of the dataset and against the
// analytic image shift of static points), the ground truth the real frames
// (the same bytes as build-dataset's pair of the clip), resumable and
// deterministic, and its errors.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "dataset/build_dataset.h"
#include "dataset/drive_dataset.h"
#include "dataset/pairs.h"
#include "dataset/scene_source.h"
#include "render/presets.h"
#include "render/renderer.h"
#include "render/video/video_io.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace nvs_set_test {
namespace {

namespace fs = std::filesystem;

// Three short synthetic Waymo segments (12 frames at 10 Hz, FRONT 96x144).
std::string World() {
  static const std::string dir =
      test::SharedFixtureDir("nvs_set_waymo", [](const std::string& d) {
        std::string log;
        const std::string cmd = test::GeodriveBinary() +
                                " synth --format waymo --out " + d +
                                "/w --scenes 3 --seed 7 --size 96x144 "
                                "--duration 1.2 --lidar-columns 400";
        if (test::RunCommand(cmd, &log) != 0)
          throw std::runtime_error(cmd + " failed:\n" + log);
      });
  return dir + "/w";
}

constexpr const char* kPairArgs = " --frames 9 --size 32x48 --threads 2";

std::string NvsSet(const std::string& args, int* rc) {
  std::string log;
  *rc = test::RunCommand(
      test::GeodriveBinary() + " nvs-set --dataroot " + World() + " " + args,
      &log);
  return log;
}

// The dataset's 9-frame clip from each segment's first frame.
std::unique_ptr<DriveDataset> Dataset() {
  DriveDatasetOptions o;
  o.format = DatasetFormat::kWaymo;
  o.root = World();
  o.clip_frames = 9;
  o.clip_stride = 1 << 30;
  return OpenDriveDataset(o);
}

// Pixel of the camera point p (OpenCV axes) through `cam`.
Eigen::Vector2d Project(const PinholeCamera& cam, const Eigen::Vector3d& p) {
  return {cam.fx * p.x() / p.z() + cam.cx, cam.fy * p.y() / p.z() + cam.cy};
}

// The pair's condition camera against the dataset's ego poses moved by `d`
// along their own y axis (the pair's world is the real camera at frame 0),
// and static points 8-40 m ahead of the real camera: where the shifted
// camera sees them, against the analytic shift of the camera point by the
// ego's left axis (camera axes) times d. Largest errors into the outputs.
void CheckShiftedCamera(const PairMeta& meta,
                        const DriveClip& clip,
                        double d,
                        double* max_pose_err,
                        double* max_px_err) {
  ASSERT_EQ(meta.world_from_cam.size(), clip.frames.size());
  const Rigid3d pair_from_world = clip.frames.front().world_from_cam.Inverse();
  const Rigid3d shift(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, d, 0));
  for (size_t i = 0; i < clip.frames.size(); ++i) {
    const DriveFrame& f = clip.frames[i];
    const Rigid3d expected =
        pair_from_world * f.world_from_ego * shift * f.ego_from_cam;
    const Rigid3d& got = meta.world_from_cam[i];
    *max_pose_err = std::max({*max_pose_err,
                              (got.translation - expected.translation).norm(),
                              got.rotation.angularDistance(expected.rotation)});
    // Static points 8-40 m ahead of the real camera: where the shifted
    // camera sees them, against the analytic shift of the camera point by
    // the ego's left axis (camera axes) times d.
    const Rigid3d cam_from_pair =
        f.world_from_cam.Inverse() * pair_from_world.Inverse();
    const Eigen::Vector3d left_in_cam =
        f.ego_from_cam.rotation.inverse() * Eigen::Vector3d(0, d, 0);
    for (const Eigen::Vector3d& p_cam :
         {Eigen::Vector3d(0, 0, 8), Eigen::Vector3d(-2, 1, 15),
          Eigen::Vector3d(3, -0.5, 40)}) {
      const Eigen::Vector3d p_pair = cam_from_pair.Inverse() * p_cam;
      const Eigen::Vector2d seen =
          Project(meta.intrinsics, got.Inverse() * p_pair);
      const Eigen::Vector2d analytic =
          Project(meta.intrinsics, p_cam - left_in_cam);
      *max_px_err = std::max(*max_px_err, (seen - analytic).norm());
      // Left of the ego: the scene moves right in the image.
      if (p_cam.z() == 8 && d > 0) {
        EXPECT_GT(seen.x(), Project(meta.intrinsics, p_cam).x());
      }
    }
  }
}

TEST(NvsSet, PairsPerSegmentAndOffsetAlongTheShiftedTrajectory) {
  const std::string out = test::MakeTempDir("nvs_set") + "/nvs";
  int rc = 0;
  std::string log = NvsSet("--offsets -3,3 --out " + out + kPairArgs, &rc);
  ASSERT_EQ(rc, 0) << log;
  EXPECT_NE(log.find("geodrive-diffusion generate --manifest " + out +
                     "/manifest.jsonl"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("geodrive eval --pred PRED --gt " + out +
                     "/pairs --metrics fid,fvd"),
            std::string::npos)
      << log;
  const std::vector<ManifestEntry> manifest =
      ReadManifest(out + "/manifest.jsonl");
  const std::unique_ptr<DriveDataset> dataset = Dataset();
  ASSERT_EQ(dataset->ClipIds().size(), 3u);
  ASSERT_EQ(manifest.size(), 6u) << log;  // 3 segments x 2 offsets
  std::map<std::string, const ManifestEntry*> by_id;
  for (const ManifestEntry& e : manifest) by_id[e.clip_id] = &e;
  for (const std::string& clip : dataset->ClipIds()) {
    for (const char* side : {"_shift_left_3m", "_shift_right_3m"}) {
      ASSERT_TRUE(by_id.count(clip + side)) << clip + side;
      EXPECT_EQ(by_id[clip + side]->clip_id.find('.'), std::string::npos);
    }
  }
  // Every pair: its meta names the source clip and offset; its condition
  // camera is the real camera with the ego moved sideways, in the pair's
  // world (the real camera at frame 0).
  double max_pose_err = 0, max_px_err = 0;
  for (const ManifestEntry& e : manifest) {
    const PairMeta meta = ReadPairMeta(out + "/" + e.pair_dir);
    ASSERT_TRUE(meta.novel_view.has_value()) << e.clip_id;
    const PairNovelView& nv = *meta.novel_view;
    const double d = nv.lateral_offset_m;
    EXPECT_EQ(std::abs(d), 3.0);
    EXPECT_EQ(e.clip_id, ShiftedPairId(nv.source_clip_id, d));
    const DriveClip clip = dataset->LoadClip(nv.source_clip_id);
    CheckShiftedCamera(meta, clip, d, &max_pose_err, &max_px_err);
    EXPECT_EQ(meta.quality.psnr_static.size(), clip.frames.size());
    for (const auto& psnr : meta.quality.psnr_static)
      EXPECT_FALSE(psnr.has_value()) << "a shifted view has no static PSNR";
  }
  std::printf("6 pairs: pose error %.3g (m / rad), static points %.3g px\n",
              max_pose_err, max_px_err);
  EXPECT_LT(max_pose_err, 1e-9);
  EXPECT_LT(max_px_err, 0.01);

  // The ground truth is the real frames: the same bytes as build-dataset's
  // pair of the same clip (and the same for both offsets).
  const std::string built = test::MakeTempDir("nvs_set_build") + "/b";
  std::string blog;
  ASSERT_EQ(
      test::RunCommand(test::GeodriveBinary() + " build-dataset --dataroot " +
                           World() + " --out " + built +
                           " --geometry lidar --clip-frames 9 "
                           "--stride 1073741824 --size 32x48 "
                           "--quiet",
                       &blog),
      0)
      << blog;
  for (const std::string& clip : dataset->ClipIds()) {
    for (const char* name : {"/gt.mp4", "/first_frame.png"}) {
      const std::string real = test::ReadFile(built + "/pairs/" + clip + name);
      ASSERT_FALSE(real.empty()) << clip << name;
      for (const char* side : {"_shift_left_3m", "_shift_right_3m"}) {
        EXPECT_EQ(test::ReadFile(out + "/pairs/" + clip + side + name), real)
            << clip << side << name;
      }
    }
  }

  // A rerun keeps the pairs; a second output has the same bytes.
  log = NvsSet("--offsets=-3,3 --out " + out + kPairArgs, &rc);
  ASSERT_EQ(rc, 0) << log;
  EXPECT_NE(log.find("pairs built 0, skipped (already built) 6"),
            std::string::npos)
      << log;
  const std::string again = test::MakeTempDir("nvs_set_again") + "/nvs";
  log = NvsSet("--offsets=-3,3 --out " + again + kPairArgs, &rc);
  ASSERT_EQ(rc, 0) << log;
  for (const ManifestEntry& e : manifest) {
    for (const char* name : {"/cond.mp4", "/gt.mp4", "/meta.json"}) {
      EXPECT_EQ(test::ReadFile(again + "/" + e.pair_dir + name),
                test::ReadFile(out + "/" + e.pair_dir + name))
          << e.pair_dir << name;
    }
  }
}

// The condition equals a direct render of the segment's LiDAR scene (the
// same scene source, paper preset, static scene) at the camera poses made
// from the dataset's ego poses moved 3 m right: every pixel of every frame.
TEST(NvsSet, ConditionIsTheRenderAtTheShiftedPose) {
  const std::string out = test::MakeTempDir("nvs_set_render") + "/nvs";
  const std::unique_ptr<DriveDataset> dataset = Dataset();
  const DriveClip clip = dataset->LoadClip(dataset->ClipIds()[0]);
  int rc = 0;
  const std::string log =
      NvsSet("--segments " + clip.scene_name +
                 " --offsets=-3 --edit-mode none --lossless-frames --out " +
                 out + kPairArgs,
             &rc);
  ASSERT_EQ(rc, 0) << log;
  const std::string pair = out + "/pairs/" + clip.id + "_shift_right_3m";
  const std::vector<cv::Mat> cond = ReadVideoFrames(pair + "/cond_frames");
  ASSERT_EQ(cond.size(), clip.frames.size());

  SceneInputs in;
  in.clip = &clip;
  const ConditionScene scene =
      BuildConditionScene("lidar", in, SceneSourceOptions());
  ASSERT_TRUE(scene.metric());
  // The scene frame is the real camera at frame 0.
  EXPECT_LT(scene.trajectory.world_from_cam[0].translation.norm(), 1e-9);
  const Rigid3d scene_from_world = clip.frames[0].world_from_cam.Inverse();
  const Rigid3d shift(Eigen::Quaterniond::Identity(),
                      Eigen::Vector3d(0, -3, 0));
  std::vector<Rigid3d> cam_from_scene;
  for (const DriveFrame& f : clip.frames) {
    cam_from_scene.push_back(
        (scene_from_world * f.world_from_ego * shift * f.ego_from_cam)
            .Inverse());
  }
  RenderOptions ro = PresetRenderOptions(RenderPreset::kPaper);
  ro.width = 48;
  ro.height = 32;
  ro.radius_px = 1.0;
  const std::vector<cv::Mat> direct = FinalFrames(
      RenderFrames(scene.cloud, {scene.CameraAt(48, 32, ResizeMode::kResize)},
                   cam_from_scene, ro),
      RenderPreset::kPaper);
  ASSERT_EQ(direct.size(), cond.size());
  int64_t differing = 0, drawn = 0;
  for (size_t i = 0; i < cond.size(); ++i) {
    cv::Mat diff;
    cv::absdiff(cond[i], direct[i], diff);
    differing += cv::countNonZero(diff.reshape(1));
    drawn += cv::countNonZero(direct[i].reshape(1));
  }
  std::printf(
      "condition vs direct render at the shifted pose: %lld of %lld "
      "drawn channel values differ\n",
      static_cast<long long>(differing), static_cast<long long>(drawn));
  EXPECT_GT(drawn, 0);
  EXPECT_EQ(differing, 0);
}

// The real nuScenes scene (keyframes of the extract): both pairs' condition
// cameras follow the logged ego poses moved 3 m, the manifest has the pairs.
TEST(NvsSet, RealNuscenesScene) {
  const std::string root = test::RealDataPath("nuscenes_scene0916");
  ASSERT_TRUE(fs::is_directory(root)) << root << " is missing";
  const std::string out = test::MakeTempDir("nvs_set_real") + "/nvs";
  std::string log;
  ASSERT_EQ(
      test::RunCommand(test::GeodriveBinary() + " nvs-set --dataroot " + root +
                           " --version v1.0-mini-extract --frame-source "
                           "keyframes --segments scene-0916 "
                           "--offsets=-3,3 --out " +
                           out + kPairArgs,
                       &log),
      0)
      << log;
  const std::vector<ManifestEntry> manifest =
      ReadManifest(out + "/manifest.jsonl");
  ASSERT_EQ(manifest.size(), 2u) << log;
  DriveDatasetOptions o;
  o.root = root;
  o.version = "v1.0-mini-extract";
  o.frames = ClipFrameSource::kKeyframes;
  o.clip_frames = 9;
  o.clip_stride = 1 << 30;
  const std::unique_ptr<DriveDataset> dataset = OpenDriveDataset(o);
  double max_pose_err = 0, max_px_err = 0;
  for (const ManifestEntry& e : manifest) {
    const PairMeta meta = ReadPairMeta(out + "/" + e.pair_dir);
    ASSERT_TRUE(meta.novel_view.has_value()) << e.clip_id;
    EXPECT_EQ(meta.novel_view->source_clip_id, "scene-0916_0000_kf");
    CheckShiftedCamera(meta, dataset->LoadClip(meta.novel_view->source_clip_id),
                       meta.novel_view->lateral_offset_m, &max_pose_err,
                       &max_px_err);
    EXPECT_GT(meta.quality.coverage.front(), 0.3) << e.clip_id;
  }
  std::printf("scene-0916: pose error %.3g (m / rad), static points %.3g px\n",
              max_pose_err, max_px_err);
  // World coordinates of ~1e3 m: double rounding ~1e-13 relative.
  EXPECT_LT(max_pose_err, 1e-6);
  EXPECT_LT(max_px_err, 0.01);
}

// nuScenes too, and batch isolation: on a synthetic nuScenes root whose
// second scene's front images are broken, that scene's two pairs are
// recorded as failed and the first scene's pairs are built along the shifted
// ego poses (exit 3).
TEST(NvsSet, NuscenesAndABrokenSegmentRecorded) {
  const std::string dir = test::MakeTempDir("nvs_set_nuscenes");
  const std::string root = dir + "/nu";
  std::string log;
  ASSERT_EQ(test::RunCommand(test::GeodriveBinary() + " synth --out " + root +
                                 " --scenes 2 --seed 7 --size 90x160 "
                                 "--duration 1.5 --lidar-azimuth-steps 180",
                             &log),
            0)
      << log;
  int broken = 0;
  for (const char* folder : {"/samples/CAM_FRONT", "/sweeps/CAM_FRONT"}) {
    for (const auto& e : fs::directory_iterator(root + folder)) {
      if (e.path().filename().string().rfind("synth-7-0001__", 0) != 0)
        continue;
      test::WriteFile(e.path().string(), "not a JPEG");
      ++broken;
    }
  }
  ASSERT_GT(broken, 9);
  const std::string out = dir + "/nvs";
  ASSERT_EQ(
      test::RunCommand(test::GeodriveBinary() + " nvs-set --dataroot " + root +
                           " --offsets -3,3 --out " + out + kPairArgs,
                       &log),
      3)
      << log;
  EXPECT_NE(log.find("pairs built 2"), std::string::npos) << log;
  EXPECT_NE(log.find("failed 2"), std::string::npos) << log;
  const std::vector<FailureEntry> failures =
      ReadFailures(out + "/failures.jsonl");
  ASSERT_EQ(failures.size(), 2u);
  EXPECT_EQ(failures[0].clip_id, "scene-0002_0000_shift_left_3m");
  EXPECT_EQ(failures[1].clip_id, "scene-0002_0000_shift_right_3m");
  const std::vector<ManifestEntry> manifest =
      ReadManifest(out + "/manifest.jsonl");
  ASSERT_EQ(manifest.size(), 2u);
  DriveDatasetOptions o;
  o.root = root;
  o.clip_frames = 9;
  o.clip_stride = 1 << 30;
  const std::unique_ptr<DriveDataset> dataset = OpenDriveDataset(o);
  double max_pose_err = 0, max_px_err = 0;
  for (const ManifestEntry& e : manifest) {
    EXPECT_EQ(e.clip_id.rfind("scene-0001_0000_shift_", 0), 0u) << e.clip_id;
    const PairMeta meta = ReadPairMeta(out + "/" + e.pair_dir);
    ASSERT_TRUE(meta.novel_view.has_value()) << e.clip_id;
    CheckShiftedCamera(meta, dataset->LoadClip(meta.novel_view->source_clip_id),
                       meta.novel_view->lateral_offset_m, &max_pose_err,
                       &max_px_err);
  }
  EXPECT_LT(max_pose_err, 1e-9);
  EXPECT_LT(max_px_err, 0.01);
}

TEST(NvsSet, NamedSegmentsAndOffsets) {
  const std::string out = test::MakeTempDir("nvs_set_named") + "/nvs";
  const std::unique_ptr<DriveDataset> dataset = Dataset();
  const DriveClip second = dataset->LoadClip(dataset->ClipIds()[1]);
  int rc = 0;
  const std::string log =
      NvsSet("--segments " + second.scene_name +
                 " --offsets 1.5,-0.25,0 --out " + out + kPairArgs,
             &rc);
  ASSERT_EQ(rc, 0) << log;
  const std::vector<ManifestEntry> manifest =
      ReadManifest(out + "/manifest.jsonl");
  std::vector<std::string> ids;
  for (const ManifestEntry& e : manifest) ids.push_back(e.clip_id);
  const std::string c = second.id;
  EXPECT_EQ(ids,
            (std::vector<std::string>{c + "_shift_0m", c + "_shift_left_1p5m",
                                      c + "_shift_right_0p25m"}));
  // Offset 0: the recorded trajectory itself.
  const PairMeta zero = ReadPairMeta(out + "/pairs/" + c + "_shift_0m");
  const Rigid3d pair_from_world =
      second.frames.front().world_from_cam.Inverse();
  for (size_t i = 0; i < second.frames.size(); ++i) {
    EXPECT_LT((zero.world_from_cam[i].translation -
               (pair_from_world * second.frames[i].world_from_cam).translation)
                  .norm(),
              1e-9);
  }
}

TEST(NvsSet, ClearErrors) {
  const std::string out = test::MakeTempDir("nvs_set_errors") + "/nvs";
  int rc = 0;
  std::string log = NvsSet("--segments nope --out " + out + kPairArgs, &rc);
  EXPECT_EQ(rc, 2) << log;
  EXPECT_NE(log.find("--segments: 'nope' is not a segment of"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("3 segments: synthetic_7_0_000_1200"), std::string::npos)
      << log;
  log = NvsSet("--offsets=-3,abc --out " + out + kPairArgs, &rc);
  EXPECT_EQ(rc, 2) << log;
  EXPECT_NE(log.find("--offsets: 'abc' is not a number of metres"),
            std::string::npos)
      << log;
  log = NvsSet("--offsets 3,3.0001 --out " + out + kPairArgs, &rc);
  EXPECT_EQ(rc, 2) << log;
  EXPECT_NE(log.find("lateral offset 3.0001 m is listed twice"),
            std::string::npos)
      << log;
  // Segments shorter than --frames.
  log = NvsSet("--frames 25 --out " + out, &rc);
  EXPECT_EQ(rc, 2) << log;
  EXPECT_NE(log.find("no segment has 25 frames"), std::string::npos) << log;
  EXPECT_FALSE(fs::exists(out + "/manifest.jsonl"));
}

// A novel-view pair's meta.json (with novel_view and null static PSNRs) and
// the manifest validate against the published schemas.
TEST(NvsSet, PairFilesValidateAgainstTheSchemas) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("jsonschema");
  const std::string out = test::MakeTempDir("nvs_set_schema") + "/nvs";
  const std::unique_ptr<DriveDataset> dataset = Dataset();
  const DriveClip clip = dataset->LoadClip(dataset->ClipIds()[2]);
  int rc = 0;
  std::string log = NvsSet("--segments " + clip.scene_name +
                               " --offsets 2.5 --out " + out + kPairArgs,
                           &rc);
  ASSERT_EQ(rc, 0) << log;
  const std::string py = std::string(test::kDebianPython) +
                         " " GEODRIVE_SOURCE_DIR
                         "/tests/dataset/validate_json.py ";
  const std::string schemas = GEODRIVE_SOURCE_DIR "/data_schema/";
  const std::string meta =
      out + "/pairs/" + clip.id + "_shift_left_2p5m/meta.json";
  const std::string text = test::ReadFile(meta);
  EXPECT_NE(text.find("\"novel_view\""), std::string::npos) << text;
  EXPECT_EQ(
      test::RunCommand(py + schemas + "pair_meta.schema.json " + meta, &log), 0)
      << log;
  EXPECT_EQ(test::RunCommand(py + "--jsonl " + schemas +
                                 "manifest_line.schema.json " + out +
                                 "/manifest.jsonl",
                             &log),
            0)
      << log;
}

TEST(NvsSet, PairIds) {
  EXPECT_EQ(ShiftedPairId("s_0000", 3), "s_0000_shift_left_3m");
  EXPECT_EQ(ShiftedPairId("s_0000", -3), "s_0000_shift_right_3m");
  EXPECT_EQ(ShiftedPairId("s_0000", 1.25), "s_0000_shift_left_1p25m");
  EXPECT_EQ(ShiftedPairId("s_0000", -0.0004), "s_0000_shift_0m");
  EXPECT_EQ(ShiftedPairId("s_0000", 0), "s_0000_shift_0m");
  EXPECT_EQ(ShiftedPairId("s_0000", 10.5), "s_0000_shift_left_10p5m");
}

}  // namespace
}  // namespace nvs_set_test
}  // namespace geodrive

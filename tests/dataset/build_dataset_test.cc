// The dataset builder on the synthetic world: every clip becomes a pair,
// outputs validate against the schemas with a real validator, the condition
// video agrees with GT in static regions, metric poses match the truth, bad
// clips are isolated, and runs are deterministic.

#include "dataset/build_dataset.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "dataset/drive_dataset.h"
#include "dataset/internal/pair_builder.h"
#include "dataset/pairs.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "geometry/monst3r.h"
#include "geometry/npy.h"
#include "geometry/pointmap.h"
#include "geometry/trajectory_io.h"
#include "geometry/util/files.h"
#include "geometry/util/progress.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace build_dataset_test {
namespace {

namespace fs = std::filesystem;

// One scene, 800x450, 8.5 s: 102 CAM_FRONT frames, MonST3R clips at 0, 24,
// 48, 72.
const std::string& World() {
  static const std::string root =
      test::SharedFixtureDir("build_world", [](const std::string& dir) {
        SyntheticDatasetOptions o;
        o.num_scenes = 1;
        o.seed = 21;
        o.image_width = 800;
        o.image_height = 450;
        o.scene_duration_s = 8.5;
        o.write_monst3r = true;
        WriteSyntheticDataset(o, dir);
      });
  return root;
}

BuildDatasetOptions Options(const std::string& out) {
  BuildDatasetOptions o;
  o.dataroot = World();
  o.monst3r_root = World() + "/monst3r";
  o.out = out;
  o.quiet = true;
  return o;
}

// Everything a build writes that must be reproducible (report.html holds
// timings: excluded).
std::map<std::string, std::string> OutputFiles(const std::string& out) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(out)) {
    if (!e.is_regular_file()) continue;
    const std::string rel = fs::relative(e.path(), out).string();
    if (rel == "report.html" || rel == ".complete" ||
        rel.rfind(".lock", 0) == 0)
      continue;  // timings; fixture marker
    files[rel] = test::ReadFile(e.path().string());
  }
  return files;
}

const std::string& FullBuild() {
  static const std::string out =
      test::SharedFixtureDir("build_full", [](const std::string& dir) {
        const BuildDatasetSummary s = BuildDataset(Options(dir));
        std::printf("full build: %s\n", s.BriefReport().c_str());
      });
  return out;
}

// The static-region PSNR's sum against the per-pixel formula in double, on
// random frames and masks (holes, runs, all and nothing), at widths that are
// not multiples of a vector and at the widest frame allowed.
TEST(BuildDataset, MaskedPsnrIsTheFormula) {
  cv::RNG rng(11);
  for (const cv::Size size : {cv::Size(720, 480), cv::Size(37, 5),
                              cv::Size(1, 3), cv::Size(16384, 2)}) {
    for (int kind = 0; kind < 4; ++kind) {
      cv::Mat a(size, CV_8UC3), b(size, CV_8UC3), mask(size, CV_8UC1);
      rng.fill(a, cv::RNG::UNIFORM, 0, 256);
      rng.fill(b, cv::RNG::UNIFORM, 0, 256);
      if (kind == 3) {  // the largest differences, 255^2 in every byte
        a = cv::Scalar::all(0);
        b = cv::Scalar::all(255);
      }
      rng.fill(mask, cv::RNG::UNIFORM, 0, 2);
      if (kind == 1) mask = cv::Scalar(7);
      if (kind == 2) mask = cv::Scalar(0);
      double se = 0, n = 0;
      for (int y = 0; y < size.height; ++y) {
        for (int x = 0; x < size.width; ++x) {
          if (mask.at<uint8_t>(y, x) == 0) continue;
          for (int c = 0; c < 3; ++c) {
            const double d =
                a.at<cv::Vec3b>(y, x)[c] - b.at<cv::Vec3b>(y, x)[c];
            se += d * d;
            n += 1;
          }
        }
      }
      const std::optional<double> got = internal::MaskedPsnr(a, b, mask);
      if (n == 0) {
        EXPECT_FALSE(got.has_value()) << size << " " << kind;
        continue;
      }
      ASSERT_TRUE(got.has_value()) << size << " " << kind;
      // Integer sums, exact: the same double as the formula's.
      EXPECT_EQ(*got, 10.0 * std::log10(255.0 * 255.0 / (se / n)))
          << size << " " << kind;
    }
  }
}

TEST(BuildDataset, EveryMonst3rClipBecomesAPair) {
  const std::string out = FullBuild();
  const auto manifest = ReadManifest(out + "/manifest.jsonl");
  ASSERT_EQ(manifest.size(), 4u);  // clips 0, 24, 48, 72 have MonST3R folders
  EXPECT_EQ(test::ReadFile(out + "/failures.jsonl"), "");
  for (const auto& e : manifest) {
    for (const char* f : {"gt.mp4", "cond.mp4", "first_frame.png", "boxes.json",
                          "meta.json", "preview.png"}) {
      EXPECT_TRUE(fs::exists(out + "/" + e.pair_dir + "/" + f))
          << e.pair_dir << "/" << f;
    }
    EXPECT_EQ(e.num_frames, 25);
    EXPECT_EQ(e.pose_units, "metres");
  }
  EXPECT_TRUE(fs::exists(out + "/report.html"));
}

TEST(BuildDataset, OutputsValidateAgainstSchemas) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("jsonschema");
  const std::string out = FullBuild();
  const std::string py = std::string(test::kDebianPython) +
                         " " GEODRIVE_SOURCE_DIR
                         "/tests/dataset/validate_json.py ";
  const std::string schema = GEODRIVE_SOURCE_DIR "/data_schema/";
  std::string metas, boxes, log;
  for (const auto& e : ReadManifest(out + "/manifest.jsonl")) {
    metas += " " + out + "/" + e.pair_dir + "/meta.json";
    boxes += " " + out + "/" + e.pair_dir + "/boxes.json";
  }
  EXPECT_EQ(
      test::RunCommand(py + schema + "pair_meta.schema.json" + metas, &log), 0)
      << log;
  EXPECT_EQ(test::RunCommand(py + schema + "boxes.schema.json" + boxes, &log),
            0)
      << log;
  EXPECT_EQ(
      test::RunCommand(py + "--jsonl " + schema + "manifest_line.schema.json " +
                           out + "/manifest.jsonl",
                       &log),
      0)
      << log;
}

// Condition frames vs GT in static regions (rendered pixels outside every
// vehicle box): frame 0 is a re-render of its own pointmap (high PSNR); later
// frames show the frame-0 cloud from the moving camera, where disocclusions and
// splat gaps lower it.
TEST(BuildDataset, ConditionAgreesWithGroundTruthInStaticRegions) {
  const std::string out = FullBuild();
  for (const auto& e : ReadManifest(out + "/manifest.jsonl")) {
    const PairMeta m = ReadPairMeta(out + "/" + e.pair_dir);
    ASSERT_EQ(m.quality.psnr_static.size(), 25u);
    std::printf("%s PSNR(static) per frame:", m.clip_id.c_str());
    double sum = 0;
    for (const auto& p : m.quality.psnr_static) {
      ASSERT_TRUE(p.has_value()) << "every synthetic frame has static pixels";
      std::printf(" %.1f", *p), sum += *p;
    }
    std::printf("  (mean %.2f dB, coverage frame0 %.3f frame24 %.3f)\n",
                sum / 25, m.quality.coverage.front(),
                m.quality.coverage.back());
    EXPECT_GT(m.quality.psnr_static.front().value(), 25.0);
    for (const auto& p : m.quality.psnr_static) EXPECT_GT(p.value(), 14.0);
    EXPECT_GT(sum / 25, 18.0);
    EXPECT_GT(m.quality.coverage.front(), 0.5);
  }
}

// With LiDAR present the pair's poses are metric: within 1 % of the true
// relative camera motion.
TEST(BuildDataset, MetricPosesWithinOnePercentOfTruth) {
  const std::string out = FullBuild();
  DriveDatasetOptions no;
  no.root = World();
  const std::unique_ptr<DriveDataset> dataset = OpenDriveDataset(no);
  for (const auto& e : ReadManifest(out + "/manifest.jsonl")) {
    const PairMeta m = ReadPairMeta(out + "/" + e.pair_dir);
    ASSERT_EQ(m.pose_units, "metres");
    const DriveClip clip = dataset->LoadClip(m.clip_id);
    ASSERT_EQ(clip.frames.size(), m.frames.size());
    const Rigid3d cam0_from_global =
        clip.frames.front().world_from_cam.Inverse();
    double worst = 0, length = 0;
    for (size_t i = 0; i < m.frames.size(); ++i) {
      ASSERT_EQ(clip.frames[i].frame_id, m.frames[i].sample_data_token);
      const Rigid3d truth = cam0_from_global * clip.frames[i].world_from_cam;
      length = std::max(length, truth.translation.norm());
      worst = std::max(
          worst, (m.world_from_cam[i].translation - truth.translation).norm());
      EXPECT_LT(
          RotationDistanceDeg(m.world_from_cam[i].rotation, truth.rotation),
          0.1);
    }
    std::printf(
        "%s: max position error %.4f m over %.2f m of travel (%.3f %%), scale "
        "%s\n",
        m.clip_id.c_str(), worst, length, 100 * worst / length,
        m.scale_report.c_str());
    EXPECT_LT(worst, 0.01 * length);
  }
}

TEST(BuildDataset, ThreadsAndResumeGiveIdenticalOutput) {
  const std::string full = FullBuild();
  // Two threads.
  const std::string two = test::MakeTempDir("build_two_threads");
  BuildDatasetOptions o = Options(two);
  o.threads = 2;
  BuildDataset(o);
  EXPECT_TRUE(OutputFiles(two) == OutputFiles(full))
      << "2-thread build differs";
  // Interrupted after one pair, then resumed.
  const std::string resumed = test::MakeTempDir("build_resumed");
  o = Options(resumed);
  o.max_clips = 1;
  const BuildDatasetSummary first = BuildDataset(o);
  EXPECT_EQ(first.built, 1);
  o.max_clips = 0;
  const BuildDatasetSummary second = BuildDataset(o);
  EXPECT_EQ(second.skipped_existing, 1);
  EXPECT_EQ(second.built, 3);
  EXPECT_TRUE(OutputFiles(resumed) == OutputFiles(full))
      << "resumed build differs";
}

TEST(BuildDataset, BadClipsAreIsolatedAndRecorded) {
  // A copy of the world with one corrupted MonST3R depth file and one missing
  // camera image.
  const std::string root = test::MakeTempDir("build_bad_world");
  fs::copy(World(), root, fs::copy_options::recursive);
  {
    std::ofstream trunc(root + "/monst3r/scene-0001_0000/frame_0003.npy",
                        std::ios::binary | std::ios::trunc);
    trunc << "\x93NUMPY";
  }
  DriveDatasetOptions no;
  no.root = root;
  std::string missing;
  {
    // CAM_FRONT frame 60 of the scene: only in the clip starting at 48.
    const DriveClip clip = OpenDriveDataset(no)->LoadClip("scene-0001_0048");
    missing = clip.frames[12].image_path;
  }
  fs::remove(missing);
  const std::string out = test::MakeTempDir("build_bad_out");
  BuildDatasetOptions o = Options(out);
  o.dataroot = root;
  o.monst3r_root = root + "/monst3r";
  const BuildDatasetSummary s = BuildDataset(o);
  std::printf("%s\n", s.BriefReport().c_str());
  EXPECT_EQ(s.built, 2);
  EXPECT_EQ(s.failed, 2);
  const auto failures = ReadFailures(out + "/failures.jsonl");
  ASSERT_EQ(failures.size(), 2u);
  EXPECT_EQ(failures[0].clip_id, "scene-0001_0000");
  EXPECT_NE(failures[0].error.find("frame_0003.npy"), std::string::npos)
      << failures[0].error;
  EXPECT_EQ(failures[1].clip_id, "scene-0001_0048");
  EXPECT_EQ(failures[1].stage, "gt");
  EXPECT_NE(failures[1].error.find(fs::path(missing).filename().string()),
            std::string::npos)
      << failures[1].error;
  EXPECT_EQ(ReadManifest(out + "/manifest.jsonl").size(), 2u);
  EXPECT_FALSE(fs::exists(out + "/pairs/scene-0001_0000"));
}

// Without MonST3R every clip of the dataset (stride 6: 13 clips) becomes a
// pair.
TEST(BuildDataset, LidarGeometryNeedsNoMonst3rAndBuildsEveryClip) {
  const std::string out = test::MakeTempDir("build_lidar");
  BuildDatasetOptions o = Options(out);
  o.monst3r_root.clear();
  o.geometry = "lidar";
  o.threads = 2;
  const BuildDatasetSummary s = BuildDataset(o);
  std::printf("lidar geometry: %s\n", s.BriefReport().c_str());
  EXPECT_EQ(s.clips_total, 13);
  ASSERT_EQ(s.built, s.clips_total) << test::ReadFile(out + "/failures.jsonl");
  EXPECT_EQ(ReadManifest(out + "/manifest.jsonl").size(), 13u);
  const PairMeta m = ReadPairMeta(out + "/pairs/scene-0001_0006");
  EXPECT_EQ(m.geometry_source, "lidar");
  EXPECT_EQ(m.pose_units, "metres");
  std::printf(
      "lidar geometry: coverage frame0 %.3f, PSNR(static) frame0 %.1f dB\n",
      m.quality.coverage.front(), m.quality.psnr_static.front().value_or(0));
  EXPECT_GT(m.quality.coverage.front(), 0.02);
}

// The released pipeline's preset (soft splatting at 288x512, x2 upsample, frame
// 0 = real image).
TEST(BuildDataset, GeodriveCompatPresetBuilds) {
  const std::string out = test::MakeTempDir("build_compat");
  BuildDatasetOptions o = Options(out);
  o.preset = RenderPreset::kGeodriveCompat;
  o.clips = {"scene-0001_0024"};
  const BuildDatasetSummary s = BuildDataset(o);
  ASSERT_EQ(s.built, 1) << test::ReadFile(out + "/failures.jsonl");
  const PairMeta m = ReadPairMeta(out + "/pairs/scene-0001_0024");
  EXPECT_EQ(m.preset, "geodrive-compat");
  // Frame 0 is the real image: its static-region PSNR is that of the video, not
  // of a render.
  std::printf("geodrive-compat: PSNR(static) frame0 %.1f dB frame24 %.1f dB\n",
              m.quality.psnr_static.front().value(),
              m.quality.psnr_static.back().value());
  EXPECT_GT(m.quality.psnr_static.front().value(), 35.0);
}

TEST(BuildDataset, BadOptionsAreInputErrors) {
  BuildDatasetOptions o = Options(test::MakeTempDir("build_bad_opts"));
  // Encoder options fail at start, before any clip is built.
  BuildDatasetOptions crf = o;
  crf.video_crf = -1;
  EXPECT_THROW(BuildDataset(crf), InputError);
  BuildDatasetOptions preset = o;
  preset.video_preset = "turbo";
  EXPECT_THROW(BuildDataset(preset), InputError);
  EXPECT_FALSE(fs::exists(o.out + "/pairs"));
  o.threads = 0;
  EXPECT_THROW(BuildDataset(o), InputError);
  o = Options(test::MakeTempDir("build_bad_opts2"));
  o.clips = {"scene-9999_0000"};
  EXPECT_THROW(BuildDataset(o), InputError);
  o = Options(test::MakeTempDir("build_bad_opts3"));
  o.dataroot = "/nonexistent/dataroot";
  EXPECT_THROW(BuildDataset(o), InputError);
}

// --refine-poses (paper eq. 3) on the MonST3R path: a clip whose stored poses
// of frames 1..24 are pushed 2 % of the scene scale sideways while its pts3d
// pointmaps (O_t) keep the true geometry: the refinement pulls the
// reprojection RMS from several pixels to below half a pixel, and meta.json
// reports both. Without the flag the fields are absent (no -1 sentinel).
TEST(BuildDataset, RefinePosesReportsReprojectionRmsBeforeAndAfter) {
  const std::string id = "scene-0001_0024";
  const std::string root = test::MakeTempDir("build_refine_root");
  fs::copy(World() + "/monst3r/" + id, root + "/" + id,
           fs::copy_options::recursive);
  const std::string dir = root + "/" + id;
  const Monst3rFolder folder = Monst3rFolder::Open(dir);
  for (int i = 0; i < folder.num_frames(); ++i) {
    const Pointmap pm = BuildPointmap(folder.LoadFrame(i));
    cv::Mat pts = pm.points_in_world.clone();
    WriteNpy(dir + "/pts3d_" + std::to_string(i) + ".npy",
             NpyArray::Float32({pts.rows, pts.cols, 3},
                               reinterpret_cast<const float*>(pts.data)));
  }
  Trajectory t = ReadMonst3rTrajectory(dir + "/pred_traj.txt");
  const double shift = 0.02 * (t.world_from_cam.back().translation -
                               t.world_from_cam.front().translation)
                                  .norm();
  for (size_t i = 1; i < t.size(); ++i)
    t.world_from_cam[i].translation.x() += shift;
  WriteMonst3rTrajectory(dir + "/pred_traj.txt", t);

  BuildDatasetOptions o = Options(test::MakeTempDir("build_refine_out"));
  o.monst3r_root = root;
  o.clips = {id};
  o.edit_mode = PairEditMode::kNone;
  o.refine_poses = true;
  ASSERT_EQ(BuildDataset(o).built, 1);
  const PairMeta m = ReadPairMeta(o.out + "/pairs/" + id);
  ASSERT_TRUE(m.quality.reprojection_rms_px_before.has_value());
  ASSERT_TRUE(m.quality.reprojection_rms_px_after.has_value());
  std::printf("refine-poses: reprojection RMS %.3f px -> %.3f px\n",
              *m.quality.reprojection_rms_px_before,
              *m.quality.reprojection_rms_px_after);
  EXPECT_GT(*m.quality.reprojection_rms_px_before, 3.0);
  EXPECT_LT(*m.quality.reprojection_rms_px_after, 0.5);

  BuildDatasetOptions plain = o;
  plain.out = test::MakeTempDir("build_refine_plain");
  plain.refine_poses = false;
  ASSERT_EQ(BuildDataset(plain).built, 1);
  const PairMeta p = ReadPairMeta(plain.out + "/pairs/" + id);
  EXPECT_FALSE(p.quality.reprojection_rms_px_before.has_value());
  EXPECT_EQ(test::ReadFile(plain.out + "/pairs/" + id + "/meta.json")
                .find("reprojection_rms_px"),
            std::string::npos);
}

// The job's contract on resume: one run per output folder; a pair
// counts as finished only when its files verify and its options are this
// run's.
TEST(BuildDataset, SecondRunOnTheSameOutIsRefused) {
  BuildDatasetOptions o = Options(test::MakeTempDir("build_locked"));
  o.clips = {"scene-0001_0024"};
  fs::create_directories(o.out);
  const ExclusiveLock other(o.out + "/.lock", "test");  // another run
  try {
    BuildDataset(o);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("another process (pid "),
              std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(fs::exists(o.out + "/pairs/scene-0001_0024"));
}

TEST(BuildDataset, ResumeRebuildsPairsWithMissingOrTruncatedFiles) {
  BuildDatasetOptions o = Options(test::MakeTempDir("build_verify"));
  o.clips = {"scene-0001_0000", "scene-0001_0024"};
  ASSERT_EQ(BuildDataset(o).built, 2);
  const auto reference = OutputFiles(o.out);
  fs::remove(o.out + "/pairs/scene-0001_0000/gt.mp4");
  fs::resize_file(o.out + "/pairs/scene-0001_0024/cond.mp4", 100);
  const BuildDatasetSummary s = BuildDataset(o);
  EXPECT_EQ(s.rebuilt_broken, 2);
  EXPECT_EQ(s.built, 2);
  EXPECT_EQ(s.skipped_existing, 0);
  EXPECT_TRUE(OutputFiles(o.out) == reference);
  EXPECT_EQ(BuildDataset(o).skipped_existing, 2);  // now they verify
}

TEST(BuildDataset, PairsOfOtherContentOptionsAreRebuiltOrKept) {
  BuildDatasetOptions o = Options(test::MakeTempDir("build_mismatch"));
  o.clips = {"scene-0001_0024"};
  o.edit_mode = PairEditMode::kNone;
  ASSERT_EQ(BuildDataset(o).built, 1);
  const std::string meta = o.out + "/pairs/scene-0001_0024";
  o.width = 360;
  o.height = 240;
  const BuildDatasetSummary rebuilt = BuildDataset(o);
  EXPECT_EQ(rebuilt.rebuilt_mismatched, 1);
  EXPECT_EQ(ReadPairMeta(meta).intrinsics.width, 360);
  BuildDatasetOptions keep = o;
  keep.width = 720;
  keep.height = 480;
  keep.keep_mismatched = true;
  const BuildDatasetSummary kept = BuildDataset(keep);
  EXPECT_EQ(kept.kept_mismatched, 1);
  EXPECT_EQ(kept.built, 0);
  EXPECT_EQ(ReadPairMeta(meta).intrinsics.width, 360);
  EXPECT_NE(kept.BriefReport().find("kept (other options) 1"),
            std::string::npos);
}

}  // namespace
}  // namespace build_dataset_test
}  // namespace geodrive

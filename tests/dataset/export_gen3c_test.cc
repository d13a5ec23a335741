// The gen3c export read back as GEN3C's dynamic-video inference reads it
// (docs/reference/trainer-formats.md §1): rgb.mp4, depth.npz['depth'],
// mask.npz['mask'], camera.npz['w2c', 'intrinsics'] at 704x1280, 121 frames;
// and its numbers against our pair and the synthetic world's exact ray
// casting: the poses are ours inverted, the intrinsics ours at 1280x704, and
// a point of the world projected with the exported camera lands on a pixel
// whose exported depth is its camera z.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "dataset/build_dataset.h"
#include "dataset/drive_dataset.h"
#include "dataset/exporter.h"
#include "dataset/pairs.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "dataset/synthetic/synthetic_world.h"
#include "geometry/npz.h"
#include "geometry/util/status.h"
#include "render/video/video_io.h"
#include "tests/common/test_util.h"
#include "tests/dataset/export_gen3c_fixture.h"

namespace geodrive {
namespace export_gen3c_test {

namespace fs = std::filesystem;

using export_gen3c_fixture::ClipDir;
using export_gen3c_fixture::Export;
using export_gen3c_fixture::kClip;
using export_gen3c_fixture::kFrames;
using export_gen3c_fixture::kHeight;
using export_gen3c_fixture::kWidth;
using export_gen3c_fixture::LoadClip;
using export_gen3c_fixture::Options;
using export_gen3c_fixture::WorldOptions;

// Another length is refused naming 120 N + 1, per clip and up front.
TEST(ExportGen3c, OtherLengthsAreRefusedNamingTheRequirement) {
  EXPECT_EQ(ParseExportFormat("gen3c"), ExportFormat::kGen3c);
  const auto exporter = CreateExporter(ExportFormat::kGen3c);
  EXPECT_NO_THROW(CheckClipForExport(*exporter, "c", 121));
  EXPECT_NO_THROW(CheckClipForExport(*exporter, "c", 241));
  for (const int n : {41, 120, 122, 240}) {
    EXPECT_THROW(CheckClipForExport(*exporter, "c", n), InputError) << n;
  }
  try {
    CheckClipForExport(*exporter, "scene-0916_0000", 41);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(),
                 "scene-0916_0000: gen3c needs 121, 241, ... frames (120 N + "
                 "1); this clip has 41");
  }
  BuildDatasetOptions o = Options("/tmp/unused");
  o.clip_frames = 25;
  try {
    o.Check();
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "gen3c needs 121, 241, ... frames (120 N + 1) per clip; "
                  "--clip-frames is 25"),
              std::string::npos)
        << e.what();
  }
}

// The Python mirror of the loader (cv2 and NumPy,
// tests/dataset/gen3c_loader_check.py): keys, dtypes, shapes, 121 frames,
// depth within the loader's clamp, mask = depth > 0.
TEST(ExportGen3c, PythonMirrorOfTheLoaderAcceptsIt) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("cv2");
  GEODRIVE_REQUIRE_PYTHON_MODULE("numpy");
  std::string log;
  EXPECT_EQ(test::RunCommand(std::string(test::kDebianPython) +
                                 " " GEODRIVE_SOURCE_DIR
                                 "/tests/dataset/gen3c_loader_check.py " +
                                 ClipDir() + " " + std::to_string(kFrames),
                             &log),
            0)
      << log;
  std::printf("%s", log.c_str());
  const std::string batch = test::ReadFile(Export() + "/gen3c/batch.jsonl");
  EXPECT_NE(batch.find(std::string("/gen3c/") + kClip + "\""),
            std::string::npos)
      << batch;
}

// w2c[t] = inverse of the pair's world_from_cam[t] (float32: to 1e-6
// relative), intrinsics = the source camera centre-cropped and scaled to
// 1280x704, every frame.
TEST(ExportGen3c, CamerasAreOursInvertedAndAtTheExportSize) {
  const NpzReader npz(ClipDir() + "/camera.npz");
  const NpyArray w2c = npz.Read("w2c");
  const NpyArray k = npz.Read("intrinsics");
  ASSERT_EQ(w2c.dtype, NpyDtype::kFloat32);
  ASSERT_EQ(k.dtype, NpyDtype::kFloat32);
  ASSERT_EQ(w2c.shape, (std::vector<int64_t>{kFrames, 4, 4}));
  ASSERT_EQ(k.shape, (std::vector<int64_t>{kFrames, 3, 3}));
  const PairMeta meta = ReadPairMeta(Export() + "/pairs/" + kClip);
  ASSERT_EQ(meta.world_from_cam.size(), static_cast<size_t>(kFrames));
  const DriveClip clip = LoadClip();
  const PinholeCamera& full = clip.frames.front().camera;
  const Eigen::Matrix3d want_k =
      ApplyResizeSpec(full, ComputeResizeSpec(full.width, full.height, kWidth,
                                              kHeight, ResizeMode::kCenterCrop))
          .K();
  double worst = 0;
  for (int t = 0; t < kFrames; ++t) {
    const Eigen::Matrix4d want = meta.world_from_cam[t].Inverse().ToMatrix();
    for (int i = 0; i < 16; ++i) {
      const double got = w2c.Data<float>()[t * 16 + i];
      const double w = want(i / 4, i % 4);
      worst = std::max(worst, std::abs(got - w) / std::max(1.0, std::abs(w)));
    }
    for (int i = 0; i < 9; ++i) {
      const double got = k.Data<float>()[t * 9 + i];
      EXPECT_NEAR(got, want_k(i / 3, i % 3),
                  1e-6 * std::max(1.0, std::abs(want_k(i / 3, i % 3))))
          << t << " " << i;
    }
  }
  std::printf("w2c vs our poses: worst relative difference %.2e\n", worst);
  EXPECT_LT(worst, 1e-6);
}

// Points of the synthetic world (the exact ray cast through sampled pixels of
// frames 0, 60, 120, moved into the export's frame = the pair's camera 0)
// projected with the exported K and w2c: they land on their pixel (0.01 px)
// at their camera z (1e-4 relative), and the exported depth there equals
// that z: median relative error < 1 %, 85 % within 3 % (the depth is the
// rendered point cloud's, not the ray cast's).
TEST(ExportGen3c, WorldPointsProjectWhereTheExportedDepthSays) {
  const NpzReader cam_npz(ClipDir() + "/camera.npz");
  const NpyArray w2c = cam_npz.Read("w2c");
  const NpyArray k = cam_npz.Read("intrinsics");
  const NpyArray depth = NpzReader(ClipDir() + "/depth.npz").Read("depth");
  ASSERT_EQ(depth.dtype, NpyDtype::kFloat32);
  ASSERT_EQ(depth.shape, (std::vector<int64_t>{kFrames, kHeight, kWidth}));
  const DriveClip clip = LoadClip();
  ASSERT_EQ(clip.num_frames(), kFrames);
  const SyntheticWorld world(SyntheticWorldOptionsFor(WorldOptions(), 0));
  const SyntheticTimeline tl = MakeSyntheticTimeline(WorldOptions(), 0);
  const PinholeCamera& full = clip.frames.front().camera;
  const PinholeCamera cam = ApplyResizeSpec(
      full, ComputeResizeSpec(full.width, full.height, kWidth, kHeight,
                              ResizeMode::kCenterCrop));
  const Rigid3d export_from_world =
      clip.frames.front().world_from_cam.Inverse();
  std::vector<double> rel;
  for (const int t : {0, 60, 120}) {
    Eigen::Matrix4d e_w2c;
    Eigen::Matrix3d e_k;
    for (int i = 0; i < 16; ++i)
      e_w2c(i / 4, i % 4) = w2c.Data<float>()[t * 16 + i];
    for (int i = 0; i < 9; ++i) e_k(i / 3, i % 3) = k.Data<float>()[t * 9 + i];
    const Rigid3d& pose = clip.frames[t].world_from_cam;
    const float* d = depth.Data<float>() + int64_t{t} * kHeight * kWidth;
    for (int y = 3; y < kHeight; y += 11) {
      for (int x = 5; x < kWidth; x += 13) {
        const Eigen::Vector2d px(x, y);
        const double z = world.CameraDepthAt(
            cam, pose, tl.Seconds(clip.frames[t].timestamp_us), px);
        if (!(z > 0) || z > 100) continue;  // sky, beyond GEN3C's clamp
        const Eigen::Vector3d ray((x - cam.cx) / cam.fx, (y - cam.cy) / cam.fy,
                                  1);
        const Eigen::Vector3d point = export_from_world * (pose * (z * ray));
        const Eigen::Vector3d c =
            (e_w2c * point.homogeneous()).head<3>();  // camera coordinates
        const Eigen::Vector3d p = e_k * c;
        ASSERT_NEAR(p.x() / p.z(), x, 0.01) << t;
        ASSERT_NEAR(p.y() / p.z(), y, 0.01) << t;
        ASSERT_NEAR(c.z(), z, 1e-4 * z) << t;
        const int u = static_cast<int>(std::lround(p.x() / p.z()));
        const int v = static_cast<int>(std::lround(p.y() / p.z()));
        const float got = d[int64_t{v} * kWidth + u];
        if (got > 0) rel.push_back(std::abs(got - c.z()) / c.z());
      }
    }
  }
  ASSERT_GT(rel.size(), 1000u);
  std::sort(rel.begin(), rel.end());
  const double median = rel[rel.size() / 2];
  const double within =
      static_cast<double>(std::lower_bound(rel.begin(), rel.end(), 0.03) -
                          rel.begin()) /
      rel.size();
  std::printf(
      "%zu world points: exported depth vs camera z, median %.3f %%, %.1f %% "
      "within 3 %%\n",
      rel.size(), 100 * median, 100 * within);
  EXPECT_LT(median, 0.01);
  EXPECT_GT(within, 0.85);
}

// `geodrive export --format gen3c` on a pair built without its gen3c files
// writes the same bytes as build-dataset --export gen3c. The pair is the
// fixture's, copied without its gen3c folder and with gen3c taken out of its
// meta.json: export re-renders from the dataset and the pair's options, so
// the pair's own files are not among its inputs (one build, not two).
TEST(ExportGen3c, ExportingBuiltPairsGivesTheSameFiles) {
  const std::string out = test::MakeTempDir("export_gen3c_later");
  const std::string pair = out + "/pairs/" + kClip;
  fs::create_directories(pair);
  fs::copy_file(Export() + "/manifest.jsonl", out + "/manifest.jsonl");
  for (const auto& e : fs::directory_iterator(Export() + "/pairs/" + kClip)) {
    if (e.path().filename() == "gen3c") continue;
    fs::copy(e.path(), pair + "/" + e.path().filename().string(),
             fs::copy_options::recursive);
  }
  const std::string meta_text = test::ReadFile(pair + "/meta.json");
  const std::string entry = "\"gen3c\": \"gen3c\"";
  const size_t at = meta_text.find(entry);
  ASSERT_NE(at, std::string::npos) << meta_text;
  std::string without = meta_text;
  without.replace(at, entry.size(), "\"gen3c_removed\": \"gen3c\"");
  test::WriteFile(pair + "/meta.json", without);
  ASSERT_EQ(ReadPairMeta(pair).files.count("gen3c"), 0u);
  ASSERT_FALSE(fs::exists(pair + "/gen3c"));
  EXPECT_EQ(
      ExportPairs(out, {ExportFormat::kGen3c}, Options(out).export_options,
                  /*quiet=*/true),
      1);
  for (const char* name : {"rgb.mp4", "depth.npz", "mask.npz", "camera.npz"}) {
    const std::string got =
        test::ReadFile(out + "/gen3c/" + kClip + "/" + name);
    EXPECT_GT(got.size(), 0u) << name;
    EXPECT_TRUE(got == test::ReadFile(ClipDir() + "/" + name)) << name;
  }
  EXPECT_EQ(ReadPairMeta(pair).files.at("gen3c"), "gen3c");
}

// The real scene-0916 as keyframes (41, the whole scene: no 121-frame clip)
// is refused with the error naming 120 N + 1: up front for --clip-frames 41,
// and per clip for its 41-frame clip.
TEST(ExportGen3c, RealScene0916KeyframeClipIsRefused) {
  const std::string root = test::RealDataPath("nuscenes_scene0916");
  ASSERT_TRUE(fs::is_directory(root)) << "real data missing: " << root;
  BuildDatasetOptions o;
  o.dataroot = root;
  o.version = "v1.0-mini-extract";
  o.frames = ClipFrameSource::kKeyframes;
  o.geometry = "lidar";
  o.out = test::MakeTempDir("export_gen3c_real");
  o.quiet = true;
  o.clip_frames = 41;
  o.exports = {ExportFormat::kGen3c};
  try {
    o.Check();
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "--export gen3c needs 121, 241, ... frames (120 N + 1) per "
                  "clip; --clip-frames is 41"),
              std::string::npos)
        << e.what();
  }
  DriveDatasetOptions dopt;
  dopt.root = root;
  dopt.version = o.version;
  dopt.frames = ClipFrameSource::kKeyframes;
  dopt.clip_frames = 41;
  const std::unique_ptr<DriveDataset> dataset = OpenDriveDataset(dopt);
  ASSERT_EQ(dataset->ClipIds().size(), 1u);
  const DriveClip clip = dataset->LoadClip(dataset->ClipIds().front());
  ASSERT_EQ(clip.num_frames(), 41);
  try {
    CheckClipForExport(*CreateExporter(ExportFormat::kGen3c), clip.id,
                       clip.num_frames());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              clip.id +
                  ": gen3c needs 121, 241, ... frames (120 N + 1); this clip "
                  "has 41");
  }
}

// Built at GEN3C's own size and framing (704x1280, centre crop), the pair's
// render serves the export and rgb.mp4 is the pair's gt.mp4 (a hard link: the
// same frames at the same preset and CRF, not encoded twice), 121 frames at
// 1280x704 as the loader reads them (cv2.VideoCapture, which the other tests'
// mirror runs on the default-size export); the exported mask covers what the
// pair's condition covers.
TEST(ExportGen3cAtItsSize, RgbVideoIsThePairsOwn) {
  const std::string out = test::MakeTempDir("export_gen3c_own_size");
  BuildDatasetOptions o = Options(out);
  o.width = kWidth;
  o.height = kHeight;
  o.resize_mode = ResizeMode::kCenterCrop;
  const BuildDatasetSummary s = BuildDataset(o);
  ASSERT_EQ(s.built, 1) << test::ReadFile(out + "/failures.jsonl");
  const std::string pair = out + "/pairs/" + kClip;
  const std::string rgb = pair + "/gen3c/rgb.mp4";
  EXPECT_TRUE(fs::equivalent(rgb, pair + "/gt.mp4"));
  EXPECT_EQ(fs::hard_link_count(rgb), 2u);
  VideoFrameStream video(rgb);
  cv::Mat frame;
  int frames = 0;
  while (video.Next(&frame)) {
    ASSERT_EQ(frame.size(), cv::Size(kWidth, kHeight)) << "frame " << frames;
    ++frames;
  }
  EXPECT_EQ(frames, kFrames);
  const PairMeta meta = ReadPairMeta(pair);
  const NpyArray mask = NpzReader(pair + "/gen3c/mask.npz").Read("mask");
  ASSERT_EQ(mask.shape, (std::vector<int64_t>{kFrames, kHeight, kWidth}));
  const int64_t n = int64_t{kWidth} * kHeight;
  for (int t : {0, kFrames / 2, kFrames - 1}) {
    const uint8_t* m = mask.Data<uint8_t>() + t * n;
    const double drawn = static_cast<double>(std::count(m, m + n, 1)) / n;
    std::printf("frame %d: mask %.6f, pair coverage %.6f\n", t, drawn,
                meta.quality.coverage[t]);
    EXPECT_NEAR(drawn, meta.quality.coverage[t], 1e-6) << "frame " << t;
  }
}

}  // namespace export_gen3c_test
}  // namespace geodrive

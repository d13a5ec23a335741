// The streetcrafter export read back as StreetCrafter's video trainer reads it
// (docs/reference/trainer-formats.md §2): meta_info_{train,val}.json lists of
// 25-path samples relative to the data root, every file present, frames and
// guidances at 576x320, the LiDAR depth npz {mask bool (H,W), value float32
// 1-D of length mask.sum()}; and its numbers against the synthetic world's
// exact ray casting: the depth the npz gives at a pixel is the z-depth of the
// surface seen through that pixel.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <set>

#include "dataset/build_dataset.h"
#include "dataset/drive_dataset.h"
#include "dataset/exporter.h"
#include "dataset/pairs.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "dataset/synthetic/synthetic_world.h"
#include "geometry/image_io.h"
#include "geometry/npz.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace export_streetcrafter_test {

namespace fs = std::filesystem;

// Two scenes (a by-scene split has something to split), 800x450, 4.5 s.
const SyntheticDatasetOptions& WorldOptions() {
  static const SyntheticDatasetOptions o = [] {
    SyntheticDatasetOptions w;
    w.num_scenes = 2;
    w.seed = 31;
    w.image_width = 800;
    w.image_height = 450;
    w.scene_duration_s = 4.5;
    return w;
  }();
  return o;
}

const std::string& World() {
  static const std::string root =
      test::SharedFixtureDir("export_sc_world", [](const std::string& dir) {
        WriteSyntheticDataset(WorldOptions(), dir);
      });
  return root;
}

const std::vector<std::string>& Clips() {
  static const std::vector<std::string> clips = {"scene-0001_0000",
                                                 "scene-0002_0006"};
  return clips;
}

BuildDatasetOptions Options(const std::string& out) {
  BuildDatasetOptions o;
  o.dataroot = World();
  o.geometry = "lidar";
  o.out = out;
  o.quiet = true;
  o.clips = Clips();
  o.exports = {ExportFormat::kStreetCrafter};
  o.export_options.val_fraction = 0.5;
  return o;
}

const std::string& Export() {
  static const std::string out =
      test::SharedFixtureDir("export_sc_out", [](const std::string& dir) {
        const BuildDatasetSummary s = BuildDataset(Options(dir));
        std::printf("streetcrafter export: %s\n", s.BriefReport().c_str());
        EXPECT_EQ(s.built, 2) << test::ReadFile(dir + "/failures.jsonl");
      });
  return out;
}

nlohmann::json ReadJson(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  return nlohmann::json::parse(in);
}

TEST(ExportStreetCrafter, FormatNamesParseAndRefuseUnknownOnes) {
  EXPECT_EQ(ParseExportFormats("streetcrafter,geodrive-upstream"),
            (std::vector<ExportFormat>{ExportFormat::kGeodriveUpstream,
                                       ExportFormat::kStreetCrafter}));
  EXPECT_TRUE(ParseExportFormats("none").empty());
  EXPECT_EQ(ToString(ParseExportFormats("streetcrafter,streetcrafter")),
            "streetcrafter");
  EXPECT_THROW(ParseExportFormats("streetcrafter,gen4c"), InputError);
}

// A clip shorter than a sample is refused with one error naming the
// requirement (the trainer's sampler would skip it silently).
TEST(ExportStreetCrafter, ShortClipsAreRefusedNamingTheRequirement) {
  const auto exporter = CreateExporter(ExportFormat::kStreetCrafter);
  EXPECT_NO_THROW(CheckClipForExport(*exporter, "c", 25));
  try {
    CheckClipForExport(*exporter, "scene-0916_0000", 24);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(),
                 "scene-0916_0000: streetcrafter needs 25 frames; this clip "
                 "has 24");
  }
  BuildDatasetOptions o = Options("/tmp/unused");
  o.clip_frames = 20;
  try {
    o.Check();
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("streetcrafter needs 25 frames per "
                                         "clip; --clip-frames is 20"),
              std::string::npos)
        << e.what();
  }
  o.clip_frames = 25;
  o.preset = RenderPreset::kGeodriveCompat;
  EXPECT_THROW(o.Check(), InputError);
}

// The loader's view: json lists, 25 paths each relative to the root, files
// present, frame and guidance of one index at the target size, black where
// the mask says nothing was drawn; the split by scene.
TEST(ExportStreetCrafter, MetaInfoReadsBackAsTheLoaderReadsIt) {
  const std::string root = Export() + "/streetcrafter";
  std::map<std::string, std::set<std::string>> scenes_by_split;
  int samples = 0;
  for (const std::string split : {"train", "val"}) {
    const nlohmann::json list =
        ReadJson(root + "/meta_info_" + split + ".json");
    ASSERT_TRUE(list.is_array());
    for (const nlohmann::json& s : list) {
      ++samples;
      for (const char* key : {"frames", "guidances", "guidances_mask"}) {
        ASSERT_EQ(s.at(key).size(), 25u) << key;
        for (const auto& p : s.at(key))
          ASSERT_TRUE(fs::is_regular_file(root + "/" + p.get<std::string>()))
              << p;
      }
      const std::string first = s["frames"][0].get<std::string>();
      scenes_by_split[split].insert(first.substr(0, first.find('_')));
      for (int i : {0, 12, 24}) {
        const cv::Mat frame =
            ReadImageRgb(root + "/" + s["frames"][i].get<std::string>());
        const cv::Mat guidance =
            ReadImageRgb(root + "/" + s["guidances"][i].get<std::string>());
        const cv::Mat mask = ReadImageGray(
            root + "/" + s["guidances_mask"][i].get<std::string>());
        EXPECT_EQ(frame.size(), cv::Size(576, 320));
        EXPECT_EQ(guidance.size(), frame.size());
        ASSERT_EQ(mask.size(), frame.size());
        cv::Mat lit;
        cv::cvtColor(guidance, lit, cv::COLOR_RGB2GRAY);
        EXPECT_EQ(cv::countNonZero(lit & (mask == 0)), 0);
        EXPECT_GT(cv::countNonZero(mask), 0.2 * mask.total());
      }
    }
  }
  EXPECT_EQ(samples, 2);  // one 25-frame window per clip
  // val_fraction 0.5 of two scenes: one each, never the same scene in both.
  EXPECT_EQ(scenes_by_split["train"].size(), 1u);
  EXPECT_EQ(scenes_by_split["val"].size(), 1u);
  EXPECT_NE(scenes_by_split["train"], scenes_by_split["val"]);
}

// depth[mask] = value (waymo_readers.py:126-134) against the ray cast of the
// synthetic world through the same pixel, at the export size, with the
// dataset's own camera pose of that frame.
TEST(ExportStreetCrafter, DepthNpzIsTheTrueZDepthAtItsPixels) {
  const std::string out = Export();
  DriveDatasetOptions dopt;
  dopt.root = World();
  const std::unique_ptr<DriveDataset> dataset = OpenDriveDataset(dopt);
  for (int scene = 0; scene < 2; ++scene) {
    const std::string clip_id = Clips()[scene];
    const DriveClip clip = dataset->LoadClip(clip_id);
    const SyntheticWorld world(SyntheticWorldOptionsFor(WorldOptions(), scene));
    const SyntheticTimeline tl = MakeSyntheticTimeline(WorldOptions(), scene);
    const PinholeCamera& full = clip.frames.front().camera;
    const PinholeCamera cam =
        ApplyResizeSpec(full, ComputeResizeSpec(full.width, full.height, 576,
                                                320, ResizeMode::kCenterCrop));
    std::vector<double> rel;
    for (int t : {0, 12, 24}) {
      char name[32];
      std::snprintf(name, sizeof(name), "%06d_0.npz", t);
      const NpzReader npz(out + "/streetcrafter/" + clip_id + "/lidar/depth/" +
                          name);
      const NpyArray mask = npz.Read("mask");
      const NpyArray value = npz.Read("value");
      ASSERT_EQ(mask.dtype, NpyDtype::kBool);
      ASSERT_EQ(mask.shape, (std::vector<int64_t>{320, 576}));
      ASSERT_EQ(value.dtype, NpyDtype::kFloat32);
      ASSERT_EQ(value.shape.size(), 1u);
      const uint8_t* m = mask.Data<uint8_t>();
      const float* v = value.Data<float>();
      const int64_t count = std::count(m, m + mask.NumElements(), 1);
      ASSERT_EQ(count, value.shape[0]);
      int64_t k = 0;
      for (int64_t p = 0; p < mask.NumElements(); ++p) {
        if (!m[p]) continue;
        const float d = v[k++];
        ASSERT_TRUE(d >= 0.1f && d <= 100.0f) << d;
        if (k % 7) continue;  // a sample of the pixels
        const Eigen::Vector2d px(p % 576, p / 576);
        const double truth =
            world.CameraDepthAt(cam, clip.frames[t].world_from_cam,
                                tl.Seconds(clip.frames[t].timestamp_us), px);
        if (truth <= 0 || truth > 100) continue;  // sky, beyond the clip
        rel.push_back(std::abs(d - truth) / truth);
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
        "%s: %zu depth pixels, median |error| %.3f %% of depth, %.1f %% "
        "within 3 %%\n",
        clip_id.c_str(), rel.size(), 100 * median, 100 * within);
    EXPECT_LT(median, 0.01);
    EXPECT_GT(within, 0.85);
  }
}

// The same files through Python, PIL and NumPy, the way the trainer's
// dataset class and the 3DGS reader open them
// (tests/dataset/streetcrafter_loader_check.py).
TEST(ExportStreetCrafter, PythonMirrorOfTheLoaderAcceptsIt) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("PIL");
  GEODRIVE_REQUIRE_PYTHON_MODULE("numpy");
  std::string log;
  EXPECT_EQ(
      test::RunCommand(std::string(test::kDebianPython) +
                           " " GEODRIVE_SOURCE_DIR
                           "/tests/dataset/streetcrafter_loader_check.py " +
                           Export() + "/streetcrafter 2",
                       &log),
      0)
      << log;
  std::printf("%s", log.c_str());
}

// Shards then --merge give the same lists as one run, when the merge is
// given the shards' split options.
TEST(ExportStreetCrafter, ShardsAndMergeGiveTheSameLists) {
  const std::string out = test::MakeTempDir("export_sc_shards");
  for (int i = 0; i < 2; ++i) {
    BuildDatasetOptions o = Options(out);
    o.shard_index = i;
    o.shard_count = 2;
    const BuildDatasetSummary s = BuildDataset(o);
    EXPECT_EQ(s.failed, 0);
  }
  EXPECT_FALSE(fs::exists(out + "/streetcrafter"));
  MergeBuildOutputs(out, Options(out).export_options);
  for (const std::string split : {"train", "val"}) {
    const std::string name = "/streetcrafter/meta_info_" + split + ".json";
    EXPECT_EQ(test::ReadFile(out + name), test::ReadFile(Export() + name))
        << split;
  }
}

// Every file under DIR (symlinks followed), by path relative to DIR.
std::map<std::string, std::string> FilesUnder(const std::string& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(
           dir, fs::directory_options::follow_directory_symlink)) {
    if (e.is_regular_file())
      files[fs::relative(e.path(), dir).string()] =
          test::ReadFile(e.path().string());
  }
  return files;
}

// `geodrive export` on pairs built without --export writes the same bytes
// as build-dataset --export: the files of every pair and the lists.
TEST(ExportStreetCrafter, ExportingBuiltPairsGivesTheSameFiles) {
  const std::string out = test::MakeTempDir("export_sc_later");
  BuildDatasetOptions o = Options(out);
  o.exports.clear();
  ASSERT_EQ(BuildDataset(o).built, 2);
  ASSERT_FALSE(fs::exists(out + "/pairs/" + Clips()[0] + "/streetcrafter"));
  const std::string meta_path = out + "/pairs/" + Clips()[0] + "/meta.json";
  nlohmann::json before = ReadJson(meta_path);
  EXPECT_EQ(ExportPairs(out, {ExportFormat::kStreetCrafter},
                        Options(out).export_options, /*quiet=*/true),
            2);
  const auto got = FilesUnder(out + "/streetcrafter");
  const auto want = FilesUnder(Export() + "/streetcrafter");
  EXPECT_EQ(got.size(), want.size());
  EXPECT_GT(got.size(), 2u * 25 * 4);
  for (const auto& [rel, bytes] : want) {
    const auto it = got.find(rel);
    ASSERT_NE(it, got.end()) << rel;
    EXPECT_TRUE(it->second == bytes) << rel;
  }
  // The pair's meta.json is as it was (poses to the bit) but for its files.
  nlohmann::json after = ReadJson(meta_path);
  EXPECT_EQ(after["files"]["streetcrafter"], "streetcrafter");
  before.erase("files");
  after.erase("files");
  EXPECT_EQ(before, after);
  // The pair records its new folder.
  EXPECT_EQ(
      ReadPairMeta(out + "/pairs/" + Clips()[0]).files.at("streetcrafter"),
      "streetcrafter");
}

// The real scene-0916 (keyframes: three 25-frame clips, LiDAR geometry)
// exports and reads back through the Python mirror of the loader.
TEST(ExportStreetCrafter, RealScene0916ExportsAndReadsBack) {
  const std::string root = test::RealDataPath("nuscenes_scene0916");
  ASSERT_TRUE(fs::is_directory(root)) << "real data missing: " << root;
  GEODRIVE_REQUIRE_PYTHON_MODULE("PIL");
  GEODRIVE_REQUIRE_PYTHON_MODULE("numpy");
  const std::string out = test::MakeTempDir("export_sc_real");
  BuildDatasetOptions o;
  o.dataroot = root;
  o.version = "v1.0-mini-extract";
  o.frames = ClipFrameSource::kKeyframes;
  o.geometry = "lidar";
  o.out = out;
  o.quiet = true;
  o.exports = {ExportFormat::kStreetCrafter};
  const BuildDatasetSummary s = BuildDataset(o);
  ASSERT_EQ(s.built, 3) << test::ReadFile(out + "/failures.jsonl");
  std::string log;
  EXPECT_EQ(
      test::RunCommand(std::string(test::kDebianPython) +
                           " " GEODRIVE_SOURCE_DIR
                           "/tests/dataset/streetcrafter_loader_check.py " +
                           out + "/streetcrafter 3",
                       &log),
      0)
      << log;
  std::printf("%s", log.c_str());
}

}  // namespace export_streetcrafter_test
}  // namespace geodrive

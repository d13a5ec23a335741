#include "dataset/pairs.h"
#include "geometry/util/hash.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <thread>
#include <utility>
#include <vector>

#include "geometry/util/files.h"
#include "geometry/util/progress.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

PairMeta SampleMeta() {
  PairMeta m;
  m.clip_id = "scene-0001_0006";
  m.scene_name = "scene-0001";
  m.scene_token = "0123456789abcdef0123456789abcdef";
  for (int i = 0; i < 3; ++i) {
    m.frames.push_back({"tok" + std::to_string(i), 1000000 + 83333 * i,
                        "samples/CAM_FRONT/x" + std::to_string(i) + ".jpg"});
    m.world_from_cam.push_back(
        Rigid3d(QuaternionFromAngleAxis(Eigen::Vector3d(0, 0.01 * i, 0)), Eigen::Vector3d(0, 0, i)));
  }
  m.intrinsics = PinholeCamera(569.9, 675.4, 367.1, 262.2, 720, 480);
  m.resize_mode = "resize";
  m.pose_units = "metres";
  m.scale = 12.5;
  m.scale_source = "lidar";
  m.geometry_source = "monst3r";
  m.preset = "paper";
  m.edit_mode = "3d";
  m.options_json = R"({"threads":1,"size":"480x720"})";
  m.options_hash = StableHash64(m.options_json);
  m.tool_version = "0.1.0";
  m.quality.coverage = {1.0, 0.9, 0.8};
  m.files = {{"gt", "gt.mp4"}, {"cond", "cond.mp4"}};
  return m;
}

TEST(Pairs, MetaRoundTrip) {
  const PairMeta m = SampleMeta();
  const PairMeta back = PairMetaFromJson(PairMetaToJson(m));
  EXPECT_EQ(back.clip_id, m.clip_id);
  ASSERT_EQ(back.frames.size(), 3u);
  EXPECT_EQ(back.frames[2].timestamp_us, m.frames[2].timestamp_us);
  EXPECT_NEAR(back.intrinsics.fy, 675.4, 1e-12);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_LT((back.world_from_cam[i].ToMatrix() - m.world_from_cam[i].ToMatrix()).norm(), 1e-12);
  }
  EXPECT_EQ(back.quality.coverage, m.quality.coverage);
  EXPECT_EQ(back.files.at("cond"), "cond.mp4");
  EXPECT_EQ(PairMetaToJson(back), PairMetaToJson(m));  // stable serialisation
}

TEST(Pairs, MetaAndManifestValidateAgainstSchemas) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("jsonschema");
  const std::string dir = test::MakeTempDir("pairs_schema");
  WriteFileAtomic(dir + "/meta.json", PairMetaToJson(SampleMeta()));
  ManifestEntry e{"scene-0001_0006", "pairs/scene-0001_0006", "scene-0001", 25, "monst3r",
                  "metres", 0.87, StableHash64("x")};
  WriteFileAtomic(dir + "/manifest.jsonl", ManifestEntryToJson(e) + "\n");
  const std::string py = std::string(test::kDebianPython) + " " GEODRIVE_SOURCE_DIR
                         "/tests/dataset/validate_json.py ";
  std::string out;
  EXPECT_EQ(test::RunCommand(py + GEODRIVE_SOURCE_DIR "/data_schema/pair_meta.schema.json " + dir +
                                 "/meta.json",
                             &out),
            0)
      << out;
  EXPECT_EQ(test::RunCommand(py + "--jsonl " GEODRIVE_SOURCE_DIR
                                  "/data_schema/manifest_line.schema.json " +
                                 dir + "/manifest.jsonl",
                             &out),
            0)
      << out;
  // The validator is real: a broken document fails.
  WriteFileAtomic(dir + "/bad.jsonl", R"({"clip_id": "x"})" "\n");
  EXPECT_NE(test::RunCommand(py + "--jsonl " GEODRIVE_SOURCE_DIR
                                  "/data_schema/manifest_line.schema.json " +
                                 dir + "/bad.jsonl",
                             &out),
            0);
}

// A surround-view pair's meta.json (views, seams, the per-camera files) and
// manifest line (cameras, lidar-dense), as build-dataset --cameras writes
// them, validate against the schemas and read back.
TEST(Pairs, SurroundViewMetaAndManifestValidateAgainstSchemas) {
  PairMeta m = SampleMeta();
  m.geometry_source = "lidar-dense";
  m.quality.psnr_static = {31.5, std::nullopt, 20.25};
  for (const std::string cam : {"CAM_FRONT", "CAM_BACK"}) {
    PairView v;
    v.channel = cam;
    v.frames = m.frames;
    v.intrinsics = m.intrinsics;
    v.world_from_cam = m.world_from_cam;
    v.coverage = {0.75, 0.5, 0.25};
    v.psnr_static = {std::nullopt, 22.0, 21.0};
    if (cam == "CAM_BACK") v.supported_fraction = 0.5;
    v.points_built = 1000;
    v.points_kept = 900;
    v.files = {{"gt", "gt_" + cam + ".mp4"},
               {"cond", "cond_" + cam + ".mp4"},
               {"boxes", "boxes_" + cam + ".json"}};
    for (const auto& [role, name] : v.files) m.files[role + ":" + cam] = name;
    m.views.push_back(v);
  }
  m.seams.push_back({"CAM_FRONT", "CAM_BACK", 120, 0.875});
  const std::string text = PairMetaToJson(m);
  const PairMeta back = PairMetaFromJson(text);
  ASSERT_EQ(back.views.size(), 2u);
  EXPECT_EQ(back.views[1].channel, "CAM_BACK");
  EXPECT_EQ(back.views[0].psnr_static[0], std::nullopt);
  ASSERT_EQ(back.seams.size(), 1u);
  EXPECT_EQ(back.seams[0].overlap_pixels, 120);
  EXPECT_EQ(PairMetaToJson(back), text);

  GEODRIVE_REQUIRE_PYTHON_MODULE("jsonschema");
  const std::string dir = test::MakeTempDir("pairs_rig_schema");
  WriteFileAtomic(dir + "/meta.json", text);
  ManifestEntry e{m.clip_id, "pairs/" + m.clip_id, m.scene_name,
                  3,         "lidar-dense",        "metres",
                  0.5,       m.options_hash,       {"CAM_FRONT", "CAM_BACK"}};
  WriteFileAtomic(dir + "/manifest.jsonl", ManifestEntryToJson(e) + "\n");
  EXPECT_EQ(ReadManifest(dir + "/manifest.jsonl").at(0).cameras, e.cameras);
  const std::string py = std::string(test::kDebianPython) +
                         " " GEODRIVE_SOURCE_DIR
                         "/tests/dataset/validate_json.py ";
  const std::string schemas = GEODRIVE_SOURCE_DIR "/data_schema/";
  std::string out;
  EXPECT_EQ(
      test::RunCommand(
          py + schemas + "pair_meta.schema.json " + dir + "/meta.json", &out),
      0)
      << out;
  EXPECT_EQ(test::RunCommand(py + "--jsonl " + schemas +
                                 "manifest_line.schema.json " + dir +
                                 "/manifest.jsonl",
                             &out),
            0)
      << out;
  // A view without its condition video is refused by the schema.
  std::string bad = text;
  const size_t at = bad.find("\"cond\": \"cond_CAM_BACK.mp4\"");
  ASSERT_NE(at, std::string::npos);
  bad.replace(at, 6, "\"cnd\"");
  WriteFileAtomic(dir + "/bad.json", bad);
  EXPECT_NE(
      test::RunCommand(
          py + schemas + "pair_meta.schema.json " + dir + "/bad.json", &out),
      0);
}

TEST(Pairs, ManifestAndFailuresRoundTripThroughAppender) {
  const std::string dir = test::MakeTempDir("pairs_manifest");
  {
    JsonlAppender manifest(dir + "/manifest.jsonl");
    JsonlAppender failures(dir + "/failures.jsonl");
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t) {
      threads.emplace_back([&, t] {
        for (int i = 0; i < 25; ++i) {
          const std::string id = "clip" + std::to_string(t * 100 + i);
          manifest.Append(ManifestEntryToJson({id, "pairs/" + id, "scene", 25, "lidar", "metres",
                                               0.5, StableHash64(id)}));
        }
      });
    }
    for (auto& th : threads) th.join();
    failures.Append(FailureEntryToJson({"clipX", "geometry", "frame_0003.npy: truncated"}));
  }
  const auto entries = ReadManifest(dir + "/manifest.jsonl");
  EXPECT_EQ(entries.size(), 100u);  // no torn or lost lines
  const auto fails = ReadFailures(dir + "/failures.jsonl");
  ASSERT_EQ(fails.size(), 1u);
  EXPECT_EQ(fails[0].stage, "geometry");
}

TEST(Pairs, BadInputNamesTheFile) {
  const std::string dir = test::MakeTempDir("pairs_bad");
  WriteFileAtomic(dir + "/manifest.jsonl", "{\"clip_id\": \"a\"\n");
  try {
    ReadManifest(dir + "/manifest.jsonl");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("manifest.jsonl:1"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ReadPairMeta(dir + "/missing"), InputError);
  EXPECT_THROW(PairMetaFromJson("{\"clip_id\": 3}", "m.json"), InputError);
}

// Integer fields are read in their own type and range: a value a cast would
// wrap or truncate (2^32 + 1 -> 1, 3.7 -> 3, -1 frames) is an error naming
// the field.
TEST(Pairs, IntegerFieldsAreRangeCheckedNotCoerced) {
  const std::string good = PairMetaToJson(SampleMeta());
  ASSERT_NO_THROW(PairMetaFromJson(good, "meta.json"));
  auto refused = [&](const std::string& from, const std::string& to,
                     const std::string& field) {
    std::string bad = good;
    const size_t at = bad.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    bad.replace(at, from.size(), to);
    try {
      PairMetaFromJson(bad, "meta.json");
      ADD_FAILURE() << to << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos)
          << e.what();
    }
  };
  refused("\"width\": 720", "\"width\": 4294967297", "intrinsics.width");
  refused("\"width\": 720", "\"width\": 720.5", "intrinsics.width");
  refused("\"height\": 480", "\"height\": -480", "intrinsics.height");
  refused("\"timestamp_us\": 1000000", "\"timestamp_us\": 18446744073709551615",
          "timestamp_us");
  refused("\"timestamp_us\": 1000000", "\"timestamp_us\": 1e6", "timestamp_us");

  const std::string dir = test::MakeTempDir("manifest_fields");
  ManifestEntry e;
  e.clip_id = "scene-0001_0000";
  e.pair_dir = "pairs/scene-0001_0000";
  e.num_frames = 25;
  const std::string line = ManifestEntryToJson(e);
  ASSERT_NO_THROW(ManifestEntryFromJson(line, "m"));
  for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
           {"\"num_frames\":25", "\"num_frames\":4294967321"},
           {"\"num_frames\":25", "\"num_frames\":0"},
           {"pairs/scene-0001_0000", "../../etc"},
           {"pairs/scene-0001_0000", "/abs/pair"},
           {"\"clip_id\":\"scene-0001_0000\"", "\"clip_id\":\"../x\""}}) {
    std::string bad = line;
    const size_t at = bad.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    bad.replace(at, from.size(), to);
    EXPECT_THROW(ManifestEntryFromJson(bad, dir + "/manifest.jsonl:1"),
                 InputError)
        << "accepted: " << bad;
  }
}

TEST(Job, CommitDirectoryIsAtomicAndRefusesOverwrite) {
  namespace fs = std::filesystem;
  const std::string dir = test::MakeTempDir("job_commit");
  fs::create_directories(dir + "/.tmp-a");
  WriteFileAtomic(dir + "/.tmp-a/x.txt", "hello");
  CommitDirectory(dir + "/.tmp-a", dir + "/a");
  EXPECT_TRUE(fs::exists(dir + "/a/x.txt"));
  EXPECT_FALSE(fs::exists(dir + "/.tmp-a"));
  fs::create_directories(dir + "/.tmp-b");
  EXPECT_THROW(CommitDirectory(dir + "/.tmp-b", dir + "/a"), InputError);
  EXPECT_EQ(StableHash64(""), "cbf29ce484222325");  // FNV-1a 64 offset basis
}

}  // namespace
}  // namespace geodrive

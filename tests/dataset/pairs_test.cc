#include "dataset/pairs.h"
#include "geometry/util/hash.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <thread>

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

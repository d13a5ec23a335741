// Parsers with unbounded cost (docs/RELIABILITY.md): the JSON depth limit
// (geometry/util/json_depth.h, kMaxJsonDepth) across every JSON reader --
// the nuScenes tables through both front ends, trajectory JSON, boxes.json,
// meta.json, manifest and clips.jsonl lines, safetensors headers -- and the
// safetensors header in linear time.

#include "geometry/util/json_depth.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <vector>

#include "dataset/internal/nuscenes_json.h"
#include "dataset/nuscenes.h"
#include "dataset/pairs.h"
#include "dataset/scene_folders.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "diffusion/format/safetensors_header.h"
#include "geometry/trajectory_json.h"
#include "geometry/util/status.h"
#include "render/boxes.h"
#include "tests/common/test_util.h"

namespace geodrive {
// A named namespace, not an anonymous one: the unity build compiles this
// file with others of its folder, whose anonymous helpers share names.
namespace json_depth_test {

namespace nj = nuscenes_json;

constexpr int kHostileDepth = 110000;

std::string Nested(int depth, const std::string& inner = "") {
  return std::string(depth, '[') + inner + std::string(depth, ']');
}
std::string NestedObjects(int depth) {
  std::string s;
  for (int i = 0; i < depth; ++i) s += "{\"a\":";
  s += "1";
  s += std::string(depth, '}');
  return s;
}

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
}

// The message of the InputError `read` throws ("" if it returns; any other
// exception fails the test).
std::string ErrorOf(const std::function<void()>& read) {
  try {
    read();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// A synthetic dataroot (tables only) and the restoring of its tables.
class DeepTables : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = new std::string(test::MakeTempDir("json_depth_nuscenes"));
    SyntheticDatasetOptions options;
    options.num_scenes = 1;
    options.scene_duration_s = 1.0;
    options.tables_only = true;
    WriteSyntheticDataset(options, *root_);
  }
  static void TearDownTestSuite() {
    delete root_;
    root_ = nullptr;
  }
  void TearDown() override {
    nj::SetFastFrontEndEnabled(true);
    nj::SetSliceBytes(nj::kDefaultSliceBytes);
  }
  std::string Table(const std::string& name) const {
    return *root_ + "/v1.0-mini/" + name + ".json";
  }
  // The load's error with the reference front end, then with the fast one
  // (1 and 2 threads: worker threads have smaller stacks).
  std::vector<std::string> Errors() const {
    NuscenesOptions options;
    options.dataroot = *root_;
    std::vector<std::string> errors;
    nj::SetFastFrontEndEnabled(false);
    options.num_threads = 1;
    errors.push_back(ErrorOf([&] { Nuscenes n(options); }));
    nj::SetFastFrontEndEnabled(true);
    for (int threads : {1, 2}) {
      options.num_threads = threads;
      errors.push_back(ErrorOf([&] { Nuscenes n(options); }));
    }
    return errors;
  }
  static std::string* root_;
};
std::string* DeepTables::root_ = nullptr;

// The category table with one more field `extra` in its first record.
std::string CategoryWithExtra(const std::string& original,
                              const std::string& extra) {
  const size_t open = original.find('{');
  return original.substr(0, open + 1) + "\"extra\": " + extra + ", " +
         original.substr(open + 1);
}

TEST_F(DeepTables, HostileNestingIsOneErrorNamingTheFileInBothFrontEnds) {
  const std::string path = Table("category");
  std::ifstream in(path, std::ios::binary);
  const std::string original(std::istreambuf_iterator<char>(in), {});
  const std::vector<std::string> tables = {
      // 110,000 arrays in a field (the stack overflow in the fast front
      // end's Skip), objects in a field, arrays in a matrix field's row,
      // and the whole table nested.
      CategoryWithExtra(original, Nested(kHostileDepth)),
      CategoryWithExtra(original, NestedObjects(kHostileDepth)),
      CategoryWithExtra(original, "[[1, " + Nested(kHostileDepth) + "]]"),
      Nested(kHostileDepth),
  };
  for (size_t i = 0; i < tables.size(); ++i) {
    WriteText(path, tables[i]);
    const std::vector<std::string> errors = Errors();
    for (const std::string& error : errors) {
      EXPECT_EQ(error.rfind(path + ": ", 0), 0u) << i << ": " << error;
      EXPECT_EQ(error, errors[0]) << i;
    }
    if (i < 3) {
      EXPECT_NE(errors[0].find("JSON nested more than 64 arrays/objects deep"),
                std::string::npos)
          << errors[0];
    }
  }
  WriteText(path, original);
  EXPECT_EQ(Errors(), std::vector<std::string>(3, ""));
}

TEST_F(DeepTables, TheLimitIsTheSameInBothFrontEnds) {
  const std::string path = Table("category");
  std::ifstream in(path, std::ios::binary);
  const std::string original(std::istreambuf_iterator<char>(in), {});
  // The table's array and the record are depths 1 and 2: a field nested
  // kMaxJsonDepth - 2 deep is the deepest legitimate file.
  for (int inner : {kMaxJsonDepth - 2, kMaxJsonDepth - 1}) {
    for (const std::string& extra :
         {Nested(inner, "1"), "[" + Nested(inner - 1, "\"s\"") + "]",
          NestedObjects(inner)}) {
      WriteText(path, CategoryWithExtra(original, extra));
      const std::vector<std::string> errors = Errors();
      EXPECT_EQ(errors[1], errors[0]) << inner;
      EXPECT_EQ(errors[2], errors[0]) << inner;
      EXPECT_EQ(errors[0].empty(), inner == kMaxJsonDepth - 2)
          << inner << ": " << errors[0];
    }
  }
  WriteText(path, original);
}

// `text` with the field "x": `value` first in its first object.
std::string WithField(const std::string& text, const std::string& value) {
  const size_t open = text.find('{');
  return text.substr(0, open + 1) + "\"x\": " + value + ", " +
         text.substr(open + 1);
}

// Each DOM reader: a legitimate file parses; the same file with one more
// field nested 110,000 deep (arrays or objects) is one InputError naming the
// file.
TEST(JsonDepth, EveryDomReaderStopsAtTheLimit) {
  const std::string dir = test::MakeTempDir("json_depth_readers");
  Trajectory trajectory;
  trajectory.Add(0.0, Rigid3d());
  WriteTrajectoryJson(dir + "/written.json", trajectory);
  std::ifstream in(dir + "/written.json", std::ios::binary);
  const std::string trajectory_text(std::istreambuf_iterator<char>(in), {});
  struct Case {
    std::string name, good;
    std::function<void(const std::string&)> read;
  };
  const std::vector<Case> cases = {
      {"traj.json", trajectory_text,
       [](const std::string& p) { ReadTrajectoryJson(p); }},
      {"boxes.json",
       R"({"format": "geodrive-boxes", "version": 1, "image_width": 8, )"
       R"("image_height": 8, "num_frames": 1, "instances": []})",
       [](const std::string& p) { ReadBoxesJson(p); }},
      // meta.json: checked for depth before any field.
      {"meta.json", R"({"clip_id": "c"})",
       [](const std::string& p) {
         std::ifstream in(p, std::ios::binary);
         PairMetaFromJson(std::string(std::istreambuf_iterator<char>(in), {}),
                          p);
       }},
      {"manifest.jsonl", R"({"clip_id": "c"})",
       [](const std::string& p) { ReadManifest(p); }},
      {"failures.jsonl", R"({"clip_id": "c", "stage": "s", "error": "e"})",
       [](const std::string& p) { ReadFailures(p); }},
      {"clips.jsonl", R"({"clip_id": "c", "index": 3})",
       [&](const std::string& p) { SceneFolders(dir, p, "pred_traj.txt"); }},
  };
  for (const Case& c : cases) {
    const std::string path = dir + "/" + c.name;
    WriteText(path, c.good);
    const std::string good_error = ErrorOf([&] { c.read(path); });
    EXPECT_EQ(good_error.find("nested"), std::string::npos) << good_error;
    for (const std::string& deep :
         {Nested(kHostileDepth), NestedObjects(kHostileDepth),
          Nested(kMaxJsonDepth)}) {
      WriteText(path, WithField(c.good, deep));
      const std::string error = ErrorOf([&] { c.read(path); });
      EXPECT_NE(error.find(path), std::string::npos) << c.name << ": " << error;
      EXPECT_NE(error.find("JSON nested more than 64 arrays/objects deep"),
                std::string::npos)
          << c.name << ": " << error;
    }
  }
}

TEST(JsonDepth, ParseJsonAcceptsTheLimitAndNoMore) {
  EXPECT_EQ(internal::ParseJson(Nested(kMaxJsonDepth), "a.json").dump(),
            Nested(kMaxJsonDepth));
  EXPECT_THROW(internal::ParseJson(Nested(kMaxJsonDepth + 1), "a.json"),
               InputError);
  EXPECT_THROW(internal::ParseJson(NestedObjects(kMaxJsonDepth + 1), "a.json"),
               InputError);
  // Malformed JSON is still nlohmann's parse error.
  EXPECT_THROW(internal::ParseJson(std::string("[1,"), "a.json"),
               nlohmann::json::parse_error);
}

// A safetensors file image: the 8-byte length, the header, `data` zero bytes.
std::vector<uint8_t> Safetensors(const std::string& header, size_t data) {
  std::vector<uint8_t> out(8 + header.size() + data, 0);
  const uint64_t n = header.size();
  for (int i = 0; i < 8; ++i) out[i] = static_cast<uint8_t>(n >> (8 * i));
  std::copy(header.begin(), header.end(), out.begin() + 8);
  return out;
}
std::string HeaderError(const std::vector<uint8_t>& file) {
  return ErrorOf([&] {
    diffusion::ParseSafetensorsHeader("m.safetensors", file.data(),
                                      file.size());
  });
}

TEST(JsonDepth, SafetensorsNestingIsAnError) {
  const std::string tensor = R"("dtype": "F32", "data_offsets": [0, 4])";
  // The shape nested 100,000 deep (the error message dumped it recursively),
  // a shape entry nested within the limit (named by its type, not dumped),
  // and metadata nested deep.
  std::string error = HeaderError(Safetensors(
      R"({"w": {"shape": )" + Nested(100000) + ", " + tensor + "}}", 4));
  EXPECT_EQ(error.rfind("m.safetensors: JSON nested more than 64", 0), 0u)
      << error;
  error = HeaderError(Safetensors(
      R"({"w": {"shape": [)" + Nested(50) + "], " + tensor + "}}", 4));
  EXPECT_NE(error.find("invalid shape entry (an array)"), std::string::npos)
      << error;
  error = HeaderError(
      Safetensors(R"({"__metadata__": )" + NestedObjects(100000) + "}", 0));
  EXPECT_EQ(error.rfind("m.safetensors: JSON nested more than 64", 0), 0u)
      << error;
  // Duplicate names are still found.
  error =
      HeaderError(Safetensors(R"({"w": {"shape": [1], )" + tensor +
                                  R"(}, "w": {"shape": [1], )" + tensor + "}}",
                              4));
  EXPECT_NE(error.find("duplicate tensor name 'w'"), std::string::npos)
      << error;
}

// A header of `n` one-element F32 tensors; returns the parse time in seconds.
double ParseManyTensors(int n) {
  std::string header = "{";
  for (int i = 0; i < n; ++i) {
    header += (i ? "," : "");
    header += "\"t" + std::to_string(i) +
              R"(": {"dtype": "F32", "shape": [1], "data_offsets": [)" +
              std::to_string(4 * i) + ", " + std::to_string(4 * i + 4) + "]}";
  }
  header += "}";
  const std::vector<uint8_t> file = Safetensors(header, 4 * size_t(n));
  const auto start = std::chrono::steady_clock::now();
  const diffusion::SafetensorsHeader parsed = diffusion::ParseSafetensorsHeader(
      "m.safetensors", file.data(), file.size());
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  EXPECT_EQ(parsed.entries.size(), size_t(n));
  return seconds;
}

TEST(JsonDepth, SafetensorsTensorCountIsBounded) {
  // One more top-level key than kSafetensorsMaxTensors (scalars: the count
  // stops the parse before any tensor is checked).
  std::string header = "{";
  for (uint64_t i = 0; i <= diffusion::kSafetensorsMaxTensors; ++i)
    header += "\"" + std::to_string(i) + "\":0,";
  header.back() = '}';
  const std::string error = HeaderError(Safetensors(header, 0));
  EXPECT_EQ(error,
            "m.safetensors: safetensors header holds more than 200000 "
            "tensors (the limit)");
}

TEST(JsonDepth, SafetensorsHeaderParsesInLinearTime) {
  // Quadratic before (nlohmann's parser callback rescanned the top-level
  // object at the end of each tensor): 100,000 tensors took 244 s. Linear,
  // they take about 0.3 s in Release; the bound leaves room for sanitizers.
  const double t50k = ParseManyTensors(50000);
  const double t100k = ParseManyTensors(100000);
  std::printf("safetensors header: 50,000 tensors %.3f s, 100,000 %.3f s\n",
              t50k, t100k);
  EXPECT_LT(t100k, 15.0);
}

}  // namespace json_depth_test
}  // namespace geodrive

// The two JSON front ends of the nuScenes reader (dataset/internal/
// nuscenes_json.h) give the same tables and the same errors: the fast one
// (simdjson over slices, several threads) against the reference one (nlohmann
// SAX, the reader's behaviour before simdjson) on the synthetic tables, the
// closed-form fixture, the real scene-0916 extract, and on thousands of
// corrupted tables. Also the SWAR hex token parser, byte by byte.

#include "dataset/internal/nuscenes_json.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <random>
#include <sstream>

#include "dataset/nuscenes.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"
#include "tests/dataset/nuscenes_fixture.h"

namespace geodrive {
namespace {

namespace nj = nuscenes_json;
using json = nlohmann::json;

// Restores the process-wide front-end settings after each test.
class FrontEnds : public ::testing::Test {
 protected:
  void TearDown() override {
    nj::SetFastFrontEndEnabled(true);
    nj::SetSliceBytes(nj::kDefaultSliceBytes);
  }
};

std::string Hex(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%a", v);
  return buf;
}

// Every loaded field, doubles exact (hex floats), in one string.
std::string Dump(const Nuscenes& n) {
  std::ostringstream os;
  auto pose = [&](const Rigid3d& p) {
    for (int i = 0; i < 4; ++i) os << Hex(p.rotation.coeffs()[i]) << ",";
    for (int i = 0; i < 3; ++i) os << Hex(p.translation[i]) << ",";
  };
  os << "category\n";
  for (const auto& c : n.categories())
    os << c.token.ToString() << c.name << "|" << c.description << c.index
       << "\n";
  os << "attribute\n";
  for (const auto& a : n.attributes())
    os << a.token.ToString() << a.name << "|" << a.description << "\n";
  os << "visibility\n";
  for (const auto& v : n.visibilities())
    os << v.token.ToString() << v.level << "|" << v.description << "\n";
  os << "instance\n";
  for (const auto& i : n.instances())
    os << i.token.ToString() << " " << i.category << " " << i.nbr_annotations
       << " " << i.first_annotation << " " << i.last_annotation << "\n";
  os << "sensor\n";
  for (const auto& s : n.sensors())
    os << s.token.ToString() << s.channel << static_cast<int>(s.modality)
       << "\n";
  os << "calibrated_sensor\n";
  for (const auto& c : n.calibrated_sensors()) {
    os << c.token.ToString() << " " << c.sensor << " " << c.has_intrinsic;
    pose(c.ego_from_sensor);
    for (int i = 0; i < 9; ++i) os << Hex(c.camera_intrinsic(i / 3, i % 3));
    os << "\n";
  }
  os << "ego_pose\n";
  for (const auto& e : n.ego_poses()) {
    os << e.token.ToString() << " " << e.timestamp;
    pose(e.global_from_ego);
    os << "\n";
  }
  os << "log\n";
  for (const auto& l : n.logs())
    os << l.token.ToString() << l.logfile << "|" << l.vehicle << "|"
       << l.date_captured << "|" << l.location << " " << l.map << "\n";
  os << "scene\n";
  for (const auto& s : n.scenes())
    os << s.token.ToString() << s.name << "|" << s.description << " " << s.log
       << " " << s.nbr_samples << " " << s.first_sample << " " << s.last_sample
       << "\n";
  os << "sample\n";
  for (const auto& s : n.samples()) {
    os << s.token.ToString() << " " << s.timestamp << " " << s.scene << " "
       << s.prev << " " << s.next << " d";
    for (int32_t d : s.data) os << " " << d;
    os << " a";
    for (int32_t a : s.anns) os << " " << a;
    os << "\n";
  }
  os << "sample_data\n";
  for (const auto& d : n.sample_data())
    os << d.token.ToString() << " " << d.sample << " " << d.ego_pose << " "
       << d.calibrated_sensor << " " << d.sensor << " " << d.prev << " "
       << d.next << " " << d.timestamp << " " << d.width << "x" << d.height
       << " " << d.is_key_frame << d.fileformat << "|" << d.filename << "\n";
  os << "sample_annotation\n";
  for (const auto& a : n.sample_annotations()) {
    os << a.token.ToString() << " " << a.sample << " " << a.instance << " "
       << a.visibility << " " << a.category << " " << a.prev << " " << a.next
       << " " << a.num_lidar_pts << " " << a.num_radar_pts << " at";
    for (int32_t t : a.attributes) os << " " << t;
    for (int i = 0; i < 3; ++i)
      os << " " << Hex(a.translation[i]) << " " << Hex(a.size[i]);
    for (int i = 0; i < 4; ++i) os << " " << Hex(a.rotation.coeffs()[i]);
    os << "\n";
  }
  os << "map\n";
  for (const auto& m : n.maps()) {
    os << m.token.ToString() << m.category << "|" << m.filename;
    for (int32_t l : m.logs) os << " " << l;
    os << "\n";
  }
  os << "chains\n";
  for (size_t s = 0; s < n.scenes().size(); ++s) {
    for (size_t k = 0; k < n.sensors().size(); ++k) {
      os << s << "/" << k << ":";
      for (int32_t d :
           n.Chain(static_cast<int32_t>(s), static_cast<int32_t>(k)))
        os << " " << d;
      os << "\n";
    }
  }
  return os.str();
}

// How a load ends: every field (Dump) or "error: <message>".
std::string Outcome(const NuscenesOptions& options) {
  try {
    const Nuscenes n(options);
    return Dump(n);
  } catch (const InputError& e) {
    return std::string("error: ") + e.what();
  }
}

// The reference front end's outcome, and the fast one's with `threads`
// threads and `slice_bytes` slices.
std::string Reference(NuscenesOptions options) {
  nj::SetFastFrontEndEnabled(false);
  options.num_threads = 1;
  const std::string out = Outcome(options);
  nj::SetFastFrontEndEnabled(true);
  return out;
}
std::string Fast(NuscenesOptions options, int threads, size_t slice_bytes) {
  nj::SetSliceBytes(slice_bytes);
  options.num_threads = threads;
  return Outcome(options);
}

// A table file's text, and writing it back.
std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}
void WriteText(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
}

// The fast front end, with 1 and 2 threads and each slice size, ends as
// `reference` does.
void ExpectFastAsReference(const NuscenesOptions& options,
                           const std::string& reference,
                           std::initializer_list<size_t> slice_sizes) {
  for (int threads : {1, 2}) {
    for (size_t slice_bytes : slice_sizes) {
      EXPECT_EQ(Fast(options, threads, slice_bytes), reference)
          << threads << " threads, " << slice_bytes << " B slices";
    }
  }
}

TEST(NuscenesHexTokens, EveryByteAtEveryPosition) {
  const std::string base = "0123456789abcdeffedcba9876543210";
  const NuscenesToken t = NuscenesToken::FromString(base);
  EXPECT_EQ(t.hi, 0x0123456789abcdefull);
  EXPECT_EQ(t.lo, 0xfedcba9876543210ull);
  int hex = 0, interned = 0;
  for (int pos = 0; pos < 32; ++pos) {
    for (int c = 1; c < 256; ++c) {
      std::string s = base;
      s[pos] = static_cast<char>(c);
      const NuscenesToken token = NuscenesToken::FromString(s);
      const bool is_hex = (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
      // Interned tokens carry the all-ones tag in hi.
      ASSERT_EQ(token.hi != ~uint64_t{0}, is_hex) << pos << " " << c;
      ASSERT_EQ(token.ToString(), s) << pos << " " << c;
      if (is_hex) {
        const int v = c <= '9' ? c - '0' : c - 'a' + 10;
        const uint64_t word = pos < 16 ? token.hi : token.lo;
        ASSERT_EQ((word >> (4 * (15 - pos % 16))) & 15,
                  static_cast<uint64_t>(v));
        ++hex;
      } else {
        ++interned;
      }
    }
  }
  EXPECT_EQ(hex, 32 * 16);
  EXPECT_EQ(interned, 32 * (255 - 16));
}

TEST_F(FrontEnds, SyntheticTablesAreIdenticalAndNeverFallBack) {
  const std::string root = test::SharedFixtureDir(
      "nuscenes_json_synthetic", [](const std::string& dir) {
        SyntheticDatasetOptions o;
        o.num_scenes = 3;
        o.scene_duration_s = 6.0;
        o.tables_only = true;
        o.radars = true;
        o.cameras = {"CAM_FRONT", "CAM_FRONT_LEFT", "CAM_BACK"};
        WriteSyntheticDataset(o, dir);
      });
  NuscenesOptions options;
  options.dataroot = root;
  const std::string reference = Reference(options);
  ASSERT_EQ(reference.rfind("error", 0), std::string::npos) << reference;
  const size_t fallbacks = nj::FallbackCount();
  // Default slices (each table is one or two), then 300-byte slices (every
  // boundary; records longer than a slice double the read), on 1-4 threads.
  for (int threads : {1, 2, 4}) {
    for (size_t slice :
         {nj::kDefaultSliceBytes, size_t{1} << 20, size_t{300}, size_t{4096}}) {
      EXPECT_EQ(Fast(options, threads, slice), reference)
          << threads << " threads, slices of " << slice;
    }
  }
  EXPECT_EQ(nj::FallbackCount(), fallbacks);
  EXPECT_GT(reference.size(), 100000u);
}

TEST_F(FrontEnds, RealSceneAndFixtureAreIdenticalAndNeverFallBack) {
  const size_t fallbacks = nj::FallbackCount();
  NuscenesOptions real;
  real.dataroot = test::RealDataPath("nuscenes_scene0916");
  real.version = "v1.0-mini-extract";
  const std::string reference = Reference(real);
  ASSERT_EQ(reference.rfind("error", 0), std::string::npos) << reference;
  EXPECT_EQ(Fast(real, 2, size_t{1} << 20), reference);
  EXPECT_EQ(Fast(real, 2, 1000), reference);
  EXPECT_EQ(Fast(real, 1, 200), reference);

  test::NuscenesFixture fx;
  NuscenesOptions fixture;
  fixture.dataroot = fx.Write(test::MakeTempDir("nuscenes_json_fixture"));
  const std::string fixture_reference = Reference(fixture);
  ASSERT_EQ(fixture_reference.rfind("error", 0), std::string::npos);
  EXPECT_EQ(Fast(fixture, 2, 256), fixture_reference);
  EXPECT_EQ(nj::FallbackCount(), fallbacks);
}

// A value of every kind the reader distinguishes, and a few it must reject.
json OddValue(std::mt19937& rng) {
  static const json kValues[] = {
      nullptr,
      true,
      1.5,
      -3,
      0,
      -0.0,
      1e300,
      "str",
      "",
      "4",
      json::array(),
      {1, 2},
      {1, 2, 3},
      {1.0, 0.0, 0.0, 0.0},
      {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}},
      {{1, 2, 3}, {4, 5}},
      {{1, {2}}, {3}},
      {1, "x"},
      {nullptr},
      {true, 1},
      json::object(),
      {{"a", 1}},
      {{"a", {1, {{"b", nullptr}}}}},
      18446744073709551615ull,
      9223372036854775808ull,
      INT64_MIN,
      "0123456789abcdef0123456789abcdef",
      "samples/../x.jpg",
      std::string("a\0b", 3),
  };
  return kValues[rng() % (sizeof(kValues) / sizeof(kValues[0]))];
}

// Raw text that JSON writers do not produce: literals and numbers simdjson
// and nlohmann may judge differently, broken structure, odd escapes.
const char* OddText(std::mt19937& rng) {
  static const char* const kTexts[] = {
      "1e400",
      "-1e400",
      "1e-400",
      "-0",
      "01",
      "1.",
      "nul",
      "nullx",
      "tru",
      "NaN",
      "\"\\udc00\"",
      "\"\\ud800\"",
      "\"\\ud83d\\ude00\"",
      "\"\\u0041\"",
      "\"\\x\"",
      "}",
      "]",
      "{",
      "[",
      ",",
      "},{",
      "}, {",
      "\"",
      "\\",
      "123456789012345678901234567890",
      "18446744073709551616",
      "-9223372036854775809",
      "\x01",
      "\xff",
      " ",
      "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[["
      "[[[[[[[[1]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]"
      "]]]]]]]]]"};
  return kTexts[rng() % (sizeof(kTexts) / sizeof(kTexts[0]))];
}

// Corrupts one table of the fixture: a field set to an odd value, a field
// removed, or raw text inserted, deleted or replaced in the written file.
void Corrupt(std::mt19937& rng,
             test::NuscenesFixture* fx,
             const std::string& root) {
  auto it = fx->tables.begin();
  std::advance(it, rng() % fx->tables.size());
  json& table = it->second;
  if (table.empty()) return;
  json& record = table[rng() % table.size()];
  const int kind = static_cast<int>(rng() % 4);
  if (kind <= 1) {
    auto field = record.begin();
    std::advance(field, rng() % record.size());
    if (kind == 0) {
      field.value() = OddValue(rng);
    } else {
      record.erase(field.key());
    }
    fx->Write(root);
    return;
  }
  fx->Write(root);
  const std::string path = root + "/v1.0-mini/" + it->first + ".json";
  std::string text;
  {
    std::ifstream in(path, std::ios::binary);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  const size_t at = rng() % (text.size() + 1);
  if (kind == 2) {
    text.insert(at, OddText(rng));
  } else if (at < text.size()) {
    text.replace(at, 1 + rng() % 3, rng() % 2 ? "" : OddText(rng));
  }
  std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
}

// The contract that makes the fast front end safe: on any input, the load
// ends exactly as it did with the reference front end alone -- the same
// tables, or the same one-line error (the same file, record and wording).
TEST_F(FrontEnds, CorruptedTablesEndExactlyAsWithTheReference) {
  std::mt19937 rng(test::kTestSeed);
  const std::string root = test::MakeTempDir("nuscenes_json_corrupt");
  int errors = 0, loads = 0, fast_taken = 0;
  for (int round = 0; round < 400; ++round) {
    test::NuscenesFixture fx;
    fx.Write(root);
    const int corruptions = 1 + static_cast<int>(rng() % 2);
    for (int c = 0; c < corruptions; ++c) Corrupt(rng, &fx, root);
    NuscenesOptions options;
    options.dataroot = root;
    const std::string reference = Reference(options);
    const size_t before = nj::FallbackCount();
    const std::string fast = Fast(options, 1 + round % 3, 64 + rng() % 2000);
    ASSERT_EQ(fast, reference) << "round " << round;
    if (reference.rfind("error: ", 0) == 0) {
      ++errors;
      EXPECT_EQ(reference.find('\n'), std::string::npos) << reference;
    } else {
      ++loads;
    }
    if (nj::FallbackCount() == before) ++fast_taken;
  }
  std::printf("corrupted tables: %d errors, %d loads, %d on the fast path\n",
              errors, loads, fast_taken);
  // Both outcomes and both paths are exercised.
  EXPECT_GT(errors, 100);
  EXPECT_GT(loads, 20);
  EXPECT_GT(fast_taken, 100);
  EXPECT_LT(fast_taken, 400);
}

// Errors in two slices of one table, handled by different threads: the one
// earlier in the file is reported, whichever kind each is.
TEST_F(FrontEnds, TheFirstErrorInFileOrderWins) {
  const std::string root = test::MakeTempDir("nuscenes_json_two_errors");
  for (int order = 0; order < 2; ++order) {
    test::NuscenesFixture fx;
    json& sd = fx.tables["sample_data"];
    ASSERT_GT(sd.size(), 200u);
    const size_t early = 20, late = sd.size() - 20;
    const size_t type_error = order == 0 ? early : late;
    sd[type_error]["timestamp"] = "soon";  // a wrong type
    fx.Write(root);
    const std::string path = root + "/v1.0-mini/sample_data.json";
    std::string text;
    {
      std::ifstream in(path, std::ios::binary);
      text.assign(std::istreambuf_iterator<char>(in), {});
    }
    // Malformed JSON (an unterminated literal) in the other record.
    const std::string tok =
        sd[order == 0 ? late : early]["token"].get<std::string>();
    const size_t at = text.find("\"is_key_frame\"", text.find(tok));
    text.replace(text.find(':', at) + 1, 0, "tru");
    std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
    NuscenesOptions options;
    options.dataroot = root;
    const std::string reference = Reference(options);
    EXPECT_NE(reference.find(order == 0 ? "wrong type" : "malformed JSON"),
              std::string::npos)
        << reference;
    for (int threads : {1, 2, 3}) {
      EXPECT_EQ(Fast(options, threads, 512), reference) << threads;
    }
  }
}

// The fast front end recognises a record's keys by comparing their raw bytes
// with the previous record's keys (no unescaping) when those are plain. A key
// spelt with escapes ("\u0074imestamp" is "timestamp"), and keys that hold a
// backslash themselves (raw "a\\tb" is a, backslash, t, b; raw "a\tb" in the
// next record is a, TAB, b: the same raw bytes after the first backslash, a
// different key), and a key that extends the previous record's ("prevX"
// where "prev" was), load exactly as with the reference front end and give
// the tables of the file without them.
TEST_F(FrontEnds, EscapedKeysAreTheKeysTheySpell) {
  const std::string root = test::MakeTempDir("nuscenes_json_escaped_keys");
  test::NuscenesFixture fx;
  json& sd = fx.tables["sample_data"];
  ASSERT_GT(sd.size(), 40u);
  for (auto& record : sd) record["a\\tb"] = 1;  // one backslash in the key
  fx.Write(root);
  NuscenesOptions options;
  options.dataroot = root;
  const std::string plain = Reference(options);
  ASSERT_EQ(plain.rfind("error: ", 0), std::string::npos) << plain;
  const std::string path = root + "/v1.0-mini/sample_data.json";
  std::string text = ReadText(path);
  // Records 20 and 30: "timestamp" and "token" spelt with escapes; record 25:
  // the backslash key's raw bytes changed into a TAB escape.
  auto record_at = [&](size_t k) {
    return text.find(sd[k]["token"].get<std::string>());
  };
  const size_t r20 = text.find("\"timestamp\"", record_at(20));
  ASSERT_NE(r20, std::string::npos);
  text.replace(r20, 11, "\"\\u0074imestamp\"");
  const size_t r30 = text.rfind("\"token\"", record_at(30));
  ASSERT_NE(r30, std::string::npos);
  text.replace(r30, 7, "\"\\u0074oken\"");
  const size_t r25 = text.find("\"a\\\\tb\"", record_at(25));
  ASSERT_NE(r25, std::string::npos);
  text.replace(r25, 7, "\"a\\tb\"");
  // Record 35: an unknown key that starts with the previous record's key at
  // that place ("prevX" where "prev" was) is another key, not "prev".
  const size_t r35 = text.find("\"prev\"", record_at(35));
  ASSERT_NE(r35, std::string::npos);
  text.insert(r35, "\"prevX\": \"\", ");
  WriteText(path, text);
  const std::string reference = Reference(options);
  EXPECT_EQ(reference, plain);
  ExpectFastAsReference(options, reference, {700, size_t{1} << 20});
}

// A "]" right after a record's "}" ends the top-level array early: the
// rest of the file is then trailing garbage, a JSON error for the reference
// front end. The fast one must not take the records before it as the whole
// table (On Demand stops at the "]" without an error; the slice parser
// checks that nothing follows it).
TEST_F(FrontEnds, ArrayClosedEarlyIsTheReferenceError) {
  const std::string root = test::MakeTempDir("nuscenes_json_early_close");
  test::NuscenesFixture fx;
  const json& sd = fx.tables["sample_data"];
  ASSERT_GT(sd.size(), 40u);
  fx.Write(root);
  const std::string path = root + "/v1.0-mini/sample_data.json";
  std::string text = ReadText(path);
  // The "}" that closes the record holding the 20th record's token.
  const size_t at =
      text.find('}', text.find(sd[20]["token"].get<std::string>()));
  ASSERT_NE(at, std::string::npos);
  text.insert(at + 1, "]");
  WriteText(path, text);
  NuscenesOptions options;
  options.dataroot = root;
  const std::string reference = Reference(options);
  EXPECT_EQ(reference.rfind("error: ", 0), 0u) << reference;
  EXPECT_NE(reference.find("sample_data.json"), std::string::npos) << reference;
  ExpectFastAsReference(options, reference, {700, size_t{1} << 20});
}

// The slicer looks for a slice's last record boundary in the last 4 KiB of
// its window first, then in 16 KiB, ...: records of 6 KiB (an unknown field
// holds the bulk) put whole 4 KiB tails inside one record. The tables are the
// reference's, and no table falls back.
TEST_F(FrontEnds, RecordsLongerThanTheBoundarySearchTail) {
  const std::string root = test::MakeTempDir("nuscenes_json_long_records");
  test::NuscenesFixture fx;
  for (auto& record : fx.tables["sample_data"])
    record["note"] = std::string(6000, 'x');
  fx.Write(root);
  NuscenesOptions options;
  options.dataroot = root;
  const std::string reference = Reference(options);
  ASSERT_EQ(reference.rfind("error: ", 0), std::string::npos) << reference;
  const size_t fallbacks = nj::FallbackCount();
  ExpectFastAsReference(options, reference, {5000, 20000, 70000});
  EXPECT_EQ(nj::FallbackCount(), fallbacks);
}

}  // namespace
}  // namespace geodrive

namespace geodrive {
namespace {

// Tables with more than 8,192 sample_data rows (two scenes of 40 s, six
// cameras, LiDAR and radars), shared by the tests of this build.
std::string BigTables() {
  return test::SharedFixtureDir(
      "nuscenes_json_big", [](const std::string& dir) {
        SyntheticDatasetOptions o;
        o.num_scenes = 2;
        o.scene_duration_s = 40.0;
        o.tables_only = true;
        o.radars = true;
        o.cameras = {"CAM_FRONT", "CAM_FRONT_LEFT", "CAM_FRONT_RIGHT",
                     "CAM_BACK",  "CAM_BACK_LEFT",  "CAM_BACK_RIGHT"};
        WriteSyntheticDataset(o, dir);
      });
}

// A private copy of BigTables() in a temporary folder, its tables read and
// written back as JSON.
struct BigTablesCopy {
  explicit BigTablesCopy(const std::string& name)
      : root(test::MakeTempDir(name)) {
    std::filesystem::copy(BigTables(), root,
                          std::filesystem::copy_options::recursive);
  }
  json Read(const std::string& table) const {
    std::ifstream in(root + "/v1.0-mini/" + table + ".json");
    return json::parse(in);
  }
  void Write(const std::string& table, const json& rows) const {
    std::ofstream(root + "/v1.0-mini/" + table + ".json", std::ios::trunc)
        << rows.dump(0);
  }
  const std::string root;
};

// Reference resolution and the token indices run on several threads above
// 8,192 rows (blocks of 4,096): dangling references and duplicate tokens in a
// big table still give the error a serial pass gives (the first row, the first
// table).
TEST_F(FrontEnds, ResolutionErrorsOfBigTablesDoNotDependOnThreads) {
  BigTablesCopy copy("nuscenes_json_big_errors");
  const std::string& root = copy.root;
  auto read = [&](const std::string& name) { return copy.Read(name); };
  auto write = [&](const std::string& name, const json& table) {
    copy.Write(name, table);
  };
  const json sample_data = read("sample_data"), ego_pose = read("ego_pose");
  ASSERT_GT(sample_data.size(), 3 * 4096u);  // four blocks of rows
  NuscenesOptions options;
  options.dataroot = root;
  const size_t n = sample_data.size();
  // Dangling references at the end of block 1 and the start of block 2: a
  // thread that takes block 2 finds its error first, the earlier one wins.
  json broken = sample_data;
  broken[8200]["ego_pose_token"] = "0123456789abcdef0123456789abcdef";
  broken[8000]["prev"] = "fedcba9876543210fedcba9876543210";
  write("sample_data", broken);
  std::string reference = Reference(options);
  EXPECT_NE(reference.find(sample_data[8000]["token"].get<std::string>()),
            std::string::npos)
      << reference;
  for (int threads : {2, 3}) {
    EXPECT_EQ(Fast(options, threads, size_t{1} << 20), reference) << threads;
  }
  // Duplicate tokens in sample_data and in ego_pose: ego_pose comes first in
  // table order.
  broken = sample_data;
  broken[n - 5]["token"] = sample_data[n - 100]["token"];
  write("sample_data", broken);
  json poses = ego_pose;
  poses[poses.size() - 3]["token"] = ego_pose[poses.size() - 2]["token"];
  write("ego_pose", poses);
  reference = Reference(options);
  EXPECT_NE(reference.find("ego_pose.json"), std::string::npos) << reference;
  EXPECT_NE(reference.find("duplicate"), std::string::npos) << reference;
  for (int threads : {2, 3}) {
    EXPECT_EQ(Fast(options, threads, size_t{1} << 20), reference) << threads;
  }
}

// References are found by a guess before the hash (the row after or the same
// as the previous record's reference; for prev, the row whose next named this
// one): whatever the order of the rows, each reference resolves to the row
// with that token, on one thread or several, and a table with several bad
// references still reports the first in file order.
TEST_F(FrontEnds, ReferencesResolveWhateverTheRowOrder) {
  BigTablesCopy copy("nuscenes_json_shuffled");
  const std::string& root = copy.root;
  auto read = [&](const std::string& name) { return copy.Read(name); };
  auto write = [&](const std::string& name, const json& table) {
    copy.Write(name, table);
  };
  json sample_data = read("sample_data");
  json annotations = read("sample_annotation");
  ASSERT_GT(sample_data.size(), 3 * 4096u);
  ASSERT_GT(annotations.size(), 100u);
  // As written (chains in file order: every guess right) and shuffled (the
  // row-order guesses wrong, the prev guess still right).
  for (bool shuffle : {false, true}) {
    if (shuffle) {
      std::shuffle(sample_data.begin(), sample_data.end(), test::Rng());
      std::shuffle(annotations.begin(), annotations.end(), test::Rng());
      write("sample_data", sample_data);
      write("sample_annotation", annotations);
    }
    for (int threads : {1, 2}) {
      NuscenesOptions options;
      options.dataroot = root;
      options.num_threads = threads;
      const Nuscenes n(options);
      ASSERT_EQ(n.sample_data().size(), sample_data.size());
      auto token_of = [](const auto& rows, int32_t i) {
        return i == kNoIndex ? std::string() : rows[i].token.ToString();
      };
      for (size_t i = 0; i < sample_data.size(); ++i) {
        const json& r = sample_data[i];
        const NuscenesSampleData& d = n.sample_data()[i];
        ASSERT_EQ(d.token.ToString(), r["token"].get<std::string>());
        ASSERT_EQ(token_of(n.samples(), d.sample), r["sample_token"]) << i;
        ASSERT_EQ(token_of(n.ego_poses(), d.ego_pose), r["ego_pose_token"])
            << i;
        ASSERT_EQ(token_of(n.calibrated_sensors(), d.calibrated_sensor),
                  r["calibrated_sensor_token"])
            << i;
        ASSERT_EQ(token_of(n.sample_data(), d.prev), r["prev"]) << i;
        ASSERT_EQ(token_of(n.sample_data(), d.next), r["next"]) << i;
      }
      for (size_t i = 0; i < annotations.size(); ++i) {
        const json& r = annotations[i];
        const NuscenesSampleAnnotation& a = n.sample_annotations()[i];
        ASSERT_EQ(token_of(n.samples(), a.sample), r["sample_token"]) << i;
        ASSERT_EQ(token_of(n.instances(), a.instance), r["instance_token"])
            << i;
        ASSERT_EQ(token_of(n.visibilities(), a.visibility),
                  r["visibility_token"])
            << i;
        ASSERT_EQ(token_of(n.sample_annotations(), a.prev), r["prev"]) << i;
        ASSERT_EQ(token_of(n.sample_annotations(), a.next), r["next"]) << i;
      }
    }
  }
  // A dangling next in an early row and a dangling prev in a later one: the
  // next pass runs first but reports nothing; the error is the early row's.
  json broken = sample_data;
  size_t early = 100;
  while (broken[early]["next"] == "") ++early;
  size_t late = 9000;
  while (broken[late]["prev"] == "") ++late;
  broken[early]["next"] = "0123456789abcdef0123456789abcdef";
  broken[late]["prev"] = "fedcba9876543210fedcba9876543210";
  write("sample_data", broken);
  NuscenesOptions options;
  options.dataroot = root;
  const std::string reference = Reference(options);
  EXPECT_NE(reference.find(broken[early]["token"].get<std::string>() +
                           ": next 0123456789abcdef0123456789abcdef"),
            std::string::npos)
      << reference;
  for (int threads : {1, 2, 3}) {
    EXPECT_EQ(Fast(options, threads, size_t{1} << 20), reference) << threads;
  }
}

}  // namespace
}  // namespace geodrive

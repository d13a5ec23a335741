// safetensors reader/writer: round trip, a file written byte by byte by an
// independent writer (python json + struct), hostile headers, and the sharded
// index form.

#include "diffusion/safetensors.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <set>

#include <cmath>
#include <cstring>
#include <fstream>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace diffusion {
namespace {

// Writes u64 header length + header text + `buffer_bytes` zero bytes.
std::string WriteRaw(const std::string& dir,
                     const std::string& name,
                     const std::string& header,
                     uint64_t buffer_bytes,
                     uint64_t declared_len = UINT64_MAX) {
  const std::string path = dir + "/" + name;
  std::ofstream out(path, std::ios::binary);
  const uint64_t n = declared_len == UINT64_MAX ? header.size() : declared_len;
  for (int i = 0; i < 8; ++i) out.put(static_cast<char>((n >> (8 * i)) & 0xff));
  out << header;
  out << std::string(buffer_bytes, '\0');
  return path;
}

// Expects InputError whose message names `path` and contains `needle`.
void ExpectRejected(const std::string& path, const std::string& needle) {
  try {
    SafetensorsFile f(path);
    ADD_FAILURE() << path << " was accepted";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find(needle), std::string::npos)
        << "expected '" << needle << "' in: " << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << "one line: " << msg;
  }
}

TEST(Safetensors, RoundTripAllDtypesExact) {
  const std::string dir = test::MakeTempDir("safetensors_roundtrip");
  at::manual_seed(7);
  NamedTensors in = {
      {"f64", at::randn({3, 2}, at::kDouble)},
      {"f32", at::randn({2, 3, 4})},
      {"f16", at::randn({5}).to(at::kHalf)},
      {"bf16", at::randn({2, 2}).to(at::kBFloat16)},
      {"i64", at::tensor({-(int64_t{1} << 40), int64_t{3}, int64_t{-7}})},
      {"i32", at::randint(-1000, 1000, {4}, at::kInt)},
      {"i16", at::randint(-300, 300, {4}, at::kShort)},
      {"i8", at::randint(-100, 100, {6}, at::kChar)},
      {"u8", at::randint(0, 255, {7}, at::kByte)},
      {"bool", at::randint(0, 2, {3}, at::kByte).to(at::kBool)},
      {"scalar", at::scalar_tensor(2.5, at::kFloat)},
      {"empty", at::zeros({0, 3})},
      {"strided", at::randn({4, 6}).transpose(0, 1)},  // non-contiguous input
  };
  const std::string path = dir + "/rt.safetensors";
  SaveSafetensors(path, in, {{"format", "pt"}, {"note", "round trip"}});
  SafetensorsFile f(path);
  EXPECT_EQ(f.metadata().at("note"), "round trip");
  ASSERT_EQ(f.entries().size(), in.size());
  for (const auto& [name, t] : in) {
    at::Tensor back = f.Load(name);
    EXPECT_EQ(back.scalar_type(), t.scalar_type()) << name;
    EXPECT_EQ(back.sizes(), t.sizes()) << name;
    EXPECT_TRUE(at::equal(back, t.contiguous())) << name;
  }
  // Data starts 8-byte aligned (writer pads the header with spaces).
  std::ifstream raw(path, std::ios::binary);
  uint8_t len[8];
  raw.read(reinterpret_cast<char*>(len), 8);
  uint64_t n = 0;
  for (int i = 7; i >= 0; --i) n = (n << 8) | len[i];
  EXPECT_EQ((8 + n) % 8, 0u);
  // LoadSafetensors returns every tensor, in name order.
  NamedTensors all = LoadSafetensors(path);
  ASSERT_EQ(all.size(), in.size());
  EXPECT_EQ(all.front().first, "bf16");
  // The torch-free header parser (diffusion/format/) accepts exactly the
  // dtypes the LibTorch loader maps, with their element sizes.
  std::set<std::string> written;
  for (const SafetensorsEntry& e : f.entries()) {
    written.insert(e.dtype);
    const at::Tensor t = f.Load(e.name);
    EXPECT_EQ(SafetensorsDtypeSize(e.dtype),
              static_cast<int64_t>(t.element_size()))
        << e.dtype;
  }
  EXPECT_EQ(written, std::set<std::string>(SafetensorsDtypeNames().begin(),
                                           SafetensorsDtypeNames().end()));
}

TEST(Safetensors, IndependentPythonWriterLoadsExactly) {
  const std::string dir = test::MakeTempDir("safetensors_python");
  const std::string script = dir + "/write.py";
  const std::string path = dir + "/py.safetensors";
  {
    // Written from the format spec with json + struct only (no
    // safetensors/torch package).
    std::ofstream py(script);
    py << R"PY(import json, struct, sys
tensors = []  # (name, dtype, shape, bytes)
a = [0.5 * i - 1.25 for i in range(6)]
tensors.append(("a", "F32", [2, 3], struct.pack("<6f", *a)))
tensors.append(("b", "I64", [4], struct.pack("<4q", -3, 0, 7, 2**40)))
tensors.append(("c", "F16", [3], struct.pack("<3e", 1.5, -2.0, 65504.0)))
bf = [1.0, -0.15625, 3.0e38]  # bfloat16 = upper 16 bits of float32 (these are exact)
tensors.append(("d", "BF16", [3], b"".join(struct.pack("<f", x)[2:] for x in bf)))
tensors.append(("e", "U8", [2, 2], bytes([0, 1, 254, 255])))
tensors.append(("f", "BOOL", [3], bytes([1, 0, 1])))
tensors.append(("g", "F64", [], struct.pack("<d", 3.141592653589793)))
tensors.append(("h", "I8", [2], struct.pack("<2b", -128, 127)))
header = {"__metadata__": {"writer": "python-struct"}}
data = b""
for name, dtype, shape, raw in reversed(tensors):  # data order differs from name order
    header[name] = {"dtype": dtype, "shape": shape, "data_offsets": [len(data), len(data) + len(raw)]}
    data += raw
text = json.dumps(header).encode("utf-8")
text += b" " * ((8 - (8 + len(text)) % 8) % 8)
with open(sys.argv[1], "wb") as f:
    f.write(struct.pack("<Q", len(text)) + text + data)
)PY";
  }
  std::string out;
  ASSERT_EQ(
      test::RunCommand(
          std::string(test::kDebianPython) + " " + script + " " + path, &out),
      0)
      << out;
  SafetensorsFile f(path);
  EXPECT_EQ(f.metadata().at("writer"), "python-struct");
  at::Tensor a = f.Load("a");
  ASSERT_EQ(a.scalar_type(), at::kFloat);
  ASSERT_EQ(a.sizes(), (std::vector<int64_t>{2, 3}));
  for (int i = 0; i < 6; ++i)
    EXPECT_EQ(a.view({-1})[i].item<float>(), 0.5f * i - 1.25f);
  at::Tensor b = f.Load("b");
  EXPECT_EQ(b[3].item<int64_t>(), int64_t{1} << 40);
  EXPECT_EQ(b[0].item<int64_t>(), -3);
  at::Tensor c = f.Load("c").to(at::kFloat);
  EXPECT_EQ(c[0].item<float>(), 1.5f);
  EXPECT_EQ(c[1].item<float>(), -2.0f);
  EXPECT_EQ(c[2].item<float>(), 65504.0f);
  at::Tensor d = f.Load("d");
  ASSERT_EQ(d.scalar_type(), at::kBFloat16);
  EXPECT_EQ(d.to(at::kFloat)[0].item<float>(), 1.0f);
  EXPECT_EQ(d.to(at::kFloat)[1].item<float>(), -0.15625f);
  at::Tensor e = f.Load("e");
  EXPECT_EQ(e[1][1].item<uint8_t>(), 255);
  EXPECT_EQ(e[1][0].item<uint8_t>(), 254);
  at::Tensor fb = f.Load("f");
  ASSERT_EQ(fb.scalar_type(), at::kBool);
  EXPECT_TRUE(fb[0].item<bool>());
  EXPECT_FALSE(fb[1].item<bool>());
  at::Tensor g = f.Load("g");
  EXPECT_EQ(g.dim(), 0);
  EXPECT_EQ(g.item<double>(), 3.141592653589793);
  at::Tensor h = f.Load("h");
  EXPECT_EQ(h[0].item<int8_t>(), -128);
  EXPECT_EQ(h[1].item<int8_t>(), 127);
}

TEST(Safetensors, HostileHeadersRejectedWithFileName) {
  const std::string dir = test::MakeTempDir("safetensors_hostile");
  const std::string ok =
      R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[0,8]}})";
  // Sanity: the well-formed variant loads.
  EXPECT_NO_THROW(SafetensorsFile(WriteRaw(dir, "ok.safetensors", ok, 8)));

  ExpectRejected(WriteRaw(dir, "huge.st", ok, 8, uint64_t{1} << 63), "exceeds");
  ExpectRejected(WriteRaw(dir, "limit.st", ok, 8, 200u * 1000u * 1000u),
                 "exceeds");
  ExpectRejected(WriteRaw(dir, "pastend.st", ok, 8, 5000), "past the end");
  {
    const std::string p = dir + "/short.st";
    std::ofstream(p) << "abc";
    ExpectRejected(p, "truncated");
  }
  ExpectRejected(WriteRaw(dir, "badjson.st", R"({"a": {"dtype": "F32", )", 8),
                 "not valid JSON");
  ExpectRejected(WriteRaw(dir, "notobj.st", R"([1, 2, 3])", 0),
                 "start with '{'");
  ExpectRejected(
      WriteRaw(dir, "f8.st",
               R"({"a":{"dtype":"F8_E4M3","shape":[2],"data_offsets":[0,2]}})",
               2),
      "F8_E4M3");
  ExpectRejected(
      WriteRaw(dir, "u16.st",
               R"({"a":{"dtype":"U16","shape":[2],"data_offsets":[0,4]}})", 4),
      "unsupported dtype 'U16'");
  ExpectRejected(
      WriteRaw(dir, "overlap.st",
               R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[0,8]},)"
               R"("b":{"dtype":"F32","shape":[2],"data_offsets":[4,12]}})",
               12),
      "overlap");
  ExpectRejected(
      WriteRaw(dir, "range.st",
               R"({"a":{"dtype":"F32","shape":[4],"data_offsets":[0,16]}})", 8),
      "outside");
  ExpectRejected(
      WriteRaw(dir, "hole.st",
               R"({"a":{"dtype":"F32","shape":[1],"data_offsets":[0,4]},)"
               R"("b":{"dtype":"F32","shape":[1],"data_offsets":[8,12]}})",
               12),
      "hole");
  ExpectRejected(WriteRaw(dir, "trail.st", ok, 16), "trailing bytes");
  ExpectRejected(
      WriteRaw(dir, "size.st",
               R"({"a":{"dtype":"F32","shape":[3],"data_offsets":[0,8]}})", 8),
      "needs 12 bytes");
  ExpectRejected(
      WriteRaw(dir, "neg.st",
               R"({"a":{"dtype":"F32","shape":[-2],"data_offsets":[0,8]}})", 8),
      "invalid shape");
  ExpectRejected(
      WriteRaw(dir, "float.st",
               R"({"a":{"dtype":"F32","shape":[2.5],"data_offsets":[0,8]}})",
               8),
      "invalid shape");
  ExpectRejected(
      WriteRaw(dir, "overflow.st",
               R"({"a":{"dtype":"F32","shape":[4294967296,4294967296,16],)"
               R"("data_offsets":[0,8]}})",
               8),
      "too many");
  ExpectRejected(
      WriteRaw(dir, "rev.st",
               R"({"a":{"dtype":"F32","shape":[0],"data_offsets":[8,0]}})", 8),
      "end < begin");
  ExpectRejected(
      WriteRaw(dir, "dup.st",
               R"({"a":{"dtype":"F32","shape":[1],"data_offsets":[0,4]},)"
               R"("a":{"dtype":"F32","shape":[1],"data_offsets":[4,8]}})",
               8),
      "duplicate tensor name 'a'");
  ExpectRejected(
      WriteRaw(dir, "missing.st", R"({"a":{"dtype":"F32","shape":[2]}})", 8),
      "data_offsets");
  ExpectRejected(WriteRaw(dir, "meta.st", R"({"__metadata__":{"k":1}})", 0),
                 "__metadata__");
  ExpectRejected(dir + "/does_not_exist.safetensors", "cannot open");
}

TEST(Safetensors, ShardedIndexLoadsAndValidates) {
  const std::string dir = test::MakeTempDir("safetensors_sharded");
  at::manual_seed(3);
  at::Tensor w1 = at::randn({3, 2}), w2 = at::randn({4}),
             w3 = at::randn({1, 2, 2});
  SaveSafetensors(dir + "/m-00001-of-00002.safetensors",
                  {{"x.weight", w1}, {"x.bias", w2}});
  SaveSafetensors(dir + "/m-00002-of-00002.safetensors", {{"y.weight", w3}});
  const std::string index = dir + "/m.safetensors.index.json";
  std::ofstream(index) << R"({"metadata": {"total_size": 64}, "weight_map": {)"
                       << R"("x.weight": "m-00001-of-00002.safetensors",)"
                       << R"("x.bias": "m-00001-of-00002.safetensors",)"
                       << R"("y.weight": "m-00002-of-00002.safetensors"}})";
  SafetensorsCheckpoint ckpt(index);
  EXPECT_TRUE(ckpt.sharded());
  ASSERT_EQ(ckpt.entries().size(), 3u);
  EXPECT_EQ(ckpt.Entry("y.weight").shape, (std::vector<int64_t>{1, 2, 2}));
  EXPECT_TRUE(at::equal(ckpt.Load("x.weight"), w1));
  EXPECT_TRUE(at::equal(ckpt.Load("y.weight"), w3));
  EXPECT_EQ(LoadSafetensors(index).size(), 3u);

  auto expect_bad = [&](const std::string& name, const std::string& body,
                        const std::string& needle) {
    const std::string p = dir + "/" + name;
    std::ofstream(p) << body;
    try {
      SafetensorsCheckpoint c(p);
      ADD_FAILURE() << name << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
          << e.what();
    }
  };
  expect_bad("a.index.json",
             R"({"weight_map": {"z": "m-00001-of-00002.safetensors"}})",
             "has no such tensor");
  expect_bad("b.index.json", R"({"weight_map": {"x.bias": "../etc/passwd"}})",
             "not a file next to the index");
  expect_bad("c.index.json", R"({"weight_map": [1]})", "weight_map");
  expect_bad("d.index.json", R"({"weight_map": )", "not valid JSON");
  expect_bad("e.index.json",
             R"({"weight_map": {"x.bias": "gone.safetensors"}})",
             "cannot open");
}

TEST(Safetensors, WriterRejectsDuplicatesAndUnsupportedDtypes) {
  const std::string dir = test::MakeTempDir("safetensors_writer");
  EXPECT_THROW(SaveSafetensors(dir + "/d.safetensors",
                               {{"a", at::ones({1})}, {"a", at::ones({1})}}),
               InputError);
  EXPECT_THROW(SaveSafetensors(dir + "/c.safetensors",
                               {{"a", at::ones({1}, at::kComplexFloat)}}),
               InputError);
}

}  // namespace
}  // namespace diffusion
}  // namespace geodrive

// Tests of the .npy reader/writer: layouts, conversions, every error path, and
// a two-way cross-check against numpy itself
// (tests/geometry/npy_numpy_crosscheck.py).

#include "geometry/npy.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

namespace fs = std::filesystem;

const NpyDtype kAllDtypes[] = {NpyDtype::kFloat32, NpyDtype::kFloat64,
                               NpyDtype::kUint8,   NpyDtype::kBool,
                               NpyDtype::kInt32,   NpyDtype::kInt64,
                               NpyDtype::kUint16,  NpyDtype::kFloat16};

// The value pattern of npy_numpy_crosscheck.py's expected(): a function of the
// C-order index.
NpyArray PatternArray(NpyDtype dtype, const std::vector<int64_t>& shape) {
  NpyArray a = NpyArray::Zeros(dtype, shape);
  const int64_t n = a.NumElements();
  for (int64_t i = 0; i < n; ++i) {
    uint8_t* p = a.bytes.data() + i * NpyDtypeSize(dtype);
    switch (dtype) {
      case NpyDtype::kFloat32: {
        const float v = static_cast<float>(i * 0.25 - 7.0);
        std::memcpy(p, &v, 4);
        break;
      }
      case NpyDtype::kFloat64: {
        const double v = i * 0.25 - 7.0;
        std::memcpy(p, &v, 8);
        break;
      }
      case NpyDtype::kUint8:
        *p = static_cast<uint8_t>(i % 251);
        break;
      case NpyDtype::kBool:
        *p = i % 3 == 0;
        break;
      case NpyDtype::kInt32: {
        const int32_t v = static_cast<int32_t>(i * 1000 - 123456);
        std::memcpy(p, &v, 4);
        break;
      }
      case NpyDtype::kInt64: {
        const int64_t v = i * (int64_t{1} << 33) - 5;
        std::memcpy(p, &v, 8);
        break;
      }
      case NpyDtype::kUint16: {
        const uint16_t v = static_cast<uint16_t>((i * 257) % 65536);
        std::memcpy(p, &v, 2);
        break;
      }
      case NpyDtype::kFloat16: {
        // i * 0.25 - 7 is exact in binary16 for |i| < 2^10.
        const uint16_t v = Eigen::numext::bit_cast<uint16_t>(
            Eigen::half(static_cast<float>(i * 0.25 - 7.0)));
        std::memcpy(p, &v, 2);
        break;
      }
    }
  }
  return a;
}

// A v1 .npy file with the given header dict (padded like numpy) followed by
// `data`.
std::string MakeNpy(const std::string& dict,
                    const std::string& data,
                    int version = 1) {
  const size_t prefix = version == 1 ? 10 : 12;
  std::string header = dict;
  while ((prefix + header.size() + 1) % 64 != 0) header += ' ';
  header += '\n';
  std::string out =
      std::string("\x93NUMPY", 6) + static_cast<char>(version) + '\0';
  out += static_cast<char>(header.size() & 0xff);
  out += static_cast<char>(header.size() >> 8);
  if (version > 1) out += std::string(2, '\0');
  return out + header + data;
}

// Message of the InputError thrown by ReadNpy(path) ("" if none).
std::string ReadError(const std::string& path,
                      const NpyReadOptions& options = {}) {
  try {
    ReadNpy(path, options);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

using ::testing::HasSubstr;
using ::testing::StartsWith;

TEST(Npy, DtypeSizesAndDescriptors) {
  EXPECT_EQ(NpyDtypeSize(NpyDtype::kFloat32), 4u);
  EXPECT_EQ(NpyDtypeSize(NpyDtype::kFloat64), 8u);
  EXPECT_EQ(NpyDtypeSize(NpyDtype::kUint8), 1u);
  EXPECT_EQ(NpyDtypeSize(NpyDtype::kBool), 1u);
  EXPECT_EQ(NpyDtypeSize(NpyDtype::kInt32), 4u);
  EXPECT_EQ(NpyDtypeSize(NpyDtype::kInt64), 8u);
  EXPECT_EQ(NpyDtypeSize(NpyDtype::kUint16), 2u);
  EXPECT_EQ(NpyDtypeDescr(NpyDtype::kFloat32), "<f4");
  EXPECT_EQ(NpyDtypeDescr(NpyDtype::kBool), "|b1");
  EXPECT_EQ(NpyDtypeDescr(NpyDtype::kUint8), "|u1");
  EXPECT_EQ(NpyDtypeDescr(NpyDtype::kUint16), "<u2");
}

TEST(Npy, WritesNumpyHeaderByteForByte) {
  // np.save(np.zeros((288, 512), np.float32)) with numpy 1.24: the dict, 18
  // spaces of growth room (21 - len("288")), padding to a 64-byte boundary,
  // '\n'; data at offset 128.
  const std::string dir = test::MakeTempDir("npy_header");
  const std::string path = dir + "/frame.npy";
  WriteNpy(path, NpyArray::Zeros(NpyDtype::kFloat32, {288, 512}));
  const std::string bytes = test::ReadFile(path);
  ASSERT_EQ(bytes.size(), 128u + 288 * 512 * 4);
  std::string dict =
      "{'descr': '<f4', 'fortran_order': False, 'shape': (288, 512), }";
  dict += std::string(117 - dict.size(), ' ') + "\n";
  EXPECT_EQ(bytes.substr(0, 10), std::string("\x93NUMPY\x01\x00\x76\x00", 10));
  EXPECT_EQ(bytes.substr(10, 118), dict);
}

TEST(Npy, RoundTripsEveryDtypeInCOrder) {
  const std::string dir = test::MakeTempDir("npy_roundtrip");
  for (NpyDtype dtype : kAllDtypes) {
    const NpyArray a = PatternArray(dtype, {3, 5});
    const std::string path =
        dir + "/" + std::to_string(static_cast<int>(dtype)) + ".npy";
    WriteNpy(path, a);
    const NpyArray b = ReadNpy(path);
    EXPECT_EQ(b.dtype, dtype);
    EXPECT_EQ(b.shape, a.shape);
    EXPECT_EQ(b.bytes, a.bytes) << NpyDtypeDescr(dtype);
  }
}

TEST(Npy, RoundTripsAllLayoutsAndVersions) {
  const std::string dir = test::MakeTempDir("npy_layouts");
  int files = 0;
  for (NpyDtype dtype : kAllDtypes) {
    for (int version = 1; version <= 3; ++version) {
      for (bool fortran : {false, true}) {
        for (bool big : {false, true}) {
          const NpyArray a = PatternArray(dtype, {2, 3, 4});
          NpyWriteOptions options;
          options.major_version = version;
          options.fortran_order = fortran;
          options.big_endian = big;
          const std::string path =
              dir + "/a" + std::to_string(files++) + ".npy";
          WriteNpy(path, a, options);
          const NpyHeader h = ReadNpyHeader(path);
          EXPECT_EQ(h.major_version, version);
          EXPECT_EQ(h.fortran_order, fortran);
          EXPECT_EQ(h.big_endian, big && NpyDtypeSize(dtype) > 1);
          EXPECT_EQ(h.data_offset % 64, 0u);
          const NpyArray b = ReadNpy(path);
          EXPECT_EQ(b.shape, a.shape);
          EXPECT_EQ(b.bytes, a.bytes)
              << NpyDtypeDescr(dtype) << " v" << version
              << (fortran ? " F" : " C") << (big ? " BE" : " LE");
        }
      }
    }
  }
  EXPECT_EQ(files, 8 * 3 * 2 * 2);
}

TEST(Npy, ReadsHandMadeFortranOrderFile) {
  // [[1, 2, 3], [4, 5, 6]] stored column-major: 1 4 2 5 3 6.
  const int32_t column_major[] = {1, 4, 2, 5, 3, 6};
  const std::string path = test::MakeTempDir("npy_fortran") + "/f.npy";
  test::WriteFile(
      path,
      MakeNpy("{'descr': '<i4', 'fortran_order': True, 'shape': (2, 3), }",
              std::string(reinterpret_cast<const char*>(column_major), 24)));
  const NpyArray a = ReadNpy(path);
  ASSERT_EQ(a.shape, (std::vector<int64_t>{2, 3}));
  const int32_t* v = a.Data<int32_t>();
  for (int i = 0; i < 6; ++i) EXPECT_EQ(v[i], i + 1);
}

TEST(Npy, ReadsHandMadeBigEndianFile) {
  // 1.5f = 0x3FC00000 and -2.0f = 0xC0000000, big-endian; 258 as >u2 = 01 02.
  const std::string dir = test::MakeTempDir("npy_big");
  test::WriteFile(
      dir + "/f.npy",
      MakeNpy("{'descr': '>f4', 'fortran_order': False, 'shape': (2,), }",
              std::string("\x3F\xC0\x00\x00\xC0\x00\x00\x00", 8)));
  const NpyArray f = ReadNpy(dir + "/f.npy");
  EXPECT_EQ(f.Data<float>()[0], 1.5f);
  EXPECT_EQ(f.Data<float>()[1], -2.0f);
  test::WriteFile(
      dir + "/u.npy",
      MakeNpy("{'descr': '>u2', 'fortran_order': False, 'shape': (1,), }",
              std::string("\x01\x02", 2)));
  EXPECT_EQ(ReadNpy(dir + "/u.npy").Data<uint16_t>()[0], 258);
}

TEST(Npy, ZeroDimensionalAndEmptyArrays) {
  const std::string dir = test::MakeTempDir("npy_edge");
  const double pi = 3.141592653589793;
  WriteNpy(dir + "/scalar.npy", NpyArray::Float64({}, &pi));
  const NpyArray s = ReadNpy(dir + "/scalar.npy");
  EXPECT_TRUE(s.shape.empty());
  EXPECT_EQ(s.NumElements(), 1);
  EXPECT_EQ(s.Data<double>()[0], pi);
  EXPECT_EQ(test::ReadFile(dir + "/scalar.npy").substr(10, 55),
            "{'descr': '<f8', 'fortran_order': False, 'shape': (), }");

  for (const std::vector<int64_t>& shape :
       {std::vector<int64_t>{0}, std::vector<int64_t>{0, 3},
        std::vector<int64_t>{4, 0, 2}}) {
    WriteNpy(dir + "/empty.npy", NpyArray::Zeros(NpyDtype::kInt64, shape),
             NpyWriteOptions{2, true, true});
    const NpyArray e = ReadNpy(dir + "/empty.npy");
    EXPECT_EQ(e.shape, shape);
    EXPECT_EQ(e.NumElements(), 0);
    EXPECT_TRUE(e.bytes.empty());
  }
}

TEST(Npy, BoolValuesAreNormalisedToZeroOrOne) {
  const std::string path = test::MakeTempDir("npy_bool") + "/b.npy";
  test::WriteFile(
      path, MakeNpy("{'descr': '|b1', 'fortran_order': False, 'shape': (3,), }",
                    std::string("\x00\x01\x07", 3)));
  const NpyArray a = ReadNpy(path);
  EXPECT_EQ(a.dtype, NpyDtype::kBool);
  EXPECT_EQ(a.bytes, (std::vector<uint8_t>{0, 1, 1}));
  EXPECT_EQ(a.Data<uint8_t>()[2], 1);  // bool reads as uint8_t
}

TEST(Npy, ReadAsFloat32ConvertsEveryDtype) {
  const std::string dir = test::MakeTempDir("npy_asfloat");
  for (NpyDtype dtype : kAllDtypes) {
    const NpyArray a = PatternArray(dtype, {6});
    WriteNpy(dir + "/a.npy", a, NpyWriteOptions{1, false, true});
    const NpyArray f = ReadNpyAsFloat32(dir + "/a.npy");
    ASSERT_EQ(f.dtype, NpyDtype::kFloat32);
    ASSERT_EQ(f.shape, a.shape);
    for (int i = 0; i < 6; ++i) {
      double want = 0;
      switch (dtype) {
        case NpyDtype::kFloat32:
        case NpyDtype::kFloat64:
        case NpyDtype::kFloat16:
          want = i * 0.25 - 7.0;
          break;
        case NpyDtype::kUint8:
          want = i % 251;
          break;
        case NpyDtype::kBool:
          want = i % 3 == 0;
          break;
        case NpyDtype::kInt32:
          want = i * 1000 - 123456;
          break;
        case NpyDtype::kInt64:
          want = static_cast<float>(i * (int64_t{1} << 33) - 5);
          break;
        case NpyDtype::kUint16:
          want = (i * 257) % 65536;
          break;
      }
      EXPECT_EQ(f.Data<float>()[i], static_cast<float>(want))
          << NpyDtypeDescr(dtype) << " " << i;
    }
  }
}

TEST(Npy, TypedAccessRejectsWrongDtype) {
  const NpyArray a = NpyArray::Zeros(NpyDtype::kFloat32, {2});
  EXPECT_NO_THROW(a.Data<float>());
  EXPECT_THROW(a.Data<double>(), InputError);
  EXPECT_THROW(a.Data<uint8_t>(), InputError);
}

TEST(Npy, WriteReplacesFileAtomicallyAndLeavesNoTemporaries) {
  const std::string dir = test::MakeTempDir("npy_atomic");
  const float one = 1.f, two = 2.f;
  WriteNpy(dir + "/x.npy", NpyArray::Float32({1}, &one));
  WriteNpy(dir + "/x.npy", NpyArray::Float32({1}, &two));
  EXPECT_EQ(ReadNpy(dir + "/x.npy").Data<float>()[0], 2.f);
  int entries = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    ++entries;
    EXPECT_EQ(entry.path().filename(), "x.npy");
  }
  EXPECT_EQ(entries, 1);
}

TEST(Npy, WriteErrorsNameTheFile) {
  const std::string dir = test::MakeTempDir("npy_write_errors");
  const std::string missing_dir = dir + "/no/such/dir/a.npy";
  try {
    WriteNpy(missing_dir, NpyArray::Zeros(NpyDtype::kUint8, {2}));
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), StartsWith(missing_dir + ": cannot write"));
  }
  NpyArray bad = NpyArray::Zeros(NpyDtype::kFloat32, {4});
  bad.bytes.resize(3);
  EXPECT_THROW(WriteNpy(dir + "/bad.npy", bad), InputError);
  EXPECT_THROW(
      WriteNpy(dir + "/v4.npy", NpyArray::Zeros(NpyDtype::kFloat32, {1}),
               NpyWriteOptions{4, false, false}),
      InputError);
  EXPECT_FALSE(fs::exists(dir + "/bad.npy"));
}

TEST(Npy, MissingFileSaysCannotOpen) {
  const std::string path = test::MakeTempDir("npy_missing") + "/missing.npy";
  EXPECT_EQ(ReadError(path),
            path + ": cannot open (No such file or directory)");
  EXPECT_THROW(ReadNpyHeader(path), InputError);
}

TEST(Npy, TruncatedDataNamesFileAndSizes) {
  const std::string path = test::MakeTempDir("npy_truncated") + "/frame.npy";
  test::WriteFile(
      path,
      MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (480, 640), }",
              std::string(100, '\0')));
  EXPECT_EQ(
      ReadError(path),
      path + ": truncated: header says 1228800 bytes of data, file has 100");
  // The header alone is still readable (what `geodrive info` prints first).
  EXPECT_EQ(ReadNpyHeader(path).shape, (std::vector<int64_t>{480, 640}));
}

TEST(Npy, TruncatedHeaderAndPreamble) {
  const std::string dir = test::MakeTempDir("npy_trunc_header");
  const std::string full =
      MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (2,), }",
              std::string(8, '\0'));
  test::WriteFile(dir + "/a.npy", full.substr(0, 40));
  EXPECT_THAT(ReadError(dir + "/a.npy"), StartsWith(dir + "/a.npy: truncated"));
  test::WriteFile(dir + "/b.npy", full.substr(0, 8));
  EXPECT_THAT(ReadError(dir + "/b.npy"), StartsWith(dir + "/b.npy: truncated"));
}

TEST(Npy, BadMagicSaysNotNpy) {
  const std::string dir = test::MakeTempDir("npy_magic");
  test::WriteFile(dir + "/text.npy", "hello, this is not numpy data at all\n");
  EXPECT_THAT(ReadError(dir + "/text.npy"),
              StartsWith(dir + "/text.npy: not a .npy file"));
  test::WriteFile(dir + "/empty.npy", "");
  EXPECT_THAT(ReadError(dir + "/empty.npy"),
              StartsWith(dir + "/empty.npy: not a .npy file"));
}

TEST(Npy, UnsupportedVersionIsRejected) {
  const std::string path = test::MakeTempDir("npy_version") + "/v9.npy";
  std::string bytes =
      MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (1,), }",
              std::string(4, '\0'));
  bytes[6] = 9;
  test::WriteFile(path, bytes);
  EXPECT_THAT(ReadError(path),
              HasSubstr(": unsupported .npy format version 9.0"));
}

TEST(Npy, BadHeaderDictsAreRejected) {
  const std::string dir = test::MakeTempDir("npy_bad_dict");
  const char* dicts[] = {
      "{'descr': '<f4', 'fortran_order': False}",  // missing shape
      "{'descr': '<f4', 'shape': (2,), }",         // missing fortran_order
      "{'descr': '<f4', 'fortran_order': Maybe, 'shape': (2,), }",  // not a
                                                                    // bool
      "{'descr': '<f4', 'fortran_order': False, 'shape': (2, x), }",  // non-numeric
                                                                      // dim
      "{'descr': '<f4', 'fortran_order': False, 'shape': (2), }",  // (2) is not
                                                                   // a tuple
      "{'descr': '<f4', 'fortran_order': False, 'shape': (2,), 'x': 1}",  // unknown
                                                                          // key
      "{'descr': '<f4', 'fortran_order': False, 'shape': (2,), } trailing",
      "['descr', '<f4']",                                          // not a dict
      "{'descr: '<f4', 'fortran_order': False, 'shape': (2,), }",  // broken
                                                                   // quoting
      "{'descr': '<f4', 'descr': '<f4', 'fortran_order': False, 'shape': (2,), "
      "}",
      "{'descr': '<f4', 'fortran_order': False, 'shape': (-2,), }",  // negative
                                                                     // dim
  };
  int i = 0;
  for (const char* dict : dicts) {
    const std::string path = dir + "/d" + std::to_string(i++) + ".npy";
    test::WriteFile(path, MakeNpy(dict, std::string(8, '\0')));
    EXPECT_THAT(ReadError(path), StartsWith(path + ": bad header dict: "))
        << dict;
  }
}

TEST(Npy, AcceptsNumpyDialectsOfTheHeader) {
  // Keys in any order, double quotes, Python 2 'L' suffixes, no trailing comma,
  // v2 preamble.
  const std::string dir = test::MakeTempDir("npy_dialects");
  test::WriteFile(
      dir + "/a.npy",
      MakeNpy(
          "{\"shape\": (2L, 1L), \"fortran_order\": False, \"descr\": \"<u2\"}",
          std::string("\x05\x00\x06\x00", 4), 2));
  const NpyArray a = ReadNpy(dir + "/a.npy");
  EXPECT_EQ(a.shape, (std::vector<int64_t>{2, 1}));
  EXPECT_EQ(a.Data<uint16_t>()[1], 6);
}

TEST(Npy, UnsupportedDtypesAreRejected) {
  const std::string dir = test::MakeTempDir("npy_dtype");
  const char* descrs[] = {"<c8", "<U10", "|O", "<i2", "<M8[ns]"};
  for (const char* descr : descrs) {
    const std::string path = dir + "/t.npy";
    test::WriteFile(path,
                    MakeNpy(std::string("{'descr': '") + descr +
                                "', 'fortran_order': False, 'shape': (1,), }",
                            std::string(16, '\0')));
    EXPECT_THAT(ReadError(path),
                StartsWith(path + ": unsupported dtype '" + descr + "'"));
  }
  const std::string path = dir + "/structured.npy";
  test::WriteFile(
      path,
      MakeNpy("{'descr': [('x', '<f4'), ('y', '<f4')], 'fortran_order': False, "
              "'shape': (1,), }",
              std::string(8, '\0')));
  EXPECT_THAT(ReadError(path), StartsWith(path + ": unsupported dtype"));
}

// Found by fuzz_npy (UBSan: signed overflow in NumElements): a zero axis
// after axes whose product passes 2^63 is an empty array, in C and in
// Fortran order, read as is and as float32.
TEST(Npy, EmptyArrayWithHugeOtherAxes) {
  const std::string dir = test::MakeTempDir("npy_empty_huge");
  const std::vector<int64_t> shape = {4,   32, 64, 2,      364, 32, 64, 2,
                                      366, 66, 2,  366632, 0,   34, 6};
  for (const char* order : {"False", "True"}) {
    test::WriteFile(
        dir + "/e.npy",
        MakeNpy(std::string("{'descr': '<f8', 'fortran_order': ") + order +
                    ", 'shape': (4, 32 ,64, 2, 364, 32 ,64, 2, 366,66, "
                    "2, 366632 ,00000, 34, 6), }",
                ""));
    const NpyArray a = ReadNpy(dir + "/e.npy");
    EXPECT_EQ(a.shape, shape) << order;
    EXPECT_EQ(a.NumElements(), 0) << order;
    const NpyArray f = ReadNpyAsFloat32(dir + "/e.npy");
    EXPECT_EQ(f.dtype, NpyDtype::kFloat32);
    EXPECT_EQ(f.shape, shape);
    EXPECT_TRUE(f.bytes.empty());
  }
}

TEST(Npy, ShapeAndSizeOverflowAreRejected) {
  const std::string dir = test::MakeTempDir("npy_overflow");
  test::WriteFile(dir + "/a.npy",
                  MakeNpy("{'descr': '<f8', 'fortran_order': False, "
                          "'shape': (99999999999999999999,), }",
                          ""));
  EXPECT_THAT(ReadError(dir + "/a.npy"),
              StartsWith(dir + "/a.npy: shape overflows"));
  test::WriteFile(dir + "/b.npy",
                  MakeNpy("{'descr': '<f8', 'fortran_order': False, 'shape': "
                          "(4294967296, 4294967296), }",
                          ""));
  EXPECT_THAT(ReadError(dir + "/b.npy"),
              StartsWith(dir + "/b.npy: shape overflows"));
  test::WriteFile(dir + "/c.npy",
                  MakeNpy("{'descr': '<f8', 'fortran_order': False, 'shape': "
                          "(2305843009213693952,), }",
                          ""));  // 2^61 elements x 8 bytes = 2^64 bytes
  EXPECT_THAT(ReadError(dir + "/c.npy"),
              StartsWith(dir + "/c.npy: size overflows"));
}

TEST(Npy, AbsurdSizesExceedMaxBytes) {
  const std::string path = test::MakeTempDir("npy_absurd") + "/huge.npy";
  // 1e6 x 1e6 float32 = 4 TB: refused before any allocation.
  test::WriteFile(path,
                  MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': "
                          "(1000000, 1000000), "
                          "}",
                          std::string(64, '\0')));
  EXPECT_THAT(ReadError(path),
              StartsWith(path + ": array of 4000000000000 bytes"));
  EXPECT_THAT(ReadError(path),
              HasSubstr("exceeds the limit of 8589934592 bytes"));
  // A small custom limit applies too.
  const float data[4] = {1, 2, 3, 4};
  WriteNpy(path, NpyArray::Float32({4}, data));
  NpyReadOptions options;
  options.max_bytes = 15;
  EXPECT_THAT(ReadError(path, options),
              HasSubstr("exceeds the limit of 15 bytes"));
  options.max_bytes = 16;
  EXPECT_EQ(ReadError(path, options), "");
}

TEST(Npy, DirectoryIsNotAFile) {
  const std::string dir = test::MakeTempDir("npy_dir");
  EXPECT_THAT(ReadError(dir), StartsWith(dir + ": is a directory"));
}

// ---- Cross-check against numpy ----

std::vector<int64_t> ParseShape(const std::string& text) {
  std::vector<int64_t> shape;
  if (text == "scalar") return shape;
  std::stringstream ss(text);
  std::string part;
  while (std::getline(ss, part, 'x')) shape.push_back(std::stoll(part));
  return shape;
}

NpyDtype DtypeFromCode(const std::string& code) {
  for (NpyDtype d : kAllDtypes) {
    if (NpyDtypeDescr(d).substr(1) == code) return d;
  }
  ADD_FAILURE() << "unknown code " << code;
  return NpyDtype::kFloat32;
}

std::string CrosscheckScript() {
  return std::string(GEODRIVE_SOURCE_DIR) +
         "/tests/geometry/npy_numpy_crosscheck.py";
}

TEST(NpyNumpy, ReadsEveryFileNumpyWrites) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("numpy");
  const std::string dir = test::MakeTempDir("npy_from_numpy");
  std::string out;
  ASSERT_EQ(test::RunCommand(std::string(test::kDebianPython) + " " +
                                 CrosscheckScript() + " write " + dir,
                             &out),
            0)
      << out;
  std::ifstream manifest(dir + "/manifest.txt");
  std::string name, descr, order, shape_text;
  int version = 0, files = 0;
  while (manifest >> name >> descr >> order >> version >> shape_text) {
    SCOPED_TRACE(name);
    const std::vector<int64_t> shape = ParseShape(shape_text);
    const NpyDtype dtype = DtypeFromCode(descr.substr(1));
    const NpyHeader header = ReadNpyHeader(dir + "/" + name);
    EXPECT_EQ(header.major_version, version);
    EXPECT_EQ(header.big_endian, descr[0] == '>');
    EXPECT_EQ(header.shape, shape);
    const NpyArray a = ReadNpy(dir + "/" + name);
    EXPECT_EQ(a.dtype, dtype);
    EXPECT_EQ(a.shape, shape);
    EXPECT_EQ(a.bytes, PatternArray(dtype, shape).bytes);
    ++files;
  }
  // 7 dtypes x 6 shapes, F order only for 3 of the shapes, BE only for 5
  // dtypes, 3 versions.
  EXPECT_EQ(files, 324);
  std::cout << "read " << files << " files written by numpy\n";
}

TEST(NpyNumpy, NumpyLoadsEveryFileWeWrite) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("numpy");
  const std::string dir = test::MakeTempDir("npy_to_numpy");
  const std::vector<std::vector<int64_t>> shapes = {{},  {0},    {0, 3},
                                                    {7}, {3, 4}, {2, 3, 4}};
  std::ofstream manifest(dir + "/manifest.txt");
  int files = 0;
  for (NpyDtype dtype : kAllDtypes) {
    for (const auto& shape : shapes) {
      for (bool fortran : {false, true}) {
        if (fortran && shape.size() < 2) continue;
        for (bool big : {false, true}) {
          if (big && NpyDtypeSize(dtype) == 1) continue;
          for (int version = 1; version <= 3; ++version) {
            std::string shape_text = shape.empty() ? "scalar" : "";
            for (size_t k = 0; k < shape.size(); ++k) {
              shape_text += (k ? "x" : "") + std::to_string(shape[k]);
            }
            std::string descr = NpyDtypeDescr(dtype);
            if (big) descr[0] = '>';
            const std::string name = descr.substr(1) + (fortran ? "_F" : "_C") +
                                     (big ? "_be" : "_le") + "_v" +
                                     std::to_string(version) + "_" +
                                     shape_text + ".npy";
            WriteNpy(dir + "/" + name, PatternArray(dtype, shape),
                     NpyWriteOptions{version, fortran, big});
            manifest << name << " " << descr << " " << (fortran ? "F" : "C")
                     << " " << version << " " << shape_text << "\n";
            ++files;
          }
        }
      }
    }
  }
  manifest.close();
  EXPECT_EQ(files, 378);
  std::string out;
  const int rc = test::RunCommand(std::string(test::kDebianPython) + " " +
                                      CrosscheckScript() + " check " + dir,
                                  &out);
  EXPECT_EQ(rc, 0) << out;
  EXPECT_THAT(out, HasSubstr("checked 378 files"));
  std::cout << out;
}

}  // namespace
}  // namespace geodrive

// Large ASCII PLY and PCD files, which the readers parse in chunks on
// OpenMP's threads (files of 2 MB and more): the same cloud, and the same
// error for the same bad line, on 1 thread as on 4; blank lines, CRLF line
// ends, a leading '+', and both the fast layouts (float32 x y z, uchar
// colours, packed rgb) and the general one (double positions); and files of
// 32 MiB and more, read in parts on several threads.

#include <gtest/gtest.h>
#include <omp.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "geometry/point_cloud_io.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace point_cloud_io_ascii_test {
namespace {

std::string ErrorOf(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// Runs fn with OpenMP's default thread count set to `threads`.
template <typename Fn>
auto WithThreads(int threads, Fn fn) {
  const int before = omp_get_max_threads();
  omp_set_num_threads(threads);
  auto result = fn();
  omp_set_num_threads(before);
  return result;
}

// The rows of a large cloud as text ("%.9g" positions round-trip float32),
// with blank lines and CRLF ends sprinkled in; `line_of` gets each row's
// 1-based line number counted from the first data line.
struct AsciiRows {
  std::string text;
  PointCloud cloud;
  std::vector<size_t> line_of;
};

AsciiRows MakeRows(size_t n, bool packed_rgb) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> pos(-80.f, 80.f);
  AsciiRows rows;
  size_t line = 0;
  char buf[128];
  for (size_t i = 0; i < n; ++i) {
    if (rng() % 500 == 0) {
      rows.text += rng() % 2 ? "\n" : " \t\r\n";
      ++line;
    }
    const Eigen::Vector3f p(pos(rng), pos(rng), pos(rng));
    const Color3u8 c(rng() % 256, rng() % 256, rng() % 256);
    rows.cloud.positions.push_back(p);
    rows.cloud.colors.push_back(c);
    const char* plus = rng() % 50 == 0 && p.x() >= 0 ? "+" : "";
    if (packed_rgb) {
      const unsigned rgb =
          (unsigned{c[0]} << 16) | (unsigned{c[1]} << 8) | c[2];
      std::snprintf(buf, sizeof buf, "%s%.9g %.9g %.9g %u", plus, p.x(), p.y(),
                    p.z(), rgb);
    } else {
      std::snprintf(buf, sizeof buf, "%s%.9g %.9g %.9g %d %d %d", plus, p.x(),
                    p.y(), p.z(), c[0], c[1], c[2]);
    }
    rows.text += buf;
    rows.text += rng() % 7 == 0 ? "\r\n" : "\n";
    rows.line_of.push_back(++line);
  }
  return rows;
}

std::string PlyHeader(size_t n, const char* type, bool faces) {
  const std::string t = type;
  return "ply\nformat ascii 1.0\nelement vertex " + std::to_string(n) +
         "\nproperty " + t + " x\nproperty " + t + " y\nproperty " + t +
         " z\nproperty uchar red\nproperty uchar green\nproperty uchar "
         "blue\n" +
         (faces ? "element face 2\nproperty list uchar int vertex_indices\n"
                : "") +
         "end_header\n";
}
constexpr size_t kPlyHeaderLines = 10;  // without the face element

void ExpectSame(const PointCloud& a, const PointCloud& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a.positions[i], b.positions[i]) << i;
    ASSERT_EQ(a.colors[i], b.colors[i]) << i;
  }
}

TEST(AsciiChunks, LargePlySameCloudOnOneOrFourThreads) {
  const std::string dir = test::MakeTempDir("ascii_chunks_ply");
  const size_t n = 70000;  // about 3 MB of rows
  const AsciiRows rows = MakeRows(n, false);
  for (const char* type : {"float", "double"}) {
    const std::string path = dir + "/" + type + ".ply";
    test::WriteFile(
        path, PlyHeader(n, type, true) + rows.text + "3 0 1 2\n\n3 2 1 0\n");
    ASSERT_GT(rows.text.size(), size_t{2} << 20);
    const PointCloud one = WithThreads(1, [&] { return ReadPly(path); });
    const PointCloud four = WithThreads(4, [&] { return ReadPly(path); });
    ExpectSame(rows.cloud, one);
    ExpectSame(rows.cloud, four);
    // A face line too many: found after the chunked vertex rows.
    test::WriteFile(path, PlyHeader(n, type, true) + rows.text +
                              "3 0 1 2\n3 2 1 0\n3 1 1 1\n");
    const std::string e1 =
        WithThreads(1, [&] { return ErrorOf([&] { ReadPly(path); }); });
    const std::string e4 =
        WithThreads(4, [&] { return ErrorOf([&] { ReadPly(path); }); });
    const size_t last = kPlyHeaderLines + 2 + rows.line_of.back() + 3;
    EXPECT_EQ(e1, path + ": line " + std::to_string(last) +
                      ": unexpected data after the last element ('3 1 1 1')");
    EXPECT_EQ(e4, e1);
  }
}

TEST(AsciiChunks, FirstBadRowIsReportedWhateverTheThreads) {
  const std::string dir = test::MakeTempDir("ascii_chunks_bad");
  const size_t n = 70000;
  AsciiRows rows = MakeRows(n, false);
  // Two bad values, in rows that land in later chunks: the first one is
  // the error.
  auto spoil = [&](size_t row, const std::string& bad) {
    size_t at = 0;
    for (size_t line = 0; line + 1 < rows.line_of[row]; ++line)
      at = rows.text.find('\n', at) + 1;
    const size_t space = rows.text.find(' ', at);
    rows.text.replace(space + 1, rows.text.find(' ', space + 1) - space - 1,
                      bad);
  };
  spoil(61000, "abc");
  spoil(30000, "1e99");
  const std::string path = dir + "/bad.ply";
  test::WriteFile(path, PlyHeader(n, "float", false) + rows.text);
  const std::string e1 =
      WithThreads(1, [&] { return ErrorOf([&] { ReadPly(path); }); });
  const std::string e4 =
      WithThreads(4, [&] { return ErrorOf([&] { ReadPly(path); }); });
  EXPECT_EQ(e1, path + ": line " +
                    std::to_string(kPlyHeaderLines + rows.line_of[30000]) +
                    ": value '1e99' is out of range for property 'y' (float)");
  EXPECT_EQ(e4, e1);
  // Truncated: two rows fewer than declared.
  const AsciiRows good = MakeRows(n, false);
  test::WriteFile(path, PlyHeader(n + 2, "float", false) + good.text);
  const std::string t1 =
      WithThreads(1, [&] { return ErrorOf([&] { ReadPly(path); }); });
  const std::string t4 =
      WithThreads(4, [&] { return ErrorOf([&] { ReadPly(path); }); });
  EXPECT_EQ(t1, path +
                    ": truncated: the file ends after 70000 of 70002 "
                    "'vertex' lines");
  EXPECT_EQ(t4, t1);
}

TEST(AsciiChunks, LargePcdSameCloudOnOneOrFourThreads) {
  const std::string dir = test::MakeTempDir("ascii_chunks_pcd");
  const size_t n = 70000;
  const AsciiRows rows = MakeRows(n, true);
  const std::string header =
      "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F "
      "U\nCOUNT 1 1 1 1\nWIDTH " +
      std::to_string(n) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " +
      std::to_string(n) + "\nDATA ascii\n";
  const std::string path = dir + "/c.pcd";
  test::WriteFile(path, header + rows.text);
  const PointCloud one = WithThreads(1, [&] { return ReadPcd(path); });
  const PointCloud four = WithThreads(4, [&] { return ReadPcd(path); });
  ExpectSame(rows.cloud, one);
  ExpectSame(rows.cloud, four);
  // The cloud as PCD writes it reads back the same on 4 threads.
  WritePcd(dir + "/w.pcd", rows.cloud, /*binary=*/false);
  ExpectSame(rows.cloud,
             WithThreads(4, [&] { return ReadPcd(dir + "/w.pcd"); }));
  // One point too many.
  test::WriteFile(path, header + rows.text + "1 2 3 4\n");
  const std::string e1 =
      WithThreads(1, [&] { return ErrorOf([&] { ReadPcd(path); }); });
  const std::string e4 =
      WithThreads(4, [&] { return ErrorOf([&] { ReadPcd(path); }); });
  EXPECT_EQ(e1, path + ": line " +
                    std::to_string(11 + rows.line_of.back() + 1) +
                    ": unexpected data after the last point ('1 2 3 4')");
  EXPECT_EQ(e4, e1);
}

// Float tokens in the many forms a text cloud can hold read as the float
// std::from_chars gives, bit for bit: the readers take the short decimal form
// through Clinger's fast path and must agree with the correctly rounded
// result everywhere, including float midpoints (2^24 + 1 is halfway between
// two floats), the ends of the normal range, exponents, signed zeros and
// tokens too long for the fast path.
TEST(AsciiChunks, FloatTokensReadAsFromCharsReadsThem) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_int_distribution<int> pow10(-40, 38), digits(1, 19);
  std::vector<std::string> tokens = {"0",
                                     "-0",
                                     "0.0",
                                     "-0.000",
                                     "16777217",
                                     "16777219",
                                     "33554434",
                                     "1.6777217e7",
                                     "0.16777217e8",
                                     "1.17549435e-38",
                                     "1.1754944e-38",
                                     "3.4028234e38",
                                     "3.40282347e+38",
                                     "1e-45",
                                     "1.4e-45",
                                     "7e-39",
                                     "0.1",
                                     "0.2",
                                     "0.3",
                                     "1e22",
                                     "1e23",
                                     "123456789012345678",
                                     "1E5",
                                     "00012.500",
                                     "9007199254740993",
                                     "2.5e-3",
                                     "-7.038531e-26"};
  char buf[64];
  for (int k = 0; k < 60000; ++k) {
    const double v = unit(rng) * std::pow(10.0, pow10(rng));
    const int form = k % 4;
    if (form == 0) {
      std::snprintf(buf, sizeof buf, "%.*g", 1 + k % 9, v);
    } else if (form == 1) {
      std::snprintf(buf, sizeof buf, "%.*g", digits(rng), v);
    } else if (form == 2) {
      std::snprintf(buf, sizeof buf, "%.*f", k % 12, v * 1e-30);
    } else {
      // Midpoints between neighbouring floats, printed with 9-17 digits.
      const float f = static_cast<float>(v);
      const double mid =
          0.5 * (static_cast<double>(f) +
                 static_cast<double>(std::nextafter(f, HUGE_VALF)));
      std::snprintf(buf, sizeof buf, "%.*g", 9 + k % 9, mid);
    }
    tokens.push_back(buf);
  }
  // Only tokens from_chars takes whole (the others are errors, tested
  // elsewhere), three to a row.
  std::vector<float> expected;
  std::string text;
  size_t n = 0;
  for (size_t k = 0; k + 3 <= tokens.size(); k += 3) {
    float v[3];
    bool ok = true;
    for (int j = 0; j < 3; ++j) {
      const std::string& t = tokens[k + j];
      const auto r = std::from_chars(t.data(), t.data() + t.size(), v[j]);
      ok &= r.ec == std::errc() && r.ptr == t.data() + t.size();
    }
    if (!ok) continue;
    expected.insert(expected.end(), v, v + 3);
    text += tokens[k] + " " + tokens[k + 1] + " " + tokens[k + 2] + " 1 2 3\n";
    ++n;
  }
  ASSERT_GT(n, size_t{15000});
  const std::string path =
      test::MakeTempDir("ascii_float_tokens") + "/tokens.ply";
  test::WriteFile(path, PlyHeader(n, "float", false) + text);
  for (int threads : {1, 4}) {
    const PointCloud cloud =
        WithThreads(threads, [&] { return ReadPly(path); });
    ASSERT_EQ(cloud.size(), n);
    for (size_t i = 0; i < n; ++i) {
      for (int j = 0; j < 3; ++j) {
        uint32_t got, want;
        std::memcpy(&got, &cloud.positions[i][j], 4);
        std::memcpy(&want, &expected[3 * i + j], 4);
        ASSERT_EQ(got, want) << "row " << i << " value " << j;
      }
    }
  }
}

// Files of 32 MiB and more are read in 16 MiB parts on OpenMP's threads
// (FileReader::ReadInParallel): a binary PLY read from its first byte and an
// ASCII PCD read on from after its header's first 64 KiB give the cloud that
// was written, on 1 thread and on 4.
TEST(AsciiChunks, FilesOf32MiBAndMoreReadInPartsGiveTheSameCloud) {
  const std::string dir = test::MakeTempDir("large_file_parts");
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> pos(-80.f, 80.f);
  PointCloud cloud;
  const size_t n = 2400000;  // 15 bytes a point in binary PLY: 36 MB
  for (size_t i = 0; i < n; ++i) {
    cloud.positions.emplace_back(pos(rng), pos(rng), pos(rng));
    cloud.colors.push_back(Color3u8(rng() % 256, rng() % 256, rng() % 256));
  }
  WritePly(dir + "/c.ply", cloud, /*binary=*/true);
  ASSERT_GT(std::filesystem::file_size(dir + "/c.ply"), uint64_t{32} << 20);
  ExpectSame(cloud, WithThreads(1, [&] { return ReadPly(dir + "/c.ply"); }));
  ExpectSame(cloud, WithThreads(4, [&] { return ReadPly(dir + "/c.ply"); }));
  PointCloud part;
  part.positions.assign(cloud.positions.begin(),
                        cloud.positions.begin() + 1000000);
  part.colors.assign(cloud.colors.begin(), cloud.colors.begin() + 1000000);
  WritePcd(dir + "/c.pcd", part, /*binary=*/false);
  ASSERT_GT(std::filesystem::file_size(dir + "/c.pcd"), uint64_t{32} << 20);
  ExpectSame(part, WithThreads(1, [&] { return ReadPcd(dir + "/c.pcd"); }));
  ExpectSame(part, WithThreads(4, [&] { return ReadPcd(dir + "/c.pcd"); }));
}

}  // namespace
}  // namespace point_cloud_io_ascii_test
}  // namespace geodrive

// Large ASCII PLY and PCD files, which the readers parse in chunks on
// OpenMP's threads (files of 2 MB and more): the same cloud, and the same
// error for the same bad line, on 1 thread as on 4; blank lines, CRLF line
// ends, a leading '+', and both the fast layouts (float32 x y z, uchar
// colours, packed rgb) and the general one (double positions); and files of
// 32 MiB and more, read in parts on several threads.

#include <gtest/gtest.h>
#include <omp.h>

#include <cstdio>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "geometry/point_cloud_io.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
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
}  // namespace geodrive

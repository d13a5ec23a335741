// Tests of point cloud files: the real nuScenes and KITTI sweeps, .bin round
// trips, PLY / PCD with all optional attributes, foreign layouts (big-endian,
// shuffled properties, lists, binary_compressed), hostile and malformed files,
// the NaN policy, and cross-checks against numpy and Open3D.

#include "geometry/point_cloud_io.h"

#include <gtest/gtest.h>
#include <liblzf/lzf.h>  // Debian's liblzf-dev (geometry links liblzf)

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include "geometry/npy.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace point_cloud_io_test {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::StartsWith;

const char kNuscenesSweep[] =
    "nuscenes_n015/"
    "n015-2018-07-24-11-22-45+0800__LIDAR_TOP__1532402927647951.pcd.bin";
const char kKittiScan[] = "kitti_000008/000008.bin";

template <typename Fn>
std::string ErrorOf(Fn fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// A cloud with every optional attribute filled with random values.
PointCloud RandomCloud(size_t n, bool all_attributes = true) {
  std::uniform_real_distribution<float> pos(-80.f, 80.f), unit(0.f, 1.f);
  std::uniform_int_distribution<int> byte(0, 255), id(-1, 40), ring(0, 31);
  PointCloud cloud;
  for (size_t i = 0; i < n; ++i) {
    cloud.positions.emplace_back(pos(test::Rng()), pos(test::Rng()),
                                 pos(test::Rng()));
    cloud.colors.emplace_back(byte(test::Rng()), byte(test::Rng()),
                              byte(test::Rng()));
    if (!all_attributes) continue;
    cloud.confidence.push_back(unit(test::Rng()));
    cloud.instance_ids.push_back(id(test::Rng()));
    cloud.intensity.push_back(static_cast<float>(byte(test::Rng())));
    cloud.ring.push_back(static_cast<float>(ring(test::Rng())));
  }
  return cloud;
}

void ExpectSameCloud(const PointCloud& a, const PointCloud& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i)
    ASSERT_EQ(a.positions[i], b.positions[i]) << i;
  EXPECT_EQ(a.colors, b.colors);
  EXPECT_EQ(a.confidence, b.confidence);
  EXPECT_EQ(a.instance_ids, b.instance_ids);
  EXPECT_EQ(a.intensity, b.intensity);
  EXPECT_EQ(a.ring, b.ring);
  EXPECT_EQ(a.footprints, b.footprints);
  ASSERT_EQ(a.footprint_u.size(), b.footprint_u.size());
  ASSERT_EQ(a.footprint_v.size(), b.footprint_v.size());
  for (size_t i = 0; i < a.footprint_u.size(); ++i) {
    ASSERT_EQ(a.footprint_u[i], b.footprint_u[i]) << i;
    ASSERT_EQ(a.footprint_v[i], b.footprint_v[i]) << i;
  }
}

std::pair<float, float> MinMax(const std::vector<float>& v) {
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return {*lo, *hi};
}

TEST(NuscenesLidarBin, ReadsRealSweep) {
  // Oracle: numpy.fromfile(path, '<f4').reshape(-1, 5) on the same file.
  const PointCloud cloud =
      ReadNuscenesLidarBin(test::RealDataPath(kNuscenesSweep));
  ASSERT_EQ(cloud.size(), 34688u);
  ASSERT_EQ(cloud.intensity.size(), 34688u);
  ASSERT_EQ(cloud.ring.size(), 34688u);
  EXPECT_FALSE(cloud.HasColors());
  EXPECT_EQ(MinMax(cloud.intensity), std::make_pair(0.f, 255.f));
  EXPECT_EQ(MinMax(cloud.ring), std::make_pair(0.f, 31.f));
  for (float r : cloud.ring) ASSERT_EQ(r, std::round(r));
  const Eigen::AlignedBox3f box = cloud.Bounds();
  EXPECT_THAT(
      box.min(),
      test::EigenNear(Eigen::Vector3f(-57.995846f, -96.290405f, -3.4167116f),
                      1e-5));
  EXPECT_THAT(box.max(),
              test::EigenNear(
                  Eigen::Vector3f(96.852745f, 98.59201f, 19.028015f), 1e-5));
  EXPECT_NO_THROW(cloud.Check());
  std::cout << "nuScenes sweep: " << cloud.size()
            << " points, ring 0..31, intensity 0..255\n";
}

TEST(KittiVelodyneBin, ReadsRealScan) {
  const PointCloud cloud = ReadKittiVelodyneBin(test::RealDataPath(kKittiScan));
  ASSERT_EQ(cloud.size(), 17238u);
  EXPECT_FALSE(cloud.HasRing());
  const auto [lo, hi] = MinMax(cloud.intensity);
  EXPECT_EQ(lo, 0.f);
  EXPECT_FLOAT_EQ(hi, 0.99f);
  const Eigen::AlignedBox3f box = cloud.Bounds();
  EXPECT_THAT(box.min(),
              test::EigenNear(Eigen::Vector3f(2.889f, -26.42f, -3.607f), 1e-5));
  EXPECT_THAT(box.max(),
              test::EigenNear(Eigen::Vector3f(76.835f, 10.278f, 2.866f), 1e-5));
}

TEST(NuscenesLidarBin, SizeNotMultipleOf20NamesFileAndSize) {
  const std::string path =
      test::MakeTempDir("nusc_bad_size") + "/sweep.pcd.bin";
  std::string bytes = test::ReadFile(test::RealDataPath(kNuscenesSweep));
  test::WriteFile(path, bytes.substr(0, 693761 - 1 - 7));  // 693753 bytes
  EXPECT_EQ(ErrorOf([&] { ReadNuscenesLidarBin(path); }),
            path +
                ": size 693753 bytes is not a multiple of 20 (float32 x 5 per "
                "point: x y z "
                "intensity ring)");
  // The same bytes are not a KITTI scan either (693753 % 16 != 0).
  EXPECT_THAT(ErrorOf([&] { ReadKittiVelodyneBin(path); }),
              StartsWith(path + ": size 693753 bytes is not a multiple of 16"));
}

TEST(NuscenesLidarBin, RoundTripIsExactAndMatchesInputBytes) {
  const std::string dir = test::MakeTempDir("nusc_roundtrip");
  const PointCloud cloud =
      ReadNuscenesLidarBin(test::RealDataPath(kNuscenesSweep));
  WriteNuscenesLidarBin(dir + "/copy.pcd.bin", cloud);
  EXPECT_EQ(test::ReadFile(dir + "/copy.pcd.bin"),
            test::ReadFile(test::RealDataPath(kNuscenesSweep)));
  ExpectSameCloud(cloud, ReadNuscenesLidarBin(dir + "/copy.pcd.bin"));
}

TEST(KittiVelodyneBin, RoundTripIsExactAndMatchesInputBytes) {
  const std::string dir = test::MakeTempDir("kitti_roundtrip");
  const PointCloud cloud = ReadKittiVelodyneBin(test::RealDataPath(kKittiScan));
  WriteKittiVelodyneBin(dir + "/copy.bin", cloud);
  EXPECT_EQ(test::ReadFile(dir + "/copy.bin"),
            test::ReadFile(test::RealDataPath(kKittiScan)));
}

TEST(NuscenesLidarBin, RejectsNonFiniteAndMissing) {
  const std::string dir = test::MakeTempDir("nusc_nan");
  const float values[10] = {1, 2, 3, 4, 5, 1, NAN, 3, 4, 5};
  test::WriteFile(dir + "/nan.pcd.bin",
                  std::string(reinterpret_cast<const char*>(values), 40));
  EXPECT_EQ(ErrorOf([&] { ReadNuscenesLidarBin(dir + "/nan.pcd.bin"); }),
            dir + "/nan.pcd.bin: point 1 has a non-finite coordinate (nan)");
  EXPECT_EQ(ErrorOf([&] { ReadNuscenesLidarBin(dir + "/missing.pcd.bin"); }),
            dir + "/missing.pcd.bin: cannot open (No such file or directory)");
  test::WriteFile(dir + "/empty.pcd.bin", "");
  EXPECT_TRUE(ReadNuscenesLidarBin(dir + "/empty.pcd.bin").empty());
}

TEST(NuscenesLidarBin, WriteFillsMissingAttributesWithZero) {
  const std::string dir = test::MakeTempDir("nusc_write_zero");
  PointCloud cloud;
  cloud.positions = {Eigen::Vector3f(1, 2, 3)};
  WriteNuscenesLidarBin(dir + "/a.pcd.bin", cloud);
  const PointCloud back = ReadNuscenesLidarBin(dir + "/a.pcd.bin");
  EXPECT_EQ(back.intensity, std::vector<float>{0.f});
  EXPECT_EQ(back.ring, std::vector<float>{0.f});
  cloud.intensity = {1.f, 2.f};  // inconsistent sizes
  EXPECT_THAT(
      ErrorOf([&] { WriteNuscenesLidarBin(dir + "/b.pcd.bin", cloud); }),
      StartsWith(dir + "/b.pcd.bin: "));
  EXPECT_FALSE(fs::exists(dir + "/b.pcd.bin"));
}

TEST(Ply, BinaryRoundTripKeepsEveryAttribute) {
  const std::string path = test::MakeTempDir("ply_binary") + "/cloud.ply";
  const PointCloud cloud = RandomCloud(1000);
  WritePly(path, cloud);
  EXPECT_THAT(test::ReadFile(path),
              StartsWith("ply\nformat binary_little_endian 1.0\n"));
  ExpectSameCloud(cloud, ReadPly(path));
}

TEST(Ply, AsciiRoundTripKeepsEveryAttribute) {
  const std::string path = test::MakeTempDir("ply_ascii") + "/cloud.ply";
  const PointCloud cloud = RandomCloud(200);
  WritePly(path, cloud, /*binary=*/false);
  EXPECT_THAT(test::ReadFile(path), StartsWith("ply\nformat ascii 1.0\n"));
  ExpectSameCloud(cloud, ReadPly(path));  // %.9g round-trips float32 exactly
}

// Capture footprints (render/footprint.h) survive a file: a re-read cloud
// renders with the same footprint splats. Every format, binary and ASCII,
// with and without the footprint axes.
TEST(PointCloudIo, FootprintsRoundTripInPlyAndPcd) {
  const std::string dir = test::MakeTempDir("cloud_footprints");
  PointCloud cloud = RandomCloud(300);
  std::uniform_real_distribution<float> side(0.f, 0.5f), axis(-0.2f, 0.2f);
  for (size_t i = 0; i < cloud.size(); ++i) {
    // Zero footprints and zero axes mean "unknown": kept as written.
    cloud.footprints.push_back(i % 7 == 0 ? 0.f : side(test::Rng()));
    const bool unknown = i % 5 == 0;
    cloud.footprint_u.emplace_back(
        unknown ? Eigen::Vector3f::Zero()
                : Eigen::Vector3f(axis(test::Rng()), axis(test::Rng()),
                                  axis(test::Rng())));
    cloud.footprint_v.emplace_back(
        unknown ? Eigen::Vector3f::Zero()
                : Eigen::Vector3f(axis(test::Rng()), axis(test::Rng()),
                                  axis(test::Rng())));
  }
  PointCloud no_axes = cloud;
  no_axes.footprint_u.clear();
  no_axes.footprint_v.clear();
  for (const PointCloud* c : {&cloud, &no_axes}) {
    for (bool binary : {true, false}) {
      WritePly(dir + "/c.ply", *c, binary);
      ExpectSameCloud(*c, ReadPly(dir + "/c.ply"));
      WritePcd(dir + "/c.pcd", *c, binary);
      ExpectSameCloud(*c, ReadPcd(dir + "/c.pcd"));
    }
  }
  WritePly(dir + "/c.ply", cloud, /*binary=*/false);
  const std::string text = test::ReadFile(dir + "/c.ply");
  EXPECT_THAT(text, HasSubstr("property float footprint\n"
                              "property float footprint_ux\n"));
  EXPECT_THAT(text, HasSubstr("property float footprint_vz\nend_header\n"));

  // Five of the six axis properties: the axes are not read, the footprints
  // are. A negative footprint in a file is an error naming it and the point.
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
      "property float y\nproperty float z\nproperty float footprint\n"
      "property float footprint_ux\nproperty float footprint_uy\n"
      "property float footprint_uz\nproperty float footprint_vx\n"
      "property float footprint_vy\nend_header\n";
  test::WriteFile(dir + "/five.ply", header +
                                         "0 0 1 0.25 1 2 3 4 5\n"
                                         "1 0 1 0 1 2 3 4 5\n");
  const PointCloud five = ReadPly(dir + "/five.ply");
  EXPECT_EQ(five.footprints, (std::vector<float>{0.25f, 0.f}));
  EXPECT_TRUE(five.footprint_u.empty());
  test::WriteFile(dir + "/neg.ply", header +
                                        "0 0 1 0.25 1 2 3 4 5\n"
                                        "1 0 1 -1 1 2 3 4 5\n");
  EXPECT_THAT(ErrorOf([&] { ReadPly(dir + "/neg.ply"); }),
              StartsWith(dir + "/neg.ply: point 1 has footprint -1"));
}

TEST(Ply, PositionsAndColorsOnly) {
  const std::string path = test::MakeTempDir("ply_rgb") + "/cloud.ply";
  const PointCloud cloud = RandomCloud(50, /*all_attributes=*/false);
  WritePly(path, cloud);
  const PointCloud back = ReadPly(path);
  ExpectSameCloud(cloud, back);
  EXPECT_FALSE(back.HasConfidence());
  EXPECT_FALSE(back.HasIntensity());
}

TEST(Ply, ReadsHandWrittenAsciiFileFromAnotherTool) {
  // Property types other tools use (double positions, uchar colours, extra
  // unknown properties, a face element).
  const std::string path = test::MakeTempDir("ply_foreign") + "/foreign.ply";
  test::WriteFile(
      path,
      "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 2\n"
      "property double x\nproperty double y\nproperty double z\nproperty float "
      "nx\n"
      "property uchar red\nproperty uchar green\nproperty uchar blue\n"
      "element face 0\nproperty list uchar int vertex_indices\nend_header\n"
      "1.5 -2 3 0.1 255 0 10\n4 5 6.25 0.2 1 2 3\n");
  const PointCloud cloud = ReadPly(path);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.positions[0], Eigen::Vector3f(1.5f, -2.f, 3.f));
  EXPECT_EQ(cloud.positions[1], Eigen::Vector3f(4.f, 5.f, 6.25f));
  ASSERT_TRUE(cloud.HasColors());
  EXPECT_EQ(cloud.colors[0], Color3u8(255, 0, 10));
  EXPECT_EQ(cloud.colors[1], Color3u8(1, 2, 3));
}

TEST(Ply, EmptyCloudRoundTrips) {
  const std::string path = test::MakeTempDir("ply_empty") + "/empty.ply";
  WritePly(path, PointCloud());
  EXPECT_TRUE(ReadPly(path).empty());
}

TEST(Ply, BadFilesNameTheFile) {
  const std::string dir = test::MakeTempDir("ply_bad");
  EXPECT_EQ(ErrorOf([&] { ReadPly(dir + "/missing.ply"); }),
            dir + "/missing.ply: cannot open (No such file or directory)");
  test::WriteFile(dir + "/text.ply", "this is not a ply file\n");
  EXPECT_EQ(ErrorOf([&] { ReadPly(dir + "/text.ply"); }),
            dir + "/text.ply: not a PLY file");
  test::WriteFile(dir + "/empty.ply", "");
  EXPECT_THAT(ErrorOf([&] { ReadPly(dir + "/empty.ply"); }),
              StartsWith(dir + "/empty.ply: "));
  // Binary body cut short.
  WritePly(dir + "/full.ply", RandomCloud(100));
  const std::string full = test::ReadFile(dir + "/full.ply");
  test::WriteFile(dir + "/truncated.ply", full.substr(0, full.size() - 500));
  EXPECT_THAT(ErrorOf([&] { ReadPly(dir + "/truncated.ply"); }),
              StartsWith(dir + "/truncated.ply: "));
  // Header without end_header.
  test::WriteFile(
      dir + "/header.ply",
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n");
  EXPECT_THAT(ErrorOf([&] { ReadPly(dir + "/header.ply"); }),
              StartsWith(dir + "/header.ply: "));
  // No x/y/z.
  test::WriteFile(dir + "/noxyz.ply",
                  "ply\nformat ascii 1.0\nelement vertex 1\nproperty float "
                  "a\nend_header\n1\n");
  EXPECT_THAT(ErrorOf([&] { ReadPly(dir + "/noxyz.ply"); }),
              StartsWith(dir + "/noxyz.ply: "));
}

TEST(Pcd, BinaryRoundTripKeepsEveryAttribute) {
  const std::string path = test::MakeTempDir("pcd_binary") + "/cloud.pcd";
  const PointCloud cloud = RandomCloud(1000);
  WritePcd(path, cloud);
  EXPECT_THAT(test::ReadFile(path), HasSubstr("\nDATA binary\n"));
  ExpectSameCloud(cloud, ReadPcd(path));
}

TEST(Pcd, AsciiRoundTripKeepsEveryAttribute) {
  const std::string path = test::MakeTempDir("pcd_ascii") + "/cloud.pcd";
  const PointCloud cloud = RandomCloud(100);
  WritePcd(path, cloud, /*binary=*/false);
  EXPECT_THAT(test::ReadFile(path), HasSubstr("\nDATA ascii\n"));
  ExpectSameCloud(cloud, ReadPcd(path));
}

// Was ReadsHandWrittenXyziFileAndDropsNanPoints: PCL's reader dropped NaN
// points everywhere. Under the one NaN policy (point_cloud_io.h) the same
// unorganised file (HEIGHT 1) is an error; only an organised file (HEIGHT > 1)
// drops its NaN holes, and says how many.
TEST(Pcd, ReadsHandWrittenXyziFileNanOnlyDroppedWhenOrganised) {
  const std::string dir = test::MakeTempDir("pcd_foreign");
  auto write = [&](const std::string& name, const char* size) {
    test::WriteFile(
        dir + "/" + name,
        std::string("# .PCD v0.7 - Point Cloud Data file format\n"
                    "VERSION 0.7\nFIELDS x y z intensity\n"
                    "SIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n") +
            size +
            "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n1 2 3 10\n"
            "nan nan nan 0\n4 5 6 20\n");
  };
  write("scan.pcd", "WIDTH 3\nHEIGHT 1\n");
  EXPECT_EQ(ErrorOf([&] { ReadPcd(dir + "/scan.pcd"); }),
            dir + "/scan.pcd: point 1 has a non-finite coordinate (nan)");
  write("organised.pcd", "WIDTH 1\nHEIGHT 3\n");
  PcdReadSummary summary;
  const PointCloud cloud = ReadPcd(dir + "/organised.pcd", &summary);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(summary.dropped_nan_points, 1u);
  EXPECT_EQ(summary.height, 3u);
  EXPECT_EQ(cloud.positions[1], Eigen::Vector3f(4, 5, 6));
  EXPECT_EQ(cloud.intensity, (std::vector<float>{10, 20}));
  EXPECT_FALSE(cloud.HasColors());
}

TEST(Pcd, EmptyCloudRoundTrips) {
  const std::string path = test::MakeTempDir("pcd_empty") + "/empty.pcd";
  WritePcd(path, PointCloud());
  EXPECT_TRUE(ReadPcd(path).empty());
}

TEST(Pcd, BadFilesNameTheFile) {
  const std::string dir = test::MakeTempDir("pcd_bad");
  EXPECT_EQ(ErrorOf([&] { ReadPcd(dir + "/missing.pcd"); }),
            dir + "/missing.pcd: cannot open (No such file or directory)");
  test::WriteFile(dir + "/text.pcd", "hello\n");
  EXPECT_THAT(ErrorOf([&] { ReadPcd(dir + "/text.pcd"); }),
              StartsWith(dir + "/text.pcd: "));
  WritePcd(dir + "/full.pcd", RandomCloud(100));
  const std::string full = test::ReadFile(dir + "/full.pcd");
  test::WriteFile(dir + "/truncated.pcd", full.substr(0, full.size() - 700));
  EXPECT_THAT(ErrorOf([&] { ReadPcd(dir + "/truncated.pcd"); }),
              StartsWith(dir + "/truncated.pcd: "));
}

TEST(PointCloudIo, DispatchesOnExtension) {
  const std::string dir = test::MakeTempDir("pc_dispatch");
  const PointCloud cloud = RandomCloud(20);
  for (const char* name : {"a.ply", "b.PCD", "c.pcd.bin", "d.bin"}) {
    WritePointCloud(dir + "/" + name, cloud);
    const PointCloud back = ReadPointCloud(dir + "/" + name);
    ASSERT_EQ(back.size(), cloud.size()) << name;
    EXPECT_EQ(back.positions, cloud.positions) << name;
  }
  EXPECT_EQ(ReadPointCloud(dir + "/c.pcd.bin").ring,
            cloud.ring);  // nuScenes keeps the ring
  EXPECT_FALSE(ReadPointCloud(dir + "/d.bin").HasRing());  // KITTI has none
  EXPECT_EQ(ErrorOf([&] { ReadPointCloud(dir + "/e.xyz"); }),
            dir +
                "/e.xyz: unknown point cloud format (expected .ply, .pcd, "
                ".pcd.bin or .bin)");
  EXPECT_THROW(WritePointCloud(dir + "/e.xyz", cloud), InputError);
}

TEST(PointCloudIo, RealSweepSurvivesPlyAndPcd) {
  const std::string dir = test::MakeTempDir("pc_real_formats");
  const PointCloud sweep =
      ReadNuscenesLidarBin(test::RealDataPath(kNuscenesSweep));
  WritePly(dir + "/sweep.ply", sweep);
  ExpectSameCloud(sweep, ReadPly(dir + "/sweep.ply"));
  WritePcd(dir + "/sweep.pcd", sweep);
  ExpectSameCloud(sweep, ReadPcd(dir + "/sweep.pcd"));
}

// The same real sweep as text: "%.9g" round-trips float32, so the ASCII
// readers (their fast float path and from_chars behind it) must give the
// sweep's positions and intensities exactly.
TEST(PointCloudIo, RealSweepSurvivesAsciiPlyAndPcd) {
  const std::string dir = test::MakeTempDir("pc_real_ascii");
  const PointCloud sweep =
      ReadNuscenesLidarBin(test::RealDataPath(kNuscenesSweep));
  WritePly(dir + "/sweep.ply", sweep, /*binary=*/false);
  ExpectSameCloud(sweep, ReadPly(dir + "/sweep.ply"));
  WritePcd(dir + "/sweep.pcd", sweep, /*binary=*/false);
  ExpectSameCloud(sweep, ReadPcd(dir + "/sweep.pcd"));
}

TEST(PointCloudIo, WritesLeaveNoTemporaries) {
  const std::string dir = test::MakeTempDir("pc_atomic");
  const PointCloud cloud = RandomCloud(10);
  WritePly(dir + "/a.ply", cloud);
  WritePcd(dir + "/a.pcd", cloud);
  WritePcd(dir + "/a.pcd", cloud, /*binary=*/false);
  WriteNuscenesLidarBin(dir + "/a.pcd.bin", cloud);
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    ++files;
    EXPECT_EQ(entry.path().filename().string()[0], 'a') << entry.path();
  }
  EXPECT_EQ(files, 3);
  EXPECT_THAT(ErrorOf([&] { WritePcd(dir + "/no/dir/x.pcd", cloud); }),
              StartsWith(dir + "/no/dir/x.pcd: cannot write"));
}

}  // namespace
}  // namespace point_cloud_io_test
}  // namespace geodrive

namespace geodrive {
namespace point_cloud_io_test {
namespace {

// Cuts a valid file at many lengths: every read either succeeds or throws
// InputError naming the file (never a crash, never a lost point).
void ExpectEveryPrefixFailsCleanly(const std::string& full_path,
                                   const std::string& ext,
                                   PointCloud (*read)(const std::string&)) {
  const std::string full = test::ReadFile(full_path);
  const std::string cut = full_path + ".cut" + ext;
  int errors = 0;
  for (size_t len = 0; len < full.size(); len += 13) {
    test::WriteFile(cut, full.substr(0, len));
    try {
      // Only a cut inside the last ASCII number can go unnoticed: never a lost
      // point.
      EXPECT_EQ(read(cut).size(), read(full_path).size()) << len;
    } catch (const InputError& e) {
      ++errors;
      EXPECT_THAT(e.what(), StartsWith(cut + ": ")) << len;
    }
  }
  EXPECT_GT(errors, 0);
}

TEST(Ply, EveryTruncationFailsCleanly) {
  const std::string dir = test::MakeTempDir("ply_prefixes");
  WritePly(dir + "/b.ply", RandomCloud(40));
  ExpectEveryPrefixFailsCleanly(dir + "/b.ply", ".ply", &ReadPly);
  WritePly(dir + "/a.ply", RandomCloud(20), /*binary=*/false);
  ExpectEveryPrefixFailsCleanly(dir + "/a.ply", ".ply", &ReadPly);
}

TEST(Pcd, EveryTruncationFailsCleanly) {
  const std::string dir = test::MakeTempDir("pcd_prefixes");
  WritePcd(dir + "/b.pcd", RandomCloud(40));
  ExpectEveryPrefixFailsCleanly(dir + "/b.pcd", ".pcd", &ReadPcd);
  WritePcd(dir + "/a.pcd", RandomCloud(20), /*binary=*/false);
  ExpectEveryPrefixFailsCleanly(dir + "/a.pcd", ".pcd", &ReadPcd);
}

}  // namespace
}  // namespace point_cloud_io_test
}  // namespace geodrive

namespace geodrive {
namespace point_cloud_io_test {
namespace {

// Our binary PLY is plain enough for numpy alone: parse the header,
// np.frombuffer the body with a structured dtype, and compare with the same
// cloud saved as .npy.
TEST(Ply, NumpyParsesOurBinaryPly) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("numpy");
  const std::string dir = test::MakeTempDir("ply_numpy");
  const PointCloud cloud = RandomCloud(500);
  WritePly(dir + "/cloud.ply", cloud);
  std::vector<float> xyz;
  for (const auto& p : cloud.positions)
    xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
  WriteNpy(dir + "/xyz.npy", NpyArray::Float32({500, 3}, xyz.data()));
  WriteNpy(dir + "/id.npy", [&] {
    NpyArray a = NpyArray::Zeros(NpyDtype::kInt32, {500});
    std::copy(cloud.instance_ids.begin(), cloud.instance_ids.end(),
              a.MutableData<int32_t>());
    return a;
  }());
  test::WriteFile(dir + "/check.py", R"(import sys, numpy as np
d = sys.argv[1]
raw = open(d + '/cloud.ply', 'rb').read()
end = raw.index(b'end_header\n') + len(b'end_header\n')
types = {'float': '<f4', 'uchar': 'u1', 'int': '<i4'}
fields, n = [], 0
for line in raw[:end].decode().splitlines():
    p = line.split()
    if p[0] == 'element': n = int(p[2])
    if p[0] == 'property': fields.append((p[2], types[p[1]]))
v = np.frombuffer(raw[end:], dtype=np.dtype(fields), count=n)
assert len(raw) - end == n * np.dtype(fields).itemsize, 'body size'
xyz = np.stack([v['x'], v['y'], v['z']], 1)
assert np.array_equal(xyz, np.load(d + '/xyz.npy')), 'xyz'
assert np.array_equal(v['instance_id'], np.load(d + '/id.npy')), 'instance_id'
assert [f[0] for f in fields] == ['x', 'y', 'z', 'red', 'green', 'blue', 'confidence',
                                  'instance_id', 'intensity', 'ring'], fields
print('numpy parsed', n, 'vertices')
)");
  std::string out;
  EXPECT_EQ(test::RunCommand(std::string(test::kDebianPython) + " " + dir +
                                 "/check.py " + dir,
                             &out),
            0)
      << out;
  EXPECT_THAT(out, HasSubstr("numpy parsed 500 vertices"));
}

}  // namespace
}  // namespace point_cloud_io_test
}  // namespace geodrive

namespace geodrive {
namespace point_cloud_io_test {
namespace {

// Appends binary values in either byte order (PLY bodies written by hand).
class Body {
 public:
  explicit Body(bool big_endian = false) : big_endian_(big_endian) {}
  template <typename T>
  Body& Put(T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (big_endian_) std::reverse(b, b + sizeof(T));
    bytes.append(b, sizeof(T));
    return *this;
  }
  std::string bytes;

 private:
  bool big_endian_;
};

std::string PlyHeader(const std::string& format, const std::string& elements) {
  return "ply\nformat " + format + " 1.0\ncomment by hand\n" + elements +
         "end_header\n";
}

double Seconds(const std::chrono::steady_clock::time_point& since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since)
      .count();
}

TEST(Ply, ReadsBigEndianBinary) {
  const std::string path = test::MakeTempDir("ply_big_endian") + "/be.ply";
  Body body(/*big_endian=*/true);
  body.Put(1.5f).Put(-2.25f).Put(3e5f).Put(uint8_t{10}).Put(uint8_t{20});
  body.Put(uint8_t{30}).Put(0.5f).Put(int32_t{-7}).Put(uint16_t{31});
  body.Put(-1e-3f).Put(7.f).Put(8.f).Put(uint8_t{255}).Put(uint8_t{0});
  body.Put(uint8_t{1}).Put(250.f).Put(int32_t{123456}).Put(uint16_t{0});
  test::WriteFile(
      path, PlyHeader("binary_big_endian",
                      "element vertex 2\nproperty float x\nproperty float "
                      "y\nproperty float z\nproperty uchar red\nproperty "
                      "uchar green\nproperty uchar blue\nproperty float "
                      "intensity\nproperty int instance_id\nproperty "
                      "ushort ring\n") +
                body.bytes);
  const PointCloud cloud = ReadPly(path);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.positions[0], Eigen::Vector3f(1.5f, -2.25f, 3e5f));
  EXPECT_EQ(cloud.positions[1], Eigen::Vector3f(-1e-3f, 7.f, 8.f));
  EXPECT_EQ(cloud.colors,
            (std::vector<Color3u8>{Color3u8(10, 20, 30), Color3u8(255, 0, 1)}));
  EXPECT_EQ(cloud.intensity, (std::vector<float>{0.5f, 250.f}));
  EXPECT_EQ(cloud.instance_ids, (std::vector<int32_t>{-7, 123456}));
  EXPECT_EQ(cloud.ring, (std::vector<float>{31.f, 0.f}));
}

// Properties in a foreign order, PLY type aliases, double coordinates,
// integer-typed confidence/ring and unknown properties in between; binary and
// ASCII give the same cloud.
TEST(Ply, ShuffledPropertyOrderAndDoubleCoordinates) {
  const std::string dir = test::MakeTempDir("ply_shuffled");
  const std::string elements =
      "element vertex 2\nproperty float64 z\nproperty uint8 blue\nproperty "
      "int16 unknown\nproperty double x\nproperty float32 intensity\nproperty "
      "uchar red\nproperty float64 y\nproperty uchar green\nproperty uint16 "
      "ring\nproperty char confidence\nproperty uint instance_id\n";
  Body body;
  body.Put(0.1).Put(uint8_t{3}).Put(int16_t{-5}).Put(-12.5).Put(9.f);
  body.Put(uint8_t{1}).Put(1e-7).Put(uint8_t{2}).Put(uint16_t{17});
  body.Put(int8_t{-1}).Put(uint32_t{40});
  body.Put(-0.3).Put(uint8_t{6}).Put(int16_t{0}).Put(80.25).Put(0.f);
  body.Put(uint8_t{4}).Put(2.0).Put(uint8_t{5}).Put(uint16_t{0});
  body.Put(int8_t{1}).Put(uint32_t{0});
  test::WriteFile(dir + "/binary.ply",
                  PlyHeader("binary_little_endian", elements) + body.bytes);
  test::WriteFile(dir + "/ascii.ply", PlyHeader("ascii", elements) +
                                          "0.1 3 -5 -12.5 9 1 1e-7 2 17 -1 40\n"
                                          "-0.3 6 0 80.25 0 4 2.0 5 0 1 0\n");
  for (const char* name : {"binary.ply", "ascii.ply"}) {
    SCOPED_TRACE(name);
    const PointCloud cloud = ReadPly(dir + "/" + name);
    ASSERT_EQ(cloud.size(), 2u);
    EXPECT_EQ(cloud.positions[0],
              Eigen::Vector3f(-12.5f, static_cast<float>(1e-7),
                              static_cast<float>(0.1)));
    EXPECT_EQ(cloud.positions[1],
              Eigen::Vector3f(80.25f, 2.f, static_cast<float>(-0.3)));
    EXPECT_EQ(cloud.colors,
              (std::vector<Color3u8>{Color3u8(1, 2, 3), Color3u8(4, 5, 6)}));
    EXPECT_EQ(cloud.intensity, (std::vector<float>{9.f, 0.f}));
    EXPECT_EQ(cloud.ring, (std::vector<float>{17.f, 0.f}));
    EXPECT_EQ(cloud.confidence, (std::vector<float>{-1.f, 1.f}));
    EXPECT_EQ(cloud.instance_ids, (std::vector<int32_t>{40, 0}));
  }
}

// An element before the vertices, a list inside the vertex element and a face
// element after it, in both byte orders and in ASCII.
TEST(Ply, SkipsListsAndOtherElements) {
  const std::string dir = test::MakeTempDir("ply_lists");
  const std::string elements =
      "element camera 1\nproperty float view_px\nproperty list ushort short "
      "tags\nelement vertex 3\nproperty float x\nproperty list uchar int "
      "neighbours\nproperty float y\nproperty float z\nproperty uchar "
      "red\nproperty uchar green\nproperty uchar blue\nelement face 2\n"
      "property list uchar int vertex_indices\nproperty uchar flags\n";
  for (bool big : {false, true}) {
    Body b(big);
    b.Put(1.f).Put(uint16_t{2}).Put(int16_t{7}).Put(int16_t{8});  // camera
    b.Put(1.f).Put(uint8_t{0}).Put(2.f).Put(3.f);
    b.Put(uint8_t{10}).Put(uint8_t{11}).Put(uint8_t{12});
    b.Put(4.f).Put(uint8_t{2}).Put(int32_t{0}).Put(int32_t{2}).Put(5.f);
    b.Put(6.f).Put(uint8_t{20}).Put(uint8_t{21}).Put(uint8_t{22});
    b.Put(7.f).Put(uint8_t{1}).Put(int32_t{1}).Put(8.f).Put(9.f);
    b.Put(uint8_t{30}).Put(uint8_t{31}).Put(uint8_t{32});
    b.Put(uint8_t{3}).Put(int32_t{0}).Put(int32_t{1}).Put(int32_t{2});
    b.Put(uint8_t{0});
    b.Put(uint8_t{4}).Put(int32_t{0}).Put(int32_t{1}).Put(int32_t{2});
    b.Put(int32_t{0}).Put(uint8_t{1});
    const std::string format =
        big ? "binary_big_endian" : "binary_little_endian";
    test::WriteFile(dir + "/" + format + ".ply",
                    PlyHeader(format, elements) + b.bytes);
    // A face whose list runs past the end of the file.
    test::WriteFile(
        dir + "/cut_" + format + ".ply",
        PlyHeader(format, elements) + b.bytes.substr(0, b.bytes.size() - 6));
  }
  test::WriteFile(dir + "/ascii.ply", PlyHeader("ascii", elements) +
                                          "1 2 7 8\n"
                                          "1 0 2 3 10 11 12\n"
                                          "4 2 0 2 5 6 20 21 22\n"
                                          "7 1 1 8 9 30 31 32\n"
                                          "3 0 1 2 0\n"
                                          "4 0 1 2 0 1\n");
  for (const char* name :
       {"binary_little_endian.ply", "binary_big_endian.ply", "ascii.ply"}) {
    SCOPED_TRACE(name);
    const PointCloud cloud = ReadPly(dir + "/" + name);
    ASSERT_EQ(cloud.size(), 3u);
    EXPECT_EQ(cloud.positions[0], Eigen::Vector3f(1, 2, 3));
    EXPECT_EQ(cloud.positions[1], Eigen::Vector3f(4, 5, 6));
    EXPECT_EQ(cloud.positions[2], Eigen::Vector3f(7, 8, 9));
    EXPECT_EQ(cloud.colors[2], Color3u8(30, 31, 32));
  }
  for (const char* name :
       {"cut_binary_little_endian.ply", "cut_binary_big_endian.ply"}) {
    EXPECT_EQ(ErrorOf([&] { ReadPly(dir + "/" + name); }),
              dir + "/" + name +
                  ": truncated: 'face' item 1 of 2 runs past the end of the "
                  "file");
  }
}

TEST(Ply, ToleratesCrlfCommentsAndObjInfo) {
  const std::string path = test::MakeTempDir("ply_crlf") + "/crlf.ply";
  test::WriteFile(
      path,
      "ply\r\nformat ascii 1.0\r\ncomment made on Windows\r\nobj_info "
      "scanner 3\r\nelement vertex 2\r\nproperty float x\r\nproperty "
      "float y\r\nproperty float z\r\nend_header\r\n1 2 3\r\n\r\n4 5 "
      "6\r\n");
  const PointCloud cloud = ReadPly(path);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.positions[1], Eigen::Vector3f(4, 5, 6));
}

// Line 9 is the first body line of these files.
std::string XyzAsciiPly(const std::string& body, uint64_t vertices = 3) {
  return PlyHeader("ascii", "element vertex " + std::to_string(vertices) +
                                "\nproperty float x\nproperty float "
                                "y\nproperty float z\n") +
         body;
}

// The size check before allocation needs at least 6 characters per line
// here ("1 2 3\n"); these bodies are longer, so each error is found where it
// is.
TEST(Ply, AsciiGarbageNamesLineAndToken) {
  const std::string dir = test::MakeTempDir("ply_garbage");
  const std::string path = dir + "/bad.ply";
  const std::pair<std::string, std::string> cases[] = {
      {"1.5 2.5 3.5\n4.5 5.5 abc\n7.5 8.5 9.5\n",
       ": line 10: bad value 'abc' for property 'z' (float)"},
      {"1.5 2.5 3.5\n4.5 5.5 6x\n7.5 8.5 9.5\n",
       ": line 10: bad value '6x' for property 'z' (float)"},
      {"1.5 2.5 3.5\n4.5 5.5 6.5\n7.5 8,5 9.5\n",
       ": line 11: bad value '8,5' for property 'y' (float)"},
      {"1.5 2.5 3.5\n4.5 5.5 1e999\n7.5 8.5 9.5\n",
       ": line 10: value '1e999' is out of range for property 'z' (float)"},
      {"1.5 2.5 3.5\n4.5 5.5\n7.5 8.5 9.5\n",
       ": line 10: too few values (the line ends before property 'z')"},
      {"1.5 2.5 3.5\n4.5 5.5 6.5 0\n7.5 8.5 9.5\n",
       ": line 10: too many values ('0' after the last property)"},
      {"1.5 2.5 3.5\n4.5 5.5 6.5\n",
       ": truncated: the file ends after 2 of 3 'vertex' lines"},
      {"1.5 2.5 3.5\n4.5 5.5 6.5\n7.5 8.5 9.5\n10 11 12\n",
       ": line 12: unexpected data after the last element ('10 11 12')"},
      // Too short for 3 lines of 3 values at all: found before allocating.
      {"1 2 3\n4 5\n",
       ": truncated or corrupt: the header declares 3 'vertex' items of at "
       "least 6 characters, but only 10 bytes follow the header"},
  };
  for (const auto& [body, error] : cases) {
    test::WriteFile(path, XyzAsciiPly(body));
    EXPECT_EQ(ErrorOf([&] { ReadPly(path); }), path + error) << body;
  }
}

TEST(Ply, AsciiIntegersOutOfTheirTypeAreErrors) {
  const std::string path = test::MakeTempDir("ply_int_range") + "/c.ply";
  const std::string header = PlyHeader(
      "ascii",
      "element vertex 1\nproperty float x\nproperty float y\nproperty float "
      "z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
      "property short s\n");
  const std::pair<std::string, std::string> cases[] = {
      {"1 2 3 256 0 0 0\n",
       ": line 13: value '256' is out of range for property 'red' (uchar)"},
      {"1 2 3 0 -1 0 0\n",
       ": line 13: value '-1' is out of range for property 'green' (uchar)"},
      {"1 2 3 0 0 2.5 0\n",
       ": line 13: bad value '2.5' for property 'blue' (uchar)"},
      {"1 2 3 0 0 0 40000\n",
       ": line 13: value '40000' is out of range for property 's' (short)"},
  };
  for (const auto& [body, error] : cases) {
    test::WriteFile(path, header + body);
    EXPECT_EQ(ErrorOf([&] { ReadPly(path); }), path + error) << body;
  }
  test::WriteFile(path, header + "1 2 3 +255 0 0 -32768\n");
  EXPECT_EQ(ReadPly(path).colors[0], Color3u8(255, 0, 0));
}

// A PLY that declares 50 M vertices in 80 KB: PCL allocated 880 MB for it.
// The declared size is checked against the file before any allocation.
TEST(Ply, HostileVertexCountFailsFast) {
  const std::string dir = test::MakeTempDir("ply_hostile");
  const std::string binary = PlyHeader(
      "binary_little_endian",
      "element vertex 50000000\nproperty float x\nproperty float y\nproperty "
      "float z\nproperty uchar red\nproperty uchar green\nproperty uchar "
      "blue\n");
  test::WriteFile(dir + "/binary.ply",
                  binary + std::string(80000 - binary.size(), 0));
  std::string ascii = XyzAsciiPly("", 50000000);
  while (ascii.size() < 80000) ascii += "1 2 3\n";
  test::WriteFile(dir + "/ascii.ply", ascii);
  test::WriteFile(dir + "/limit.ply", XyzAsciiPly("1 2 3\n", 2147483649));
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(ErrorOf([&] { ReadPly(dir + "/binary.ply"); }),
            dir +
                "/binary.ply: truncated or corrupt: the header declares "
                "50000000 'vertex' items of at least 15 bytes, but only " +
                std::to_string(80000 - binary.size()) +
                " bytes follow the header");
  EXPECT_EQ(
      ErrorOf([&] { ReadPly(dir + "/ascii.ply"); }),
      dir +
          "/ascii.ply: truncated or corrupt: the header declares "
          "50000000 'vertex' items of at least 6 characters, but "
          "only " +
          std::to_string(ascii.size() - XyzAsciiPly("", 50000000).size()) +
          " bytes follow the header");
  EXPECT_EQ(ErrorOf([&] { ReadPly(dir + "/limit.ply"); }),
            dir +
                "/limit.ply: header declares 2147483649 vertices, more "
                "than the limit of 2147483648");
  EXPECT_LT(Seconds(start), 0.5);
}

// The PCD sizes a hostile file can declare: points, the compressed block's
// two sizes, and LZF data that does not decode.
TEST(Pcd, HostileDeclaredSizesFailFast) {
  const std::string dir = test::MakeTempDir("pcd_hostile");
  auto header = [](const std::string& width, const std::string& data) {
    return "VERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT "
           "1 1 1 1\nWIDTH " +
           width + "\nHEIGHT 1\nPOINTS " + width + "\nDATA " + data + "\n";
  };
  auto sizes = [](uint32_t compressed, uint32_t uncompressed) {
    return Body().Put(compressed).Put(uncompressed).bytes;
  };
  const std::string b = header("50000000", "binary");
  test::WriteFile(dir + "/binary.pcd", b + std::string(80000 - b.size(), 0));
  const std::string c = header("50000000", "binary_compressed");
  test::WriteFile(dir + "/ratio.pcd",
                  c + sizes(1000, 800000000) + std::string(1000, 0));
  test::WriteFile(dir + "/mismatch.pcd",
                  c + sizes(1000, 4000000000u) + std::string(1000, 0));
  const std::string c2 = header("2", "binary_compressed");
  test::WriteFile(dir + "/compressed_size.pcd",
                  c2 + sizes(2000000000u, 32) + "x");
  test::WriteFile(dir + "/garbage.pcd",
                  c2 + sizes(10, 32) + std::string(10, '\xff'));
  test::WriteFile(dir + "/nosizes.pcd", c2 + "abc");
  test::WriteFile(
      dir + "/limit.pcd",
      "FIELDS x y z\nWIDTH 4294967295\nHEIGHT 4294967295\nDATA binary\n");
  const auto start = std::chrono::steady_clock::now();
  const std::pair<const char*, std::string> cases[] = {
      {"binary.pcd",
       ": truncated or corrupt: the header declares 50000000 points of 16 "
       "bytes (800000000 bytes), but only " +
           std::to_string(80000 - b.size()) + " bytes follow the header"},
      {"ratio.pcd",
       ": corrupt: 1000 bytes of LZF data cannot hold 800000000 bytes"},
      {"mismatch.pcd",
       ": corrupt: the compressed block declares 4000000000 bytes of points, "
       "the header needs 50000000 x 16 = 800000000"},
      {"compressed_size.pcd",
       ": truncated: the compressed block declares 2000000000 bytes, only 1 "
       "bytes follow it"},
      {"garbage.pcd", ": corrupt LZF data (invalid stream: 0 of 32 bytes)"},
      {"nosizes.pcd", ": truncated: the compressed block's sizes are missing"},
      {"limit.pcd",
       ": header declares 18446744065119617025 points, more than the limit of "
       "2147483648"},
  };
  for (const auto& [name, error] : cases) {
    const std::string path = dir + "/" + name;  // (clang 14: no lambda
                                                // capture of bindings)
    EXPECT_EQ(ErrorOf([&] { ReadPcd(path); }), path + error);
  }
  EXPECT_LT(Seconds(start), 0.5);
}

// PCL's binary_compressed layout, written here with liblzf: uint32
// compressed size, uint32 uncompressed size, then the LZF-compressed fields
// one after another. Fields: x y z rgb (U 4, as PCL's templated writer
// declares it), intensity, a 4-byte "_" padding field, confidence,
// instance_id (I 4), a COUNT 3 descriptor, ring. `width` x `height` must be
// cloud.size(); positions are not checked (NaN holes allowed).
std::string CompressedPcd(const PointCloud& cloud,
                          size_t width,
                          size_t height) {
  const size_t n = cloud.size();
  std::string soa;
  auto column = [&](auto value_of) {
    for (size_t i = 0; i < n; ++i) {
      const auto v = value_of(i);
      soa.append(reinterpret_cast<const char*>(&v), sizeof(v));
    }
  };
  for (int k = 0; k < 3; ++k)
    column([&](size_t i) { return cloud.positions[i][k]; });
  column([&](size_t i) {
    const Color3u8& c = cloud.colors[i];
    return (uint32_t{c[0]} << 16) | (uint32_t{c[1]} << 8) | c[2];
  });
  column([&](size_t i) { return cloud.intensity[i]; });
  column([&](size_t i) { return static_cast<uint32_t>(0xdeadbeef + i); });
  column([&](size_t i) { return cloud.confidence[i]; });
  column([&](size_t i) { return cloud.instance_ids[i]; });
  column([&](size_t i) { return std::array<float, 3>{float(i), -1.f, 1e30f}; });
  column([&](size_t i) { return cloud.ring[i]; });
  std::string lzf(soa.size() * 2 + 64, '\0');
  const unsigned int compressed =
      lzf_compress(soa.data(), static_cast<unsigned int>(soa.size()),
                   lzf.data(), static_cast<unsigned int>(lzf.size()));
  EXPECT_GT(compressed, 0u);
  return "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
         "FIELDS x y z rgb intensity _ confidence instance_id fpfh ring\n"
         "SIZE 4 4 4 4 4 1 4 4 4 4\nTYPE F F F U F U F I F F\n"
         "COUNT 1 1 1 1 1 4 1 1 3 1\nWIDTH " +
         std::to_string(width) + "\nHEIGHT " + std::to_string(height) +
         "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(n) +
         "\nDATA binary_compressed\n" +
         Body().Put(uint32_t{compressed}).Put(uint32_t(soa.size())).bytes +
         lzf.substr(0, compressed);
}

TEST(Pcd, BinaryCompressedMatchesUncompressedExactly) {
  const std::string dir = test::MakeTempDir("pcd_compressed");
  const PointCloud cloud = RandomCloud(5000);
  WritePcd(dir + "/binary.pcd", cloud);
  test::WriteFile(dir + "/compressed.pcd", CompressedPcd(cloud, 5000, 1));
  PcdReadSummary summary;
  const PointCloud compressed = ReadPcd(dir + "/compressed.pcd", &summary);
  EXPECT_EQ(summary.data, "binary_compressed");
  ExpectSameCloud(ReadPcd(dir + "/binary.pcd"), compressed);
  ExpectSameCloud(cloud, compressed);
  // One byte less of LZF data: the stream no longer decodes to the full size.
  std::string cut = test::ReadFile(dir + "/compressed.pcd");
  cut.pop_back();
  test::WriteFile(dir + "/cut.pcd", cut);
  EXPECT_THAT(ErrorOf([&] { ReadPcd(dir + "/cut.pcd"); }),
              StartsWith(dir + "/cut.pcd: truncated: the compressed block "));
}

// Binary points are read on from the header in chunks of about 256 KiB of
// whole records: a cloud of several chunks whose record size does not divide
// it reads back exactly, with the header in the first 64 KiB or past them.
TEST(Pcd, BinaryReadInChunksIsExact) {
  const std::string dir = test::MakeTempDir("pcd_binary_chunks");
  const PointCloud cloud = RandomCloud(30000);
  WritePcd(dir + "/a.pcd", cloud);
  const std::string file = test::ReadFile(dir + "/a.pcd");
  ASSERT_GT(file.size(), size_t{3} << 18);
  ExpectSameCloud(cloud, ReadPcd(dir + "/a.pcd"));
  std::string comments;
  while (comments.size() < (size_t{80} << 10))
    comments += "# a long comment line before the header\n";
  test::WriteFile(dir + "/b.pcd", comments + file);
  ExpectSameCloud(cloud, ReadPcd(dir + "/b.pcd"));
}

// A real LiDAR sweep (34,688 points, 455 KB, more than one of the reader's 256
// KiB chunks once compressed) as PCL writes binary_compressed: x y z intensity,
// the fields one after another, LZF by liblzf. The streamed read gives the
// sweep's values exactly.
TEST(Pcd, RealSweepAsBinaryCompressed) {
  const std::string dir = test::MakeTempDir("pcd_real_compressed");
  const PointCloud sweep =
      ReadNuscenesLidarBin(test::RealDataPath(kNuscenesSweep));
  const size_t n = sweep.size();
  ASSERT_GT(n, size_t{30000});
  std::string soa;
  for (int k = 0; k < 4; ++k) {
    for (size_t i = 0; i < n; ++i) {
      const float v = k < 3 ? sweep.positions[i][k] : sweep.intensity[i];
      soa.append(reinterpret_cast<const char*>(&v), 4);
    }
  }
  std::string lzf(soa.size() * 2 + 64, '\0');
  const unsigned int packed =
      lzf_compress(soa.data(), static_cast<unsigned int>(soa.size()),
                   lzf.data(), static_cast<unsigned int>(lzf.size()));
  ASSERT_GT(packed, 256u << 10);
  const uint32_t sizes[2] = {packed, static_cast<uint32_t>(soa.size())};
  test::WriteFile(
      dir + "/sweep.pcd",
      "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\n"
      "TYPE F F F F\nCOUNT 1 1 1 1\nWIDTH " +
          std::to_string(n) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " +
          std::to_string(n) + "\nDATA binary_compressed\n" +
          std::string(reinterpret_cast<const char*>(sizes), 8) +
          lzf.substr(0, packed));
  const PointCloud read = ReadPcd(dir + "/sweep.pcd");
  EXPECT_EQ(read.positions, sweep.positions);
  EXPECT_EQ(read.intensity, sweep.intensity);
}

// The reader takes the header from the file's first 64 KiB when it is
// there and streams the LZF block on from it: headers that end anywhere near
// that boundary, or past it, give the same cloud.
TEST(Pcd, CompressedHeaderEndingAnywhereGivesTheSameCloud) {
  const std::string dir = test::MakeTempDir("pcd_compressed_header");
  const PointCloud cloud = RandomCloud(20000);
  const std::string file = CompressedPcd(cloud, 20000, 1);
  const size_t header = file.find("DATA binary_compressed\n") + 23;
  ASSERT_GT(file.size(), size_t{200000});
  // Comment lines before the header put the DATA line's end, or the block's
  // two sizes, on either side of byte 65536, or the header past it.
  const size_t k64 = size_t{1} << 16;
  for (size_t end :
       {k64 - 100, k64 - 8, k64 - 3, k64, k64 + 1, k64 + 30, 3 * k64}) {
    std::string comments;
    for (size_t left = end - header; left > 0;) {  // lines of 2 to 71 bytes
      const size_t line = left >= 72 || left == 70 ? 70 : left;
      comments += "#" + std::string(line - 2, 'c') + "\n";
      left -= line;
    }
    ASSERT_EQ(comments.size() + header, end);
    const std::string path = dir + "/c" + std::to_string(end) + ".pcd";
    test::WriteFile(path, comments + file);
    ExpectSameCloud(cloud, ReadPcd(path));
  }
}

TEST(Pcd, ReadsOlderHeadersCrlfAndPaddedBinary) {
  const std::string dir = test::MakeTempDir("pcd_old");
  // v0.5: no VERSION, COUNT, WIDTH, HEIGHT or VIEWPOINT; SIZE and TYPE
  // default to float32.
  test::WriteFile(dir + "/v5.pcd",
                  "# old\nFIELDS x y z\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n");
  EXPECT_EQ(ReadPcd(dir + "/v5.pcd").positions,
            (std::vector<Eigen::Vector3f>{{1, 2, 3}, {4, 5, 6}}));
  test::WriteFile(
      dir + "/crlf.pcd",
      "VERSION .7\r\nFIELDS x y z\r\nSIZE 4 4 4\r\nTYPE F F F\r\nCOUNT 1 "
      "1 1\r\nWIDTH 1\r\nHEIGHT 1\r\nPOINTS 1\r\nDATA ascii\r\n1 2 3\r\n");
  EXPECT_EQ(ReadPcd(dir + "/crlf.pcd").positions[0], Eigen::Vector3f(1, 2, 3));
  // Older PCL padded binary files with zeros after the points.
  const PointCloud cloud = RandomCloud(10);
  WritePcd(dir + "/padded.pcd", cloud);
  test::WriteFile(dir + "/padded.pcd", test::ReadFile(dir + "/padded.pcd") +
                                           std::string(4096, '\0'));
  ExpectSameCloud(cloud, ReadPcd(dir + "/padded.pcd"));
  test::WriteFile(dir + "/v9.pcd",
                  "VERSION 0.9\nFIELDS x y z\nPOINTS 0\nDATA ascii\n");
  EXPECT_EQ(ErrorOf([&] { ReadPcd(dir + "/v9.pcd"); }),
            dir +
                "/v9.pcd: malformed PCD header: unsupported VERSION (0.5, "
                "0.6 and 0.7 are read) (line 1)");
  test::WriteFile(dir + "/ascii_bad.pcd",
                  "FIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nWIDTH 2\nDATA "
                  "ascii\n1 2 3 4\n4 5 6 -1\n");
  EXPECT_EQ(ErrorOf([&] { ReadPcd(dir + "/ascii_bad.pcd"); }),
            dir +
                "/ascii_bad.pcd: line 7: value '-1' is out of range for "
                "field 'rgb' (U 4)");
}

TEST(Pcd, WritesPclHeaderLayout) {
  const std::string path = test::MakeTempDir("pcd_header") + "/c.pcd";
  PointCloud cloud;
  cloud.positions = {Eigen::Vector3f(0.1f, -2, 3e-5f)};
  cloud.colors = {Color3u8(1, 2, 3)};
  cloud.intensity = {7.5f};
  WritePcd(path, cloud, /*binary=*/false);
  EXPECT_EQ(test::ReadFile(path),
            "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS "
            "x y z rgb intensity\nSIZE 4 4 4 4 4\nTYPE F F F U F\nCOUNT 1 1 1 "
            "1 1\nWIDTH 1\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 1\nDATA "
            "ascii\n0.100000001 -2 2.99999992e-05 66051 7.5\n");
  WritePcd(path, cloud);
  const std::string binary = test::ReadFile(path);
  EXPECT_THAT(binary, HasSubstr("POINTS 1\nDATA binary\n"));
  EXPECT_EQ(binary.size(), binary.find("DATA binary\n") + 12 + 20);
}

// Writes `cloud` in `format` with one coordinate of point 2 replaced by
// `value` (written through a sentinel, as the writers refuse non-finite
// points).
std::string WithNonFinite(const std::string& dir,
                          const std::string& name,
                          float value) {
  const std::string path = dir + "/" + name;
  PointCloud cloud = RandomCloud(4);
  const float sentinel = 12345.5f;
  cloud.positions[2].y() = sentinel;
  if (EndsWith(name, ".cpcd")) {
    cloud.positions[2].y() = value;
    test::WriteFile(path, CompressedPcd(cloud, 4, 1));
    return path;
  }
  WritePointCloud(path, cloud);
  if (EndsWith(name, "a.ply")) WritePly(path, cloud, /*binary=*/false);
  if (EndsWith(name, "a.pcd")) WritePcd(path, cloud, /*binary=*/false);
  std::string bytes = test::ReadFile(path);
  std::string from(reinterpret_cast<const char*>(&sentinel), 4);
  std::string to(reinterpret_cast<const char*>(&value), 4);
  if (EndsWith(name, "a.ply") || EndsWith(name, "a.pcd")) {
    from = "12345.5";
    to = std::isnan(value) ? "nan" : (value > 0 ? "inf" : "-inf");
  }
  const size_t at = bytes.find(from);
  EXPECT_NE(at, std::string::npos) << name;
  bytes.replace(at, from.size(), to);
  test::WriteFile(path, bytes);
  return path;
}

TEST(PointCloudIo, NonFiniteCoordinateIsTheSameErrorInEveryFormat) {
  const std::string dir = test::MakeTempDir("pc_nan_policy");
  // Names ending in a.ply / a.pcd are ASCII; .cpcd is binary_compressed.
  const std::string names[] = {"b.ply",  "a.ply",     "b.pcd", "a.pcd",
                               "c.cpcd", "n.pcd.bin", "k.bin"};
  const std::pair<float, const char*> values[] = {
      {std::numeric_limits<float>::quiet_NaN(), "nan"},
      {std::numeric_limits<float>::infinity(), "+inf"},
      {-std::numeric_limits<float>::infinity(), "-inf"}};
  for (const std::string& name : names) {
    for (int v = 0; v < 3; ++v) {
      const auto& [value, text] = values[v];
      const std::string path =
          WithNonFinite(dir, std::to_string(v) + name, value);
      auto read = [&] {
        return EndsWith(path, ".cpcd") ? ReadPcd(path) : ReadPointCloud(path);
      };
      EXPECT_EQ(ErrorOf(read),
                path + ": point 2 has a non-finite coordinate (" + text + ")");
    }
  }
}

TEST(Pcd, OrganisedCloudDropsNanHolesOnly) {
  const std::string dir = test::MakeTempDir("pcd_organised");
  PointCloud cloud = RandomCloud(6);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cloud.positions[1] = Eigen::Vector3f(nan, nan, nan);
  cloud.positions[4].z() = nan;
  test::WriteFile(dir + "/organised.pcd", CompressedPcd(cloud, 3, 2));
  PcdReadSummary summary;
  const PointCloud read = ReadPcd(dir + "/organised.pcd", &summary);
  EXPECT_EQ(summary.dropped_nan_points, 2u);
  EXPECT_EQ(summary.width, 3u);
  EXPECT_EQ(summary.height, 2u);
  ExpectSameCloud(read, cloud.Select({0, 2, 3, 5}));
  // The same points as one row are an error; +inf is one even when organised.
  test::WriteFile(dir + "/row.pcd", CompressedPcd(cloud, 6, 1));
  EXPECT_EQ(ErrorOf([&] { ReadPcd(dir + "/row.pcd"); }),
            dir + "/row.pcd: point 1 has a non-finite coordinate (nan)");
  cloud.positions[3].x() = std::numeric_limits<float>::infinity();
  test::WriteFile(dir + "/inf.pcd", CompressedPcd(cloud, 3, 2));
  EXPECT_EQ(ErrorOf([&] { ReadPcd(dir + "/inf.pcd"); }),
            dir + "/inf.pcd: point 3 has a non-finite coordinate (+inf)");
}

// Open3D (Debian's python3-open3d) writes PLY and PCD files, ours reads
// them; ours writes, Open3D reads. Every coordinate and colour must agree:
// Open3D's points are doubles (its PLYs store double coordinates), ours float,
// so float(open3d) must equal ours exactly; colours are round(255 c).
TEST(PointCloudIo, MatchesOpen3dBothWays) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("open3d");
  const std::string dir = test::MakeTempDir("pc_open3d");
  const PointCloud ours = RandomCloud(3000);
  WritePly(dir + "/ours_b.ply", ours);
  WritePly(dir + "/ours_a.ply", ours, /*binary=*/false);
  WritePcd(dir + "/ours_b.pcd", ours);
  WritePcd(dir + "/ours_a.pcd", ours, /*binary=*/false);
  test::WriteFile(dir + "/check.py", R"(import sys, numpy as np, open3d as o3d
d = sys.argv[1]
rng = np.random.default_rng(5)
p = o3d.geometry.PointCloud()
p.points = o3d.utility.Vector3dVector(rng.uniform(-80, 80, (3000, 3)))
p.colors = o3d.utility.Vector3dVector(rng.integers(0, 256, (3000, 3)) / 255.0)
o3d.io.write_point_cloud(d + '/o3d_b.ply', p)
o3d.io.write_point_cloud(d + '/o3d_a.ply', p, write_ascii=True)
o3d.io.write_point_cloud(d + '/o3d_b.pcd', p)
o3d.io.write_point_cloud(d + '/o3d_a.pcd', p, write_ascii=True)
o3d.io.write_point_cloud(d + '/o3d_c.pcd', p, compressed=True)
names = ['o3d_b.ply', 'o3d_a.ply', 'o3d_b.pcd', 'o3d_a.pcd', 'o3d_c.pcd',
         'ours_b.ply', 'ours_a.ply', 'ours_b.pcd', 'ours_a.pcd']
for name in names:
    q = o3d.io.read_point_cloud(d + '/' + name)
    assert len(q.points) == 3000 and q.has_colors(), name
    np.save(d + '/' + name + '.xyz.npy', np.asarray(q.points))
    np.save(d + '/' + name + '.rgb.npy',
            np.round(np.asarray(q.colors) * 255).astype(np.uint8))
print('open3d', o3d.__version__, 'wrote 5 files and read', len(names))
)");
  std::string out;
  ASSERT_EQ(test::RunCommand(std::string(test::kDebianPython) + " " + dir +
                                 "/check.py " + dir + " 2>&1",
                             &out),
            0)
      << out;
  for (const char* name :
       {"o3d_b.ply", "o3d_a.ply", "o3d_b.pcd", "o3d_a.pcd", "o3d_c.pcd",
        "ours_b.ply", "ours_a.ply", "ours_b.pcd", "ours_a.pcd"}) {
    SCOPED_TRACE(name);
    const std::string path = dir + "/" + name;
    const PointCloud cloud = ReadPointCloud(path);
    const NpyArray xyz = ReadNpy(path + ".xyz.npy");
    const NpyArray rgb = ReadNpy(path + ".rgb.npy");
    ASSERT_EQ(xyz.shape, (std::vector<int64_t>{3000, 3}));
    ASSERT_EQ(cloud.size(), 3000u);
    ASSERT_TRUE(cloud.HasColors());
    int xyz_mismatches = 0, rgb_mismatches = 0;
    for (size_t i = 0; i < 3000; ++i) {
      for (int k = 0; k < 3; ++k) {
        xyz_mismatches += static_cast<float>(xyz.Data<double>()[3 * i + k]) !=
                          cloud.positions[i][k];
        rgb_mismatches += rgb.Data<uint8_t>()[3 * i + k] != cloud.colors[i][k];
      }
    }
    EXPECT_EQ(xyz_mismatches, 0);
    EXPECT_EQ(rgb_mismatches, 0);
    if (std::string(name).rfind("ours", 0) == 0) ExpectSameCloud(ours, cloud);
  }
  std::cout << out;
}

}  // namespace
}  // namespace point_cloud_io_test
}  // namespace geodrive

// Tests of point cloud files: the real nuScenes and KITTI sweeps, .bin round
// trips, and PLY / PCD through PCL with all optional attributes.

#include "geometry/point_cloud_io.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <random>

#include "geometry/npy.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
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

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void WriteAll(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
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
  std::string bytes = ReadAll(test::RealDataPath(kNuscenesSweep));
  WriteAll(path, bytes.substr(0, 693761 - 1 - 7));  // 693753 bytes
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
  EXPECT_EQ(ReadAll(dir + "/copy.pcd.bin"),
            ReadAll(test::RealDataPath(kNuscenesSweep)));
  ExpectSameCloud(cloud, ReadNuscenesLidarBin(dir + "/copy.pcd.bin"));
}

TEST(KittiVelodyneBin, RoundTripIsExactAndMatchesInputBytes) {
  const std::string dir = test::MakeTempDir("kitti_roundtrip");
  const PointCloud cloud = ReadKittiVelodyneBin(test::RealDataPath(kKittiScan));
  WriteKittiVelodyneBin(dir + "/copy.bin", cloud);
  EXPECT_EQ(ReadAll(dir + "/copy.bin"),
            ReadAll(test::RealDataPath(kKittiScan)));
}

TEST(NuscenesLidarBin, RejectsNonFiniteAndMissing) {
  const std::string dir = test::MakeTempDir("nusc_nan");
  const float values[10] = {1, 2, 3, 4, 5, 1, NAN, 3, 4, 5};
  WriteAll(dir + "/nan.pcd.bin",
           std::string(reinterpret_cast<const char*>(values), 40));
  EXPECT_EQ(ErrorOf([&] { ReadNuscenesLidarBin(dir + "/nan.pcd.bin"); }),
            dir + "/nan.pcd.bin: point 1 has a non-finite coordinate");
  EXPECT_EQ(ErrorOf([&] { ReadNuscenesLidarBin(dir + "/missing.pcd.bin"); }),
            dir + "/missing.pcd.bin: cannot open (No such file or directory)");
  WriteAll(dir + "/empty.pcd.bin", "");
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
  EXPECT_THAT(ReadAll(path),
              StartsWith("ply\nformat binary_little_endian 1.0\n"));
  ExpectSameCloud(cloud, ReadPly(path));
}

TEST(Ply, AsciiRoundTripKeepsEveryAttribute) {
  const std::string path = test::MakeTempDir("ply_ascii") + "/cloud.ply";
  const PointCloud cloud = RandomCloud(200);
  WritePly(path, cloud, /*binary=*/false);
  EXPECT_THAT(ReadAll(path), StartsWith("ply\nformat ascii 1.0\n"));
  ExpectSameCloud(cloud, ReadPly(path));  // %.9g round-trips float32 exactly
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
  WriteAll(
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
  WriteAll(dir + "/text.ply", "this is not a ply file\n");
  EXPECT_EQ(ErrorOf([&] { ReadPly(dir + "/text.ply"); }),
            dir + "/text.ply: not a PLY file");
  WriteAll(dir + "/empty.ply", "");
  EXPECT_THAT(ErrorOf([&] { ReadPly(dir + "/empty.ply"); }),
              StartsWith(dir + "/empty.ply: "));
  // Binary body cut short.
  WritePly(dir + "/full.ply", RandomCloud(100));
  const std::string full = ReadAll(dir + "/full.ply");
  WriteAll(dir + "/truncated.ply", full.substr(0, full.size() - 500));
  EXPECT_THAT(ErrorOf([&] { ReadPly(dir + "/truncated.ply"); }),
              StartsWith(dir + "/truncated.ply: "));
  // Header without end_header.
  WriteAll(dir + "/header.ply",
           "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n");
  EXPECT_THAT(ErrorOf([&] { ReadPly(dir + "/header.ply"); }),
              StartsWith(dir + "/header.ply: "));
  // No x/y/z.
  WriteAll(dir + "/noxyz.ply",
           "ply\nformat ascii 1.0\nelement vertex 1\nproperty float "
           "a\nend_header\n1\n");
  EXPECT_THAT(ErrorOf([&] { ReadPly(dir + "/noxyz.ply"); }),
              StartsWith(dir + "/noxyz.ply: "));
}

TEST(Pcd, BinaryRoundTripKeepsEveryAttribute) {
  const std::string path = test::MakeTempDir("pcd_binary") + "/cloud.pcd";
  const PointCloud cloud = RandomCloud(1000);
  WritePcd(path, cloud);
  EXPECT_THAT(ReadAll(path), HasSubstr("\nDATA binary\n"));
  ExpectSameCloud(cloud, ReadPcd(path));
}

TEST(Pcd, AsciiRoundTripKeepsEveryAttribute) {
  const std::string path = test::MakeTempDir("pcd_ascii") + "/cloud.pcd";
  const PointCloud cloud = RandomCloud(100);
  WritePcd(path, cloud, /*binary=*/false);
  EXPECT_THAT(ReadAll(path), HasSubstr("\nDATA ascii\n"));
  ExpectSameCloud(cloud, ReadPcd(path));
}

TEST(Pcd, ReadsHandWrittenXyziFileAndDropsNanPoints) {
  const std::string path = test::MakeTempDir("pcd_foreign") + "/scan.pcd";
  WriteAll(path,
           "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x "
           "y z intensity\n"
           "SIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 3\nHEIGHT 1\n"
           "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n1 2 3 10\nnan nan "
           "nan 0\n4 5 6 20\n");
  const PointCloud cloud = ReadPcd(path);
  ASSERT_EQ(cloud.size(), 2u);
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
  WriteAll(dir + "/text.pcd", "hello\n");
  EXPECT_THAT(ErrorOf([&] { ReadPcd(dir + "/text.pcd"); }),
              StartsWith(dir + "/text.pcd: "));
  WritePcd(dir + "/full.pcd", RandomCloud(100));
  const std::string full = ReadAll(dir + "/full.pcd");
  WriteAll(dir + "/truncated.pcd", full.substr(0, full.size() - 700));
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
}  // namespace geodrive

namespace geodrive {
namespace {

// Cuts a valid file at many lengths: every read either succeeds or throws
// InputError naming the file (PCL is never handed a file it would crash on or
// print to stderr about).
void ExpectEveryPrefixFailsCleanly(const std::string& full_path,
                                   const std::string& ext,
                                   PointCloud (*read)(const std::string&)) {
  const std::string full = ReadAll(full_path);
  const std::string cut = full_path + ".cut" + ext;
  int errors = 0;
  for (size_t len = 0; len < full.size(); len += 13) {
    WriteAll(cut, full.substr(0, len));
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
}  // namespace geodrive

namespace geodrive {
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
  WriteAll(dir + "/check.py", R"(import sys, numpy as np
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
}  // namespace geodrive

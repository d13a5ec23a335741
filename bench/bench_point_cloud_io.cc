// Point cloud files (geometry/point_cloud_io.h): read and write binary PLY,
// ASCII PLY, binary PCD, binary_compressed PCD and ASCII PCD at 345,600
// points (one 480x720 pointmap) and 10 M points, x y z float + r g b. ASCII
// reads parse on OpenMP's threads (OMP_NUM_THREADS; files of 2 MB and more),
// everything else runs on one thread; the CPU column is the whole process's.
//
//   build/bench/bench_point_cloud_io --benchmark_min_time=2
//
// The files are kept in $GEODRIVE_BENCH_PCIO_DIR (default
// /tmp/geodrive_bench_point_cloud_io) for bench/point_cloud_io_vs_open3d.sh,
// which times Open3D on the same files. Figures: docs/PERFORMANCE.md,
// section "Point cloud files".

#include <benchmark/benchmark.h>
#include <liblzf/lzf.h>  // Debian's liblzf-dev: writes binary_compressed

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include "bench/bench_main.h"
#include "geometry/point_cloud_io.h"

namespace geodrive {
namespace {

enum Format { kBinaryPly, kAsciiPly, kBinaryPcd, kCompressedPcd, kAsciiPcd };
const char* const kNames[] = {"binary.ply", "ascii.ply", "binary.pcd",
                              "compressed.pcd", "ascii.pcd"};

std::string Dir() {
  const char* env = std::getenv("GEODRIVE_BENCH_PCIO_DIR");
  const std::string dir = env ? env : "/tmp/geodrive_bench_point_cloud_io";
  std::filesystem::create_directories(dir);
  return dir;
}

// Pointmap-like clouds: 480x720 grids of a wavy surface seen from a camera
// (frame after frame for more than 345,600 points), colours from position.
const PointCloud& Cloud(size_t n) {
  static std::map<size_t, PointCloud> clouds;
  PointCloud& cloud = clouds[n];
  if (cloud.size() == n) return cloud;
  cloud.positions.resize(n);
  cloud.colors.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const float u = static_cast<float>(i % 720) - 359.5f;
    const float v = static_cast<float>((i / 720) % 480) - 239.5f;
    const float frame = static_cast<float>(i / 345600);
    const float depth = 8.f + 3.f * std::sin(0.01f * u + 0.3f * frame) +
                        2.f * std::cos(0.013f * v);
    cloud.positions[i] = Eigen::Vector3f(u * depth / 560.f, v * depth / 560.f,
                                         depth + 0.4f * frame);
    cloud.colors[i] =
        Color3u8(static_cast<uint8_t>(i * 7), static_cast<uint8_t>(depth * 20),
                 static_cast<uint8_t>(v));
  }
  return cloud;
}

// PCL's binary_compressed layout (fields one after another, LZF), written
// here as WritePcd writes binary and ASCII only.
void WriteCompressedPcd(const std::string& path, const PointCloud& cloud) {
  const size_t n = cloud.size();
  std::string soa(n * 16, '\0');
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k)
      std::memcpy(&soa[4 * (k * n + i)], &cloud.positions[i][k], 4);
    const Color3u8& c = cloud.colors[i];
    const uint32_t rgb = (uint32_t{c[0]} << 16) | (uint32_t{c[1]} << 8) | c[2];
    std::memcpy(&soa[4 * (3 * n + i)], &rgb, 4);
  }
  std::string lzf(soa.size() + soa.size() / 16 + 64, '\0');
  const uint32_t compressed =
      lzf_compress(soa.data(), static_cast<unsigned int>(soa.size()),
                   lzf.data(), static_cast<unsigned int>(lzf.size()));
  const uint32_t uncompressed = static_cast<uint32_t>(soa.size());
  std::ofstream out(path, std::ios::binary);
  out << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y "
         "z rgb\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH "
      << n << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << n
      << "\nDATA binary_compressed\n";
  out.write(reinterpret_cast<const char*>(&compressed), 4);
  out.write(reinterpret_cast<const char*>(&uncompressed), 4);
  out.write(lzf.data(), compressed);
}

void Write(Format format, const std::string& path, const PointCloud& cloud) {
  switch (format) {
    case kBinaryPly:
      return WritePly(path, cloud);
    case kAsciiPly:
      return WritePly(path, cloud, /*binary=*/false);
    case kBinaryPcd:
      return WritePcd(path, cloud);
    case kCompressedPcd:
      return WriteCompressedPcd(path, cloud);
    case kAsciiPcd:
      return WritePcd(path, cloud, /*binary=*/false);
  }
}

std::string FilePath(Format format, size_t n) {
  return Dir() + "/" + std::to_string(n) + "_" + kNames[format];
}

// Args: format, points.
void BM_Read(benchmark::State& state) {
  const Format format = static_cast<Format>(state.range(0));
  const size_t n = static_cast<size_t>(state.range(1));
  const std::string path = FilePath(format, n);
  if (!std::filesystem::exists(path)) Write(format, path, Cloud(n));
  const PointCloud& reference = Cloud(n);
  for (auto _ : state) {
    const PointCloud cloud = ReadPointCloud(path);
    if (cloud.size() != n ||
        cloud.positions.back() != reference.positions.back())
      state.SkipWithError("read back a different cloud");
    benchmark::DoNotOptimize(cloud.positions.data());
  }
  state.SetLabel(kNames[format]);
  state.counters["MB"] = std::filesystem::file_size(path) / 1e6;
  state.counters["Mpoints/s"] =
      benchmark::Counter(static_cast<double>(n) * state.iterations() / 1e6,
                         benchmark::Counter::kIsRate);
}

// Args: format (not compressed), points. Writes are atomic (fsync + rename),
// so the figure includes the fsync of the file.
void BM_Write(benchmark::State& state) {
  const Format format = static_cast<Format>(state.range(0));
  const size_t n = static_cast<size_t>(state.range(1));
  const PointCloud& cloud = Cloud(n);
  const std::string path = FilePath(format, n);
  for (auto _ : state) Write(format, path, cloud);
  state.SetLabel(kNames[format]);
  state.counters["MB"] = std::filesystem::file_size(path) / 1e6;
}

BENCHMARK(BM_Read)
    ->ArgNames({"format", "points"})
    ->ArgsProduct({{kBinaryPly, kAsciiPly, kBinaryPcd, kCompressedPcd,
                    kAsciiPcd},
                   {345600, 10000000}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime();

BENCHMARK(BM_Write)
    ->ArgNames({"format", "points"})
    ->ArgsProduct({{kBinaryPly, kAsciiPly, kBinaryPcd, kAsciiPcd},
                   {345600, 10000000}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime();

}  // namespace
}  // namespace geodrive

GEODRIVE_BENCHMARK_MAIN();

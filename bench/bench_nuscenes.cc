// nuScenes reader benchmarks: loading the 13 tables (simdjson over slices of
// whole records, on all threads, into compact structs) at v1.0-mini and
// v1.0-trainval scale, plus the projections. The tables come from the
// synthetic generator in tables-only mode (`geodrive synth --tables-only`, all
// six cameras, LIDAR_TOP and the five radars), cached under
// $GEODRIVE_BENCH_DIR (default /tmp/geodrive_bench_nuscenes).
//
//   bench_nuscenes --benchmark_filter=Load/10/0    # v1.0-mini size (10 scenes)
//   bench_nuscenes --benchmark_filter=Load/850/0   # v1.0-trainval size (850
//                                                  # scenes, ~2.6 M rows)
//
// BM_Load/<scenes>/<threads>: threads 0 = one per core (OpenMP's default), 1 =
// one thread. CPU time is the process's (all threads). Counters: sample_data
// rows, MB = JSON size, peak_rss_MB = the process's peak RSS so far (run one
// size per process for a memory figure). The nuScenes devkit on the same
// tables: bench/nuscenes_tables_vs_devkit.sh.

#include <benchmark/benchmark.h>
#include <sys/resource.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <random>

#include "dataset/nuscenes_clips.h"
#include "dataset/nuscenes.h"
#include "dataset/nuscenes_projection.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "geometry/util/memory.h"

namespace geodrive {
namespace {

std::string TablesFor(int scenes) {
  const char* env = std::getenv("GEODRIVE_BENCH_DIR");
  const std::string root =
      std::string(env ? env : "/tmp/geodrive_bench_nuscenes") + "/scenes_" +
      std::to_string(scenes);
  if (!std::filesystem::exists(root + "/done")) {
    SyntheticDatasetOptions o;
    o.num_scenes = scenes;
    o.tables_only = true;
    o.radars = true;
    o.cameras = {"CAM_FRONT", "CAM_FRONT_LEFT", "CAM_FRONT_RIGHT",
                 "CAM_BACK",  "CAM_BACK_LEFT",  "CAM_BACK_RIGHT"};
    o.version = "v1.0-bench";
    WriteSyntheticDataset(o, root);
    std::ofstream(root + "/done") << "ok\n";
  }
  return root;
}

double PeakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;
}

void BM_Load(benchmark::State& state) {
  const std::string root = TablesFor(static_cast<int>(state.range(0)));
  NuscenesOptions options;
  options.dataroot = root;
  options.version = "v1.0-bench";
  options.num_threads = static_cast<int>(state.range(1));
  size_t rows = 0, bytes = 0, anns = 0;
  // The tables are freed outside the timed region, as the devkit script
  // frees its tables after its timer (`del nusc`): a load, not a teardown.
  std::optional<Nuscenes> nusc;
  for (auto _ : state) {
    state.PauseTiming();
    nusc.reset();
    state.ResumeTiming();
    nusc.emplace(options);
    rows = nusc->sample_data().size();
    anns = nusc->sample_annotations().size();
    bytes = nusc->summary().json_bytes;
    benchmark::DoNotOptimize(rows);
  }
  state.counters["sample_data"] = static_cast<double>(rows);
  state.counters["annotations"] = static_cast<double>(anns);
  state.counters["MB"] = bytes / 1e6;
  state.counters["MB_per_s"] = benchmark::Counter(
      bytes / 1e6, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["peak_rss_MB"] = PeakRssMb();
}
BENCHMARK(BM_Load)
    ->Args({10, 0})
    ->Args({10, 1})
    ->Args({850, 0})
    ->Args({850, 1})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->Iterations(1);

void BM_SelectClips(benchmark::State& state) {
  NuscenesOptions options;
  options.dataroot = TablesFor(static_cast<int>(state.range(0)));
  options.version = "v1.0-bench";
  const Nuscenes nusc(options);
  size_t clips = 0;
  for (auto _ : state) clips = SelectClips(nusc, ClipOptions()).size();
  state.counters["clips"] = static_cast<double>(clips);
}
BENCHMARK(BM_SelectClips)->Arg(10)->Unit(benchmark::kMillisecond);

// One 34,688-point sweep (the real sweep's size) through the devkit's five
// transforms.
void BM_MapPointCloudToImage(benchmark::State& state) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> U(-50, 50);
  std::vector<Eigen::Vector3f> points(34688);
  for (auto& p : points) p = Eigen::Vector3f(U(rng), U(rng), U(rng) / 20);
  const Rigid3d ego_from_lidar(
      QuaternionFromWxyz(0.7071, 0, 0, -0.7071).normalized(),
      Eigen::Vector3d(0.944, 0, 1.84));
  const Rigid3d g(QuaternionFromAngleAxis(Eigen::Vector3d(0, 0, 0.3)),
                  Eigen::Vector3d(400, 1100, 0));
  const Rigid3d ego_from_cam(
      QuaternionFromWxyz(0.4998, -0.5030, 0.4998, -0.4974).normalized(),
      Eigen::Vector3d(1.70, 0.016, 1.51));
  Eigen::Matrix3d K;
  K << 1266.4, 0, 816.3, 0, 1266.4, 491.5, 0, 0, 1;
  size_t kept = 0;
  for (auto _ : state) {
    kept = MapPointCloudToImage(points, ego_from_lidar, g, g, ego_from_cam, K,
                                1600, 900)
               .size();
  }
  state.counters["kept"] = static_cast<double>(kept);
  state.SetItemsProcessed(state.iterations() * points.size());
}
BENCHMARK(BM_MapPointCloudToImage)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace geodrive

// The allocator policy the `geodrive` binary sets at start-up
// (geometry/util/memory.h: freed memory is kept for reuse rather than
// returned to the kernel and faulted in again), so the loads measured are the
// ones `geodrive nuscenes-info` and `build-dataset` make.
// GEODRIVE_MALLOC_DEFAULTS=1 measures with glibc's defaults instead.
int main(int argc, char** argv) {
  geodrive::ConfigureAllocatorForThroughput();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

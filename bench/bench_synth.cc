// Benchmarks of the synthetic world (docs/PERFORMANCE.md). The argument is the
// OpenMP thread count; the budget is one 25-frame 1600x900 clip
// (CAM_FRONT JPEGs, LIDAR_TOP sweeps, tables, MonST3R folder) in <= 10 s on one
// core:
//   OMP_NUM_THREADS=1 ./bench_synth --benchmark_filter=Clip

#include <benchmark/benchmark.h>
#include <omp.h>

#include <filesystem>

#include "dataset/synthetic/synthetic_dataset.h"
#include "dataset/synthetic/synthetic_world.h"

namespace geodrive {
namespace {

std::string BenchDir(const std::string& name) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("geodrive_bench_synth_" + name);
  std::filesystem::remove_all(dir);
  return dir.string();
}

// One scene of 2.5 s = exactly one 25-frame CAM_FRONT clip (41 lidar sweeps, 5
// samples) with its MonST3R folder, at 1600x900.
void BM_SynthClip1600x900(benchmark::State& state) {
  omp_set_num_threads(static_cast<int>(state.range(0)));
  SyntheticDatasetOptions o;
  o.num_scenes = 1;
  o.scene_duration_s = 2.5;
  o.write_monst3r = true;
  const std::string dir = BenchDir("clip");
  for (auto _ : state) {
    const SyntheticDatasetSummary s = WriteSyntheticDataset(o, dir);
    benchmark::DoNotOptimize(s.num_images);
    state.counters["images"] = static_cast<double>(s.num_images);
    state.counters["sweeps"] = static_cast<double>(s.num_lidar_sweeps);
  }
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_SynthClip1600x900)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

void BM_RenderCamera1600x900(benchmark::State& state) {
  omp_set_num_threads(static_cast<int>(state.range(0)));
  const SyntheticWorld world(SyntheticWorldOptions{});
  const PinholeCamera cam = SyntheticCameraIntrinsics("CAM_FRONT", 1600, 900);
  double t = 0;
  for (auto _ : state) {
    const Rigid3d pose =
        world.GlobalFromEgo(t) * SyntheticEgoFromSensor("CAM_FRONT");
    benchmark::DoNotOptimize(world.RenderCamera(cam, pose, t).depth.data);
    t += 1.0 / 12;
  }
  state.counters["Mrays/s"] = benchmark::Counter(
      1.44e6 * state.iterations() / 1e6, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_RenderCamera1600x900)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond);

void BM_LidarSweep(benchmark::State& state) {
  omp_set_num_threads(1);
  const SyntheticWorld world(SyntheticWorldOptions{});
  LidarOptions lo;
  lo.azimuth_steps = static_cast<int>(state.range(0));
  double t = 0;
  for (auto _ : state) {
    const Rigid3d pose =
        world.GlobalFromEgo(t) * SyntheticEgoFromSensor("LIDAR_TOP");
    benchmark::DoNotOptimize(world.CastLidar(pose, t, lo).points.size());
    t += 0.05;
  }
}
BENCHMARK(BM_LidarSweep)->Arg(720)->Arg(1080)->Unit(benchmark::kMillisecond);

// Tables only, trainval-like rows (6 cameras, lidar, 5 radars, 20 s scenes).
void BM_TablesOnly(benchmark::State& state) {
  SyntheticDatasetOptions o;
  o.num_scenes = static_cast<int>(state.range(0));
  o.tables_only = true;
  o.radars = true;
  o.cameras = {"CAM_FRONT", "CAM_FRONT_RIGHT", "CAM_BACK_RIGHT",
               "CAM_BACK",  "CAM_BACK_LEFT",   "CAM_FRONT_LEFT"};
  const std::string dir = BenchDir("tables");
  int64_t rows = 0;
  for (auto _ : state) rows += WriteSyntheticDataset(o, dir).num_sample_data;
  state.counters["sample_data rows/s"] = benchmark::Counter(
      static_cast<double>(rows), benchmark::Counter::kIsRate);
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_TablesOnly)->Arg(20)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace geodrive

BENCHMARK_MAIN();

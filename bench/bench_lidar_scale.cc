// LiDAR depth-scale fit for one 25-frame clip (one sweep per frame): read
// sweeps, project with the nuScenes chain, sample the 512x288 MonST3R depth,
// robust fit per frame and per clip, align the trajectory. Target: <= 200 ms
// on one core.
//
//   cmake -S . -B build -DGEODRIVE_BUILD_BENCH=ON && cmake --build build
//   --target bench_lidar_scale OMP_NUM_THREADS=1 taskset -c 0
//   ./build/bench/bench_lidar_scale

#include <benchmark/benchmark.h>

#include <filesystem>

#include "dataset/drive_dataset.h"
#include "dataset/lidar_alignment.h"
#include "dataset/synthetic/synthetic_dataset.h"

namespace geodrive {
namespace {

struct Fixture {
  std::string root;
  DriveClip clip;
  std::string clip_id;
};

Fixture& Get() {
  static Fixture f = [] {
    Fixture x;
    x.root =
        (std::filesystem::temp_directory_path() / "geodrive_bench_lidar_scale")
            .string();
    SyntheticDatasetOptions o;
    o.num_scenes = 1;
    o.seed = 3;
    o.scene_duration_s =
        2.5;  // one 25-frame clip at 1600x900 (MonST3R 512x288)
    o.write_monst3r = true;
    o.monst3r_depth_noise = 0.03;
    const SyntheticDatasetSummary s = WriteSyntheticDataset(o, x.root);
    x.clip_id = s.monst3r_clip_ids.front();
    DriveDatasetOptions no;
    no.root = x.root;
    no.clip_stride = 1;
    x.clip = OpenDriveDataset(no)->LoadClip(x.clip_id);
    return x;
  }();
  return f;
}

void BM_FitClipLidarScale(benchmark::State& state) {
  Fixture& f = Get();
  const Monst3rFolder folder =
      Monst3rFolder::Open(f.root + "/monst3r/" + f.clip_id);
  double scale = 0;
  int points = 0;
  for (auto _ : state) {
    const ClipScaleReport r = FitClipLidarScale(f.clip, folder, {});
    scale = r.clip_fit.scale;
    points = r.clip_fit.num_points;
    benchmark::DoNotOptimize(scale);
  }
  state.counters["lidar_points_used"] = points;
  state.counters["frames"] = static_cast<double>(f.clip.frames.size());
}
BENCHMARK(BM_FitClipLidarScale)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace
}  // namespace geodrive

BENCHMARK_MAIN();

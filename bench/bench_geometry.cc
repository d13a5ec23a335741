// Geometry benchmarks (Google Benchmark): pose refinement (eq. 3) of one frame
// from 4,096 sampled pixels, and reading + building + filtering + fusing a
// 25-frame 512x288 MonST3R folder. Run on one core: the main sets OpenMP to one
// thread. Figures: docs/PERFORMANCE.md ("Geometry").

#include <benchmark/benchmark.h>
#include <omp.h>

#include <filesystem>
#include <memory>

#include "geometry/fusion.h"
#include "geometry/monst3r.h"
#include "geometry/pointmap.h"
#include "geometry/pose_refinement.h"
#include "tests/geometry/synthetic_pointmaps.h"

namespace geodrive {
namespace {

constexpr int kWidth = 512, kHeight = 288, kFrames = 25;

// A 25-frame 512x288 MonST3R folder (with pts3d pointmaps for frame 0..1),
// written once.
const std::string& Folder() {
  static const std::string dir = [] {
    const std::string d = (std::filesystem::temp_directory_path() /
                           "geodrive_bench_geometry_monst3r")
                              .string();
    std::filesystem::remove_all(d);
    test::SyntheticClipOptions o;
    o.width = kWidth;
    o.height = kHeight;
    o.focal = 460;
    o.num_frames = kFrames;
    const test::SyntheticClip clip = test::MakeSyntheticClip(o);
    test::Monst3rWriteOptions w;
    w.depth_noise = 0.003;
    w.bad_depth_fraction = 0.08;
    w.write_pointmaps = true;
    w.pointmap_pixel_noise = 0.5;
    w.pointmap_outlier_fraction = 0.1;
    for (int t = 0; t < kFrames; ++t) {
      w.world_from_cam.push_back(test::PerturbPose(
          clip.world_from_cam[t], 2.0, 0.05 * clip.median_depth, 100 + t));
    }
    test::WriteMonst3rFolder(clip, d, w);
    return d;
  }();
  return dir;
}

void BM_RefineFramePose4096(benchmark::State& state) {
  const Monst3rFolder folder = Monst3rFolder::Open(Folder());
  Monst3rLoadOptions lo;
  lo.raw_pointmaps = true;
  const Monst3rFrame f = folder.LoadFrame(12, lo);
  PoseRefinementInput in;
  in.frame_index = 12;
  in.points_in_world = f.raw_points_in_world;
  in.camera = f.camera;
  in.initial_world_from_cam = f.world_from_cam;
  cv::bitwise_not(f.enlarged_dynamic_mask, in.valid_mask);
  PoseRefinementOptions opt;
  opt.num_samples = 4096;
  opt.loss = static_cast<RobustLoss>(state.range(0));
  PoseRefinementSummary last;
  for (auto _ : state) {
    const PoseRefinementResult r = RefineFramePose(in, opt);
    last = r.summary;
    benchmark::DoNotOptimize(r.world_from_cam);
  }
  state.counters["iterations_solver"] = last.iterations;
  state.counters["final_median_px"] = last.final_median_px;
  state.SetLabel(ToString(opt.loss));
}
BENCHMARK(BM_RefineFramePose4096)
    ->Arg(static_cast<int>(RobustLoss::kHuber))
    ->Arg(static_cast<int>(RobustLoss::kCauchy))
    ->Unit(benchmark::kMillisecond);

void BM_LoadFolder25(benchmark::State& state) {
  Folder();
  for (auto _ : state) {
    const Monst3rFolder folder = Monst3rFolder::Open(Folder());
    auto frames = folder.LoadFrames(ParseFrameList("all", folder.num_frames()));
    benchmark::DoNotOptimize(frames.data());
  }
}
BENCHMARK(BM_LoadFolder25)->Unit(benchmark::kMillisecond);

void BM_BuildAndFilter25(benchmark::State& state) {
  const Monst3rFolder folder = Monst3rFolder::Open(Folder());
  const auto frames =
      folder.LoadFrames(ParseFrameList("all", folder.num_frames()));
  for (auto _ : state) {
    int64_t kept = 0;
    for (const auto& f : frames) {
      const Pointmap pm = BuildPointmap(f);
      PointmapFilterStats s;
      ComputeValidMask(pm, {}, &s);
      kept += s.kept;
    }
    benchmark::DoNotOptimize(kept);
  }
}
BENCHMARK(BM_BuildAndFilter25)->Unit(benchmark::kMillisecond);

// The whole path: read folder, build pointmaps, filter (tau 0.65, depth range,
// static), fuse (voxel + statistical outlier removal).
void BM_ReadBuildFilterFuse25(benchmark::State& state) {
  Folder();
  FusionSummary last;
  for (auto _ : state) {
    const Monst3rFolder folder = Monst3rFolder::Open(Folder());
    std::vector<Pointmap> pms;
    for (const auto& f :
         folder.LoadFrames(ParseFrameList("all", folder.num_frames()))) {
      pms.push_back(BuildPointmap(f));
    }
    PointmapFilterOptions filter;
    filter.selection = PixelSelection::kStaticOnly;
    FusionOptions fusion;
    fusion.statistical_outlier_removal = state.range(0) != 0;
    const FusedCloud fused = FusePointmaps(pms, filter, fusion);
    last = fused.summary;
    benchmark::DoNotOptimize(fused.cloud.positions.data());
  }
  state.counters["input_points"] = static_cast<double>(last.input_points);
  state.counters["after_voxel"] = static_cast<double>(last.after_voxel);
  state.counters["output_points"] = static_cast<double>(last.after_radius);
  state.SetLabel(state.range(0) ? "voxel+SOR" : "voxel only");
}
BENCHMARK(BM_ReadBuildFilterFuse25)
    ->Arg(1)
    ->Arg(0)
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace geodrive

int main(int argc, char** argv) {
  omp_set_num_threads(1);  // one core
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

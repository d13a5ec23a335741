// Dynamic-editing benchmark: a 25-frame clip at 512x288 (the released
// pipeline's render size) of the synthetic street in
// tests/render/edit_test_scene.h (128k-point frame-0 pointmap cloud, five
// moving vehicles with 3D boxes), z-buffer splatting, fresh outputs per call.
//
//   build/bench/bench_edit
//   bench/edit_overhead.sh build/bench/bench_edit 9   (the overhead target)
//
// BM_PlainRender: RenderFrames of the unedited cloud (the baseline).
// BM_Edit3d: RenderWithDynamicEdits in 3D mode: segmentation of the five
// vehicles in their 3D boxes, poses, then one depth test per frame over the
// background and the moving vehicles (RenderFramesWithMovingSets; footprint
// splats for a vehicle drawn magnified, render/footprint.h).
// BM_BuildScene3d: the scene building alone.
// BM_Edit2d: the upstream-compatible 2D mode (point deletion, static render,
// feathered pastes). Figures and target (3D editing <= 1.3x the plain render):
// docs/PERFORMANCE.md, "Dynamic editing".

#include <benchmark/benchmark.h>

#include "bench/bench_main.h"
#include "render/dynamic_edit.h"
#include "render/renderer.h"
#include "tests/render/edit_test_scene.h"

namespace geodrive {
namespace {

const test_scene::Scene& GetScene() {
  static const test_scene::Scene* scene =
      new test_scene::Scene(test_scene::MakeScene(5));
  return *scene;
}

RenderOptions Options(const test_scene::Scene& scene, int threads) {
  RenderOptions o;
  o.width = scene.camera.width;
  o.height = scene.camera.height;
  o.mode = RenderMode::kZBuffer;
  o.radius_px = 0;
  o.far = 1000;
  o.num_threads = threads;
  return o;
}

void BM_PlainRender(benchmark::State& state) {
  const test_scene::Scene& scene = GetScene();
  const RenderOptions o = Options(scene, static_cast<int>(state.range(0)));
  for (auto _ : state) {
    RenderResult r =
        RenderFrames(scene.cloud, {scene.camera}, scene.cam_from_world, o);
    benchmark::DoNotOptimize(r.frames.data());
  }
  state.counters["points"] = static_cast<double>(scene.cloud.size());
}

// The floor of any per-frame-cloud approach with the public renderer API: 25
// RenderFrame calls on the unedited cloud (each call re-validates and re-packs
// the whole cloud).
void BM_PerFrameRenderCalls(benchmark::State& state) {
  const test_scene::Scene& scene = GetScene();
  RenderOptions o = Options(scene, 1);
  const int threads = static_cast<int>(state.range(0));
  for (auto _ : state) {
    std::vector<RenderedFrame> frames(scene.cam_from_world.size());
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1)
    for (int f = 0; f < static_cast<int>(frames.size()); ++f)
      frames[f] =
          RenderFrame(scene.cloud, scene.camera, scene.cam_from_world[f], o);
    benchmark::DoNotOptimize(frames.data());
  }
}

void BM_Edit(benchmark::State& state, EditMode mode) {
  const test_scene::Scene& scene = GetScene();
  const RenderOptions o = Options(scene, static_cast<int>(state.range(0)));
  DynamicEditOptions e;
  e.mode = mode;
  e.frame0_image = scene.frame0_rgb;
  e.num_threads = o.num_threads;
  int objects = 0;
  for (auto _ : state) {
    DynamicEditResult r =
        RenderWithDynamicEdits(scene.cloud, {scene.camera},
                               scene.cam_from_world, scene.boxes, {}, e, o);
    objects = r.summary.num_objects;
    benchmark::DoNotOptimize(r.frames.data());
  }
  state.counters["points"] = static_cast<double>(scene.cloud.size());
  state.counters["vehicles"] = objects;
}
// The 3D edit's preparation alone: ground plane, segmentation, poses.
void BM_BuildScene3d(benchmark::State& state) {
  const test_scene::Scene& scene = GetScene();
  DynamicEditOptions e;
  size_t drawn = 0, background = 0;
  for (auto _ : state) {
    DynamicEditSummary summary;
    DynamicScene d =
        BuildDynamicScene(scene.cloud, {scene.camera}, scene.cam_from_world,
                          scene.boxes, {}, e, &summary);
    benchmark::DoNotOptimize(d.objects.data());
    drawn = 0;
    for (const DynamicObject& o : d.objects)
      for (const auto& pose : o.poses)
        if (pose) drawn += o.points_in_object.size();
    background = d.NumBackgroundPoints(scene.cloud);
  }
  // Points drawn per frame on average: background + moved object points.
  state.counters["background"] = static_cast<double>(background);
  state.counters["object_points_per_frame"] =
      static_cast<double>(drawn) / scene.cam_from_world.size();
}
BENCHMARK(BM_BuildScene3d)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(1.0);

void BM_Edit3d(benchmark::State& state) { BM_Edit(state, EditMode::k3d); }
void BM_Edit2d(benchmark::State& state) { BM_Edit(state, EditMode::k2d); }

BENCHMARK(BM_PlainRender)
    ->ArgName("threads")
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(2.0);
BENCHMARK(BM_PerFrameRenderCalls)
    ->ArgName("threads")
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(2.0);
BENCHMARK(BM_Edit3d)
    ->ArgName("threads")
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(2.0);
BENCHMARK(BM_Edit2d)
    ->ArgName("threads")
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(2.0);

}  // namespace
}  // namespace geodrive

GEODRIVE_BENCHMARK_MAIN();

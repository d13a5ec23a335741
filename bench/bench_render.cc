// Renderer benchmark: 25 frames at 480x720 from a 345,600-point cloud (one
// full-resolution pointmap of a ray-cast street-like scene), along a forward
// trajectory with a small yaw.
//
//   OMP_NUM_THREADS=1 build/bench/bench_render --benchmark_filter=threads:1
//
// With GEODRIVE_BENCH_RENDER_DUMP=<dir> the scene is also written there for
// other renderers (bench/render_vs_open3d.sh): points.f32 (N x 3 float32,
// world), colors.u8 (N x 3 RGB), cameras.txt (width height fx fy cx cy, then
// one line of 16 numbers per frame: the row-major 4x4 cam_from_world).
//
// Figures and targets: docs/PERFORMANCE.md, section "Renderer".

#include <benchmark/benchmark.h>
#include <omp.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "bench/bench_main.h"
#include "render/renderer.h"
#include "tests/render/render_test_util.h"

#if defined(__x86_64__)
#include <immintrin.h>
#define GEODRIVE_BENCH_STREAM 1
#endif

namespace geodrive {
namespace {

struct Scene {
  PinholeCamera camera{560, 560, 359.5, 239.5, 720, 480};
  PointCloud cloud;
  std::vector<Rigid3d> cam_from_world;
};

// Writes the scene for other renderers (see the file comment).
void DumpScene(const Scene& s, const std::string& dir) {
  std::ofstream points(dir + "/points.f32", std::ios::binary);
  for (const Eigen::Vector3f& p : s.cloud.positions)
    points.write(reinterpret_cast<const char*>(p.data()), 3 * sizeof(float));
  std::ofstream colors(dir + "/colors.u8", std::ios::binary);
  for (const Color3u8& c : s.cloud.colors)
    colors.write(reinterpret_cast<const char*>(c.data()), 3);
  std::ofstream cams(dir + "/cameras.txt");
  cams.precision(17);
  cams << s.camera.width << " " << s.camera.height << " " << s.camera.fx << " "
       << s.camera.fy << " " << s.camera.cx << " " << s.camera.cy << "\n";
  for (const Rigid3d& pose : s.cam_from_world) {
    const Eigen::Matrix4d m = pose.ToMatrix();
    for (int i = 0; i < 16; ++i)
      cams << m(i / 4, i % 4) << (i == 15 ? "\n" : " ");
  }
  if (!points || !colors || !cams) {
    std::fprintf(stderr, "bench_render: could not write the scene to %s\n",
                 dir.c_str());
    std::exit(2);
  }
}

const Scene& GetScene() {
  static const Scene* scene = [] {
    auto* s = new Scene;
    const test::RayCastScene rc = test::RayCast(s->camera, Rigid3d());
    // Pixels without depth (sky) still get a point far away so the cloud has
    // exactly W*H points.
    cv::Mat depth = rc.depth.clone();
    depth.setTo(90.0f, depth <= 0);
    s->cloud = test::Unproject(s->camera, Rigid3d(), depth, rc.rgb);
    for (int f = 0; f < 25; ++f) {
      const Rigid3d world_from_cam(
          QuaternionFromAngleAxis(Eigen::Vector3d(0, 0.004 * f, 0)),
          Eigen::Vector3d(0.02 * f, 0, 0.4 * f));
      s->cam_from_world.push_back(world_from_cam.Inverse());
    }
    if (const char* dir = std::getenv("GEODRIVE_BENCH_RENDER_DUMP"))
      DumpScene(*s, dir);
    return s;
  }();
  return *scene;
}

// Args: mode (0 zbuffer r=0, 1 zbuffer r=1.5 px, 2 soft K=10 r=0.01 NDC),
// threads.
void BM_Render25Frames(benchmark::State& state) {
  const Scene& scene = GetScene();
  RenderOptions options;
  options.width = 720;
  options.height = 480;
  const int mode = static_cast<int>(state.range(0));
  options.mode = mode == 2 ? RenderMode::kSoft : RenderMode::kZBuffer;
  options.radius_px = mode == 1 ? 1.5 : 0.0;
  options.radius_ndc = 0.01;
  options.points_per_pixel = 10;
  options.num_threads = static_cast<int>(state.range(1));
  // Output buffers are reused across iterations (as a clip-rendering loop
  // would), so the timing measures rendering, not first-touch page faults of
  // fresh output images.
  RenderResult r;
  for (auto _ : state) {
    RenderFramesInto(scene.cloud, {scene.camera}, scene.cam_from_world, options,
                     &r);
    benchmark::DoNotOptimize(r.frames.data());
  }
  const double coverage = r.summary.mean_coverage;
  state.counters["points"] = static_cast<double>(scene.cloud.size());
  state.counters["mean_coverage"] = coverage;
  state.SetLabel(mode == 0   ? "zbuffer r=0"
                 : mode == 1 ? "zbuffer r=1.5px"
                             : "soft K=10 r=0.01");
}
BENCHMARK(BM_Render25Frames)
    ->ArgNames({"mode", "threads"})
    ->ArgsProduct({{0, 1, 2}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime()  // CPU time of all threads
    ->MinTime(2.0);

#ifdef GEODRIVE_BENCH_STREAM
// Fills n bytes with v: the 32-byte-aligned body with streaming stores (no
// read of each line before it is written, as the renderer's resolve writes
// outputs larger than the caches), the ends with memset.
__attribute__((target("avx2"))) void StreamFill(uint8_t* p,
                                                size_t n,
                                                uint8_t v) {
  const size_t head =
      std::min(n, (32 - reinterpret_cast<uintptr_t>(p) % 32) % 32);
  std::memset(p, v, head);
  const __m256i x = _mm256_set1_epi8(static_cast<char>(v));
  size_t i = head;
  for (; i + 32 <= n; i += 32)
    _mm256_stream_si256(reinterpret_cast<__m256i*>(p + i), x);
  std::memset(p + i, v, n - i);
  _mm_sfence();
}
#endif

// The bytes the radius-0 z-buffer path cannot avoid moving, and nothing else:
// per frame, the cloud's positions read once (x, y, z arrays, 12 B a point),
// a 64-bit key per pixel read and written once, and the frame's outputs (RGB
// 3 B + depth 4 B + mask 1 B a pixel) written once, with streaming stores
// where the CPU has AVX2 (the renderer's path for outputs this large) and
// memset otherwise. No projection, no depth test, no colour lookup: a
// lower bound for any renderer that writes these outputs, on this machine, in
// the same run as BM_Render25Frames (bench/render_vs_open3d.sh prints it).
// Args: threads (frames split over OpenMP threads as the renderer does).
void BM_TrafficFloor25Frames(benchmark::State& state) {
  const Scene& scene = GetScene();
  const size_t n = scene.cloud.size(), npix = 720 * 480;
  const int frames = static_cast<int>(scene.cam_from_world.size());
  std::vector<uint32_t> x(n), y(n), z(n);
  for (size_t i = 0; i < n; ++i) {
    std::memcpy(&x[i], &scene.cloud.positions[i][0], 4);
    std::memcpy(&y[i], &scene.cloud.positions[i][1], 4);
    std::memcpy(&z[i], &scene.cloud.positions[i][2], 4);
  }
  const int threads = static_cast<int>(state.range(0));
  std::vector<std::vector<uint64_t>> keys(threads,
                                          std::vector<uint64_t>(npix, ~0ull));
  std::vector<std::vector<uint8_t>> rgb(frames, std::vector<uint8_t>(3 * npix));
  std::vector<std::vector<uint8_t>> depth(frames,
                                          std::vector<uint8_t>(4 * npix));
  std::vector<std::vector<uint8_t>> mask(frames, std::vector<uint8_t>(npix));
  uint64_t sink = 0;
#ifdef GEODRIVE_BENCH_STREAM
  const bool avx2 = __builtin_cpu_supports("avx2");
#endif
  for (auto _ : state) {
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1) \
    reduction(^ : sink)
    for (int f = 0; f < frames; ++f) {
      uint32_t acc = static_cast<uint32_t>(f);
      for (size_t i = 0; i < n; ++i) acc ^= x[i] ^ y[i] ^ z[i];
      uint64_t* k = keys[omp_get_thread_num()].data();
      uint64_t kacc = 0;
      for (size_t i = 0; i < npix; ++i) {
        kacc ^= k[i];
        k[i] = ~uint64_t{0} - static_cast<uint64_t>(f);
      }
      for (std::vector<uint8_t>* out : {&rgb[f], &depth[f], &mask[f]}) {
#ifdef GEODRIVE_BENCH_STREAM
        if (avx2) {
          StreamFill(out->data(), out->size(), static_cast<uint8_t>(f));
          continue;
        }
#endif
        std::memset(out->data(), f, out->size());
      }
      sink ^= acc ^ kacc;
    }
    benchmark::DoNotOptimize(sink);
    benchmark::ClobberMemory();
  }
  state.SetLabel(
      "bytes only: points read, keys read+written, outputs written (streamed)");
}
BENCHMARK(BM_TrafficFloor25Frames)
    ->ArgNames({"threads"})
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->MinTime(2.0);

}  // namespace
}  // namespace geodrive

GEODRIVE_BENCHMARK_MAIN();

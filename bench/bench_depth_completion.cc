// lidar-dense: depth completion of a real frame-0 LiDAR depth image
// and the whole scene source, on nuScenes scene-0916 (../shared/data/real, or
// $GEODRIVE_REAL_DATA). Arguments: the working width (800 = the source's
// default, 1600 = CAM_FRONT's full width).
//
//   build/bench/bench_depth_completion --benchmark_filter=.
//
// BM_CompleteDepth: CompleteDepth + unprojection of every completed pixel
// (what the source does per clip after projecting the sweeps; with
// GEODRIVE_BENCH_SPARSE_DUMP=DIR its sparse inputs are written there as .npy
// for the peer, bench/depth_completion_vs_ip_basic.sh);
// BM_LidarDenseScene: the whole source for one clip (sweeps read from disk,
// projection, completion, unprojection, colours, the held-out accuracy on the
// frame-0 sweep (a second completion) and the capture footprints with their
// surface axes; the frame-0 image decoded beforehand, as the builder hands it
// over). One core: OpenCV's thread pool
// is set to one thread, and the CPU time is the whole process's.

#include <cstdlib>
#include <opencv2/core.hpp>
#include <string>

#include "bench/bench_main.h"
#include "dataset/drive_dataset.h"
#include "dataset/scene/lidar_sweeps.h"
#include "dataset/scene_source.h"
#include "geometry/depth_completion.h"
#include "geometry/image_io.h"
#include "geometry/npy.h"

namespace geodrive {
namespace {

std::string RealRoot() {
  const char* env = std::getenv("GEODRIVE_REAL_DATA");
  return std::string(env ? env : GEODRIVE_DEFAULT_REAL_DATA) +
         "/nuscenes_scene0916";
}

const DriveClip& Clip() {
  static const DriveClip clip = [] {
    DriveDatasetOptions o;
    o.root = RealRoot();
    o.version = "v1.0-mini-extract";
    o.frames = ClipFrameSource::kKeyframes;
    return OpenDriveDataset(o)->LoadClip("scene-0916_0006_kf");
  }();
  return clip;
}

void BM_CompleteDepth(benchmark::State& state) {
  cv::setNumThreads(1);
  const DriveClip& clip = Clip();
  const int width = static_cast<int>(state.range(0));
  const PinholeCamera& cam0 = clip.frames.front().camera;
  const PinholeCamera cam =
      ResizeCamera(cam0, width, width * cam0.height / cam0.width);
  const int64_t t0 = clip.frames.front().timestamp_us;
  std::vector<int64_t> times;
  const PointCloud sweeps =
      AggregateStaticSweeps(clip, t0 - 500000, t0 + 50000, &times);
  const cv::Mat sparse = SparseDepthImage(sweeps.positions, cam);
  // The input for the Python peer (bench/depth_completion_vs_ip_basic.sh).
  if (const char* dump = std::getenv("GEODRIVE_BENCH_SPARSE_DUMP")) {
    WriteNpy(
        std::string(dump) + "/sparse_" + std::to_string(width) + ".npy",
        NpyArray::Float32({sparse.rows, sparse.cols}, sparse.ptr<float>()));
  }
  DepthCompletionReport report;
  for (auto _ : state) {
    const cv::Mat dense = CompleteDepth(sparse, {}, &report);
    std::vector<Eigen::Vector3f> points;
    points.reserve(dense.total());
    for (int y = 0; y < dense.rows; ++y) {
      const float* d = dense.ptr<float>(y);
      for (int x = 0; x < dense.cols; ++x)
        if (d[x] > 0.f)
          points.push_back(
              cam.Unproject(Eigen::Vector2d(x, y), d[x]).cast<float>());
    }
    benchmark::DoNotOptimize(points.data());
  }
  state.counters["coverage"] = report.coverage;
  state.counters["returns"] = static_cast<double>(report.input_pixels);
}
BENCHMARK(BM_CompleteDepth)
    ->Arg(800)
    ->Arg(1600)
    ->MeasureProcessCPUTime()
    ->Unit(benchmark::kMillisecond);

void BM_LidarDenseScene(benchmark::State& state) {
  cv::setNumThreads(1);
  const DriveClip& clip = Clip();
  const std::vector<cv::Mat> images = {
      ReadImageRgb(clip.frames.front().image_path)};
  SceneSourceOptions options;
  options.dense_width = static_cast<int>(state.range(0));
  SceneInputs in;
  in.clip = &clip;
  in.clip_images = &images;
  size_t points = 0;
  for (auto _ : state) {
    const ConditionScene scene =
        BuildConditionScene("lidar-dense", in, options);
    points = scene.cloud.size();
  }
  state.counters["points"] = static_cast<double>(points);
}
BENCHMARK(BM_LidarDenseScene)
    ->Arg(800)
    ->Arg(1600)
    ->MeasureProcessCPUTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace geodrive

GEODRIVE_BENCHMARK_MAIN();

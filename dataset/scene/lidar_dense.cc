// Scene source "lidar-dense": a dense, metric frame-0 pointmap from LiDAR
// alone, the paper's scaffold P_0 without a reconstruction. The
// clip's static sweeps in a time window (dataset/scene/lidar_sweeps.h; the
// window policy is SceneSourceOptions::dense_window) are projected into the
// frame-0 camera scaled to `dense_width` (a z-buffer: the nearest return per
// pixel), the sparse depth is completed (geometry/depth_completion.h), and
// every completed pixel is unprojected with the frame-0 camera and coloured
// from the frame-0 image. Pixels above the LiDAR's reach (sky, tall
// structures) stay empty; the scene's `completion` report says how much of
// the image the LiDAR supports and how much of that became points.

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "dataset/scene/define.h"
#include "dataset/scene/lidar_sweeps.h"
#include "geometry/image_io.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

// A LiDAR sweep takes 50 ms (20 Hz): the sweep in progress at frame 0 ends
// (and is stamped) up to that much after the camera's timestamp.
constexpr int64_t kSweepPeriodUs = 50000;
// Seed of the held-out returns (the same in every run: deterministic metas).
constexpr uint64_t kHoldOutSeed = 2026;

// [lo, hi] in microseconds for the window policy.
std::pair<int64_t, int64_t> WindowOf(const DriveClip& clip,
                                     const SceneSourceOptions& options) {
  const int64_t t0 = clip.frames.front().timestamp_us;
  const int64_t lo =
      t0 - static_cast<int64_t>(options.lidar_window_before_s * 1e6);
  switch (options.dense_window) {
    case LidarWindow::kCausal:
      return {lo, t0 + kSweepPeriodUs};
    case LidarWindow::kClip:
      return {lo, clip.frames.back().timestamp_us};
    case LidarWindow::kExplicit:
      return {lo,
              t0 + static_cast<int64_t>(options.lidar_window_after_s * 1e6)};
  }
  return {lo, t0 + kSweepPeriodUs};
}

// The frame-0 sweep: the keyframe sweep of frame 0, or the last sweep at or
// before it; nullopt when there is none.
std::optional<size_t> FrameZeroSweep(const DriveClip& clip) {
  const DriveFrame& f0 = clip.frames.front();
  const std::vector<LidarSweepInfo>& sweeps = clip.lidar->Sweeps();
  if (f0.keyframe_sweep && *f0.keyframe_sweep < sweeps.size())
    return f0.keyframe_sweep;
  std::optional<size_t> last;
  for (size_t i = 0; i < sweeps.size(); ++i)
    if (sweeps[i].timestamp_us <= f0.timestamp_us) last = i;
  return last;
}

// Accuracy of the completion on the frame-0 sweep (the keyframe sweep of
// frame 0, or the last sweep at or before it): a seeded 20 % of its returns
// that project into the camera held out, the rest completed (KITTI depth
// completion's measures). Nullopt when frame 0 has no sweep with returns in
// the image.
std::optional<DepthCompletionAccuracy> FrameZeroHoldOut(
    const DriveClip& clip,
    const PinholeCamera& camera,
    const SceneSourceOptions& options) {
  const std::optional<size_t> s = FrameZeroSweep(clip);
  if (!s) return std::nullopt;
  const int64_t ts = clip.lidar->Sweeps()[*s].timestamp_us;
  std::vector<int64_t> times;
  const PointCloud sweep = AggregateStaticSweeps(clip, ts, ts, &times);
  const cv::Mat sparse = SparseDepthImage(sweep.positions, camera);
  if (cv::countNonZero(sparse) < 10) return std::nullopt;
  return HoldOutAccuracy(sparse, 0.2, kHoldOutSeed, options.completion);
}

class LidarDenseSceneSource : public SceneSource {
 public:
  SceneSourceTraits Traits() const override {
    return {false, true,
            "a dataset clip with LiDAR: frame-0 depth completed from the "
            "sweeps (causal window by default), unprojected and coloured from "
            "frame 0",
            /*folder_marker=*/"", /*full_size_images=*/1};
  }

  ConditionScene Build(const SceneInputs& in,
                       const SceneSourceOptions& options) const override {
    const DriveClip& clip = *in.clip;
    GEODRIVE_CHECK_INPUT(
        clip.lidar != nullptr, clip.dataset, ": ", clip.id,
        ": no LiDAR (nuScenes LIDAR_TOP sweeps, Waymo range images): use a "
        "reconstruction (--geometry monst3r, vggt, da3, cut3r, megasam, moge "
        "or npz)");
    GEODRIVE_CHECK_INPUT(!clip.frames.empty(), clip.id, ": clip has no frames");
    const DriveFrame& frame0 = clip.frames.front();
    const cv::Mat image = in.clip_images && !in.clip_images->empty()
                              ? in.clip_images->front()
                              : ReadImageRgb(frame0.image_path);
    const int width =
        options.dense_width > 0 ? options.dense_width : frame0.camera.width;
    const int height =
        std::max(1, static_cast<int>(std::lround(static_cast<double>(width) *
                                                 frame0.camera.height /
                                                 frame0.camera.width)));
    // What the frame-0 depth holds, checked before any of it is allocated.
    CheckLidarDenseMemory(
        clip.id + ": lidar-dense width " + std::to_string(width), width,
        height);
    const PinholeCamera camera = ResizeCamera(frame0.camera, width, height);
    cv::Mat rgb;
    cv::resize(image, rgb, cv::Size(width, height), 0, 0, cv::INTER_AREA);

    const auto [lo, hi] = WindowOf(clip, options);
    std::vector<int64_t> point_time;
    const std::optional<size_t> frame0_sweep = FrameZeroSweep(clip);
    const PointCloud sweeps = AggregateStaticSweeps(
        clip, lo, hi, &point_time,
        options.dense_objects == LidarObjects::kFrame0 ? frame0_sweep
                                                       : std::nullopt);
    const cv::Mat sparse = SparseDepthImage(sweeps.positions, camera);
    DepthCompletionReport report;
    const cv::Mat dense = CompleteDepth(sparse, options.completion, &report);
    GEODRIVE_CHECK_INPUT(report.input_pixels > 0, clip.id,
                         ": no LiDAR return of the window [", lo, ", ", hi,
                         "] us projects into frame 0's image");

    ConditionScene scene;
    for (int y = 0; y < height; ++y) {
      const float* d = dense.ptr<float>(y);
      const cv::Vec3b* c = rgb.ptr<cv::Vec3b>(y);
      for (int x = 0; x < width; ++x) {
        if (d[x] <= 0.f) continue;
        scene.cloud.positions.push_back(
            camera.Unproject(Eigen::Vector2d(x, y), d[x]).cast<float>());
        scene.cloud.colors.push_back(Color3u8(c[x][0], c[x][1], c[x][2]));
      }
    }
    const Rigid3d cam0_from_world = frame0.world_from_cam.Inverse();
    for (const DriveFrame& f : clip.frames)
      scene.trajectory.Add(f.timestamp_us * 1e-6,
                           cam0_from_world * f.world_from_cam);
    scene.camera = camera;
    scene.has_camera = true;
    scene.frame0_rgb = rgb;
    scene.units = "metres";
    scene.scale.scale = 1.0;
    scene.scale.source = "ego";
    scene.scale.report = "metric from LiDAR and ego poses";
    scene.completion = report;
    scene.completion_accuracy = FrameZeroHoldOut(clip, camera, options);
    scene.completion_sparse = sparse;
    scene.completion_dense = dense;
    scene.description = "LiDAR of " + clip.id + ", " +
                        ToString(options.dense_window) + " window, objects " +
                        ToString(options.dense_objects) +
                        ", completed: " + report.BriefReport();
    return scene;
  }
};

}  // namespace
}  // namespace geodrive

GEODRIVE_DEFINE_SCENE_SOURCE(lidar_dense, geodrive::LidarDenseSceneSource)

// Scene source "lidar": the static LiDAR around frame 0, aggregated from the
// clip's LidarProvider over a time window, in camera 0's frame, coloured from
// the clip's images. Points near the ego vehicle (< 2.5 m horizontally) and
// inside any annotated box (grown 0.3 m) are dropped; a point is coloured by
// the clip frame nearest in time that sees it (projects inside the image and
// is within 5 % of the nearest depth in its 4x4-pixel cell); points that no
// frame sees are dropped. Metric by construction (LiDAR and ego poses).

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

#include "dataset/scene/define.h"
#include "dataset/scene/lidar_sweeps.h"
#include "geometry/image_io.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

// Colours each point from the nearest-in-time frame that sees it; drops the
// points that no frame sees.
PointCloud ColourFromFrames(const DriveClip& clip,
                            const std::vector<cv::Mat>& images,
                            const PointCloud& cloud,
                            const std::vector<int64_t>& point_time) {
  const size_t n = cloud.size();
  std::vector<int> best_frame(n, -1);
  std::vector<int64_t> best_dt(n, INT64_MAX);
  std::vector<Color3u8> colors(n, Color3u8(0, 0, 0));
  const Rigid3d& world_from_cam0 = clip.frames.front().world_from_cam;
  for (size_t f = 0; f < clip.frames.size(); ++f) {
    const DriveFrame& frame = clip.frames[f];
    const PinholeCamera& cam = frame.camera;
    const Matrix3x4d cam_from_cam0 =
        (frame.world_from_cam.Inverse() * world_from_cam0).ToMatrix3x4();
    const Eigen::Matrix3d rotation = cam_from_cam0.leftCols<3>();
    const Eigen::Vector3d translation = cam_from_cam0.col(3);
    const int cw = (cam.width + 3) / 4, ch = (cam.height + 3) / 4;
    std::vector<float> zmin(static_cast<size_t>(cw) * ch,
                            std::numeric_limits<float>::infinity());
    std::vector<Eigen::Vector3f> proj(n);
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d pc =
          rotation * cloud.positions[i].cast<double>() + translation;
      proj[i] = Eigen::Vector3f(-1, -1, -1);
      if (pc.z() < 1.0) continue;
      const Eigen::Vector2d uv = cam.Project(pc);
      if (uv.x() < 0 || uv.y() < 0 || uv.x() > cam.width - 1 ||
          uv.y() > cam.height - 1)
        continue;
      proj[i] = Eigen::Vector3f(uv.x(), uv.y(), pc.z());
      float& z = zmin[static_cast<size_t>(uv.y() / 4) * cw +
                      static_cast<size_t>(uv.x() / 4)];
      z = std::min(z, static_cast<float>(pc.z()));
    }
    const cv::Mat& img = images[f];
    for (size_t i = 0; i < n; ++i) {
      if (proj[i].z() <= 0) continue;
      const float z = zmin[static_cast<size_t>(proj[i].y() / 4) * cw +
                           static_cast<size_t>(proj[i].x() / 4)];
      if (proj[i].z() > z * 1.05f) continue;
      const int64_t dt = std::llabs(frame.timestamp_us - point_time[i]);
      if (dt >= best_dt[i]) continue;
      best_dt[i] = dt;
      best_frame[i] = static_cast<int>(f);
      const cv::Vec3b c =
          img.at<cv::Vec3b>(static_cast<int>(std::lround(proj[i].y())),
                            static_cast<int>(std::lround(proj[i].x())));
      colors[i] = Color3u8(c[0], c[1], c[2]);
    }
  }
  PointCloud out;
  for (size_t i = 0; i < n; ++i) {
    if (best_frame[i] < 0) continue;
    out.positions.push_back(cloud.positions[i]);
    out.colors.push_back(colors[i]);
  }
  return out;
}

class LidarSceneSource : public SceneSource {
 public:
  SceneSourceTraits Traits() const override {
    return {false, true,
            "a dataset clip with LiDAR: sweeps around frame 0, coloured from "
            "the clip's images",
            /*folder_marker=*/"", /*full_size_images=*/-1};
  }
  ConditionScene Build(const SceneInputs& in,
                       const SceneSourceOptions& options) const override {
    const DriveClip& clip = *in.clip;
    GEODRIVE_CHECK_INPUT(clip.lidar != nullptr, clip.dataset,
                         ": dataset has no LIDAR_TOP: use --geometry monst3r");
    GEODRIVE_CHECK_INPUT(!clip.frames.empty(), clip.id, ": clip has no frames");
    std::vector<cv::Mat> read;
    const std::vector<cv::Mat>* images = in.clip_images;
    if (!images) {
      for (const DriveFrame& f : clip.frames)
        read.push_back(ReadImageRgb(f.image_path));
      images = &read;
    }
    GEODRIVE_CHECK_INPUT(images->size() == clip.frames.size(), clip.id, ": ",
                         images->size(), " images for ", clip.frames.size(),
                         " frames");
    std::vector<int64_t> point_time;
    const int64_t t0 = clip.frames.front().timestamp_us;
    const PointCloud all = AggregateStaticSweeps(
        clip, t0 - static_cast<int64_t>(options.lidar_window_before_s * 1e6),
        t0 + static_cast<int64_t>(options.lidar_window_after_s * 1e6),
        &point_time);
    ConditionScene scene;
    scene.cloud = ColourFromFrames(clip, *images, all, point_time);
    GEODRIVE_CHECK_INPUT(!scene.cloud.empty(), clip.id,
                         ": no LiDAR point of the clip is visible in its "
                         "images");
    const Rigid3d cam0_from_world =
        clip.frames.front().world_from_cam.Inverse();
    for (const DriveFrame& f : clip.frames)
      scene.trajectory.Add(f.timestamp_us * 1e-6,
                           cam0_from_world * f.world_from_cam);
    scene.camera = clip.frames.front().camera;
    scene.has_camera = true;
    scene.frame0_rgb = images->front();
    scene.units = "metres";
    scene.scale.scale = 1.0;
    scene.scale.source = "ego";
    scene.scale.report = "metric from LiDAR and ego poses";
    scene.description = "LiDAR of " + clip.id;
    return scene;
  }
};

}  // namespace
}  // namespace geodrive

GEODRIVE_DEFINE_SCENE_SOURCE(lidar, geodrive::LidarSceneSource)

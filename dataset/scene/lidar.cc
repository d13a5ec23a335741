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
    // Plain scalars per point (no Eigen temporaries): this loop runs points x
    // frames times, and Eigen's small expressions made it 17x slower than the
    // Release build under the sanitizer build. Same formulas as
    // PinholeCamera::Project (kIntegerIndex).
    double rot[9], trans[3];
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) rot[3 * r + c] = cam_from_cam0(r, c);
      trans[r] = cam_from_cam0(r, 3);
    }
    const int cw = (cam.width + 3) / 4, ch = (cam.height + 3) / 4;
    std::vector<float> zmin(static_cast<size_t>(cw) * ch,
                            std::numeric_limits<float>::infinity());
    struct Projected {
      float u, v, z;  // z <= 0: not seen in this frame
    };
    std::vector<Projected> proj(n, Projected{-1, -1, -1});
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3f& p = cloud.positions[i];
      const double x = p.x(), y = p.y(), zw = p.z();
      const double pz = rot[6] * x + rot[7] * y + rot[8] * zw + trans[2];
      if (pz < 1.0) continue;
      const double px = rot[0] * x + rot[1] * y + rot[2] * zw + trans[0];
      const double py = rot[3] * x + rot[4] * y + rot[5] * zw + trans[1];
      const double u = cam.fx * px / pz + cam.cx, v = cam.fy * py / pz + cam.cy;
      if (u < 0 || v < 0 || u > cam.width - 1 || v > cam.height - 1) continue;
      proj[i] = Projected{static_cast<float>(u), static_cast<float>(v),
                          static_cast<float>(pz)};
      float& z =
          zmin[static_cast<size_t>(v / 4) * cw + static_cast<size_t>(u / 4)];
      z = std::min(z, static_cast<float>(pz));
    }
    const cv::Mat& img = images[f];
    for (size_t i = 0; i < n; ++i) {
      if (proj[i].z <= 0) continue;
      const float z = zmin[static_cast<size_t>(proj[i].v / 4) * cw +
                           static_cast<size_t>(proj[i].u / 4)];
      if (proj[i].z > z * 1.05f) continue;
      const int64_t dt = std::llabs(frame.timestamp_us - point_time[i]);
      if (dt >= best_dt[i]) continue;
      best_dt[i] = dt;
      best_frame[i] = static_cast<int>(f);
      const cv::Vec3b c =
          img.at<cv::Vec3b>(static_cast<int>(std::lround(proj[i].v)),
                            static_cast<int>(std::lround(proj[i].u)));
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
    GEODRIVE_CHECK_INPUT(
        clip.lidar != nullptr, clip.dataset, ": ", clip.id,
        ": no LiDAR (nuScenes LIDAR_TOP sweeps, Waymo range images): use a "
        "reconstruction (--geometry monst3r, vggt, da3, cut3r, megasam, moge "
        "or npz)");
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

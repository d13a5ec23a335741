#pragma once
// LiDAR -> image, exact to the nuScenes devkit's
// `NuScenesExplorer.map_pointcloud_to_image` (five transforms, depth >
// min_dist, 1 < u < W - 1, 1 < v < H - 1), for any dataset that gives ego
// poses and sensor mountings (dataset/drive_clip.h). Pixels are kIntegerIndex
// (K, no +0.5), as the devkit's view_points. Implemented in
// nuscenes_projection.cc with the nuScenes-specific projections.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "geometry/rigid3.h"

namespace geodrive {

struct LidarProjectionOptions {
  double min_dist =
      1.0;  // keep points with camera depth > min_dist (m), as the devkit
  // Devkit border rule 1 < u < W - 1, 1 < v < H - 1 (true) or plain 0 <= u < W,
  // 0 <= v < H.
  bool devkit_border = true;
  void Check() const;
};

// Points of a cloud that land in the image: pixel (u, v), camera depth (z) and
// the index of the point in the input cloud, in input order.
struct LidarProjection {
  std::vector<Eigen::Vector2d> pixels;
  std::vector<double> depths;
  std::vector<int32_t> indices;
  size_t size() const { return indices.size(); }
};

// The devkit's five transforms: lidar -> ego(lidar time) -> global ->
// ego(camera time) -> camera, then K. Mirrors the devkit's float32 point
// storage between steps (LidarPointCloud keeps points as float32 and every
// rotate/translate rounds), so borderline points agree with the devkit.
LidarProjection MapPointCloudToImage(
    const std::vector<Eigen::Vector3f>& points_in_lidar,
    const Rigid3d& ego_from_lidar,
    const Rigid3d& global_from_ego_at_lidar,
    const Rigid3d& global_from_ego_at_cam,
    const Rigid3d& ego_from_cam,
    const Eigen::Matrix3d& K,
    int width,
    int height,
    const LidarProjectionOptions& options = {});

// The same with the whole chain given as one 4x4 cam_from_lidar (e.g.
// mmdetection3d's `lidar2cam`), computed in double precision.
LidarProjection ProjectLidarToImage(
    const std::vector<Eigen::Vector3f>& points_in_lidar,
    const Eigen::Matrix4d& cam_from_lidar,
    const Eigen::Matrix3d& K,
    int width,
    int height,
    const LidarProjectionOptions& options = {});

}  // namespace geodrive

// The static LiDAR around a clip's frame 0 (dataset/scene/lidar_sweeps.h).

#include "dataset/scene/lidar_sweeps.h"

#include <cmath>

namespace geodrive {

PointCloud AggregateStaticSweeps(const DriveClip& clip,
                                 int64_t lo,
                                 int64_t hi,
                                 std::vector<int64_t>* point_time,
                                 std::optional<size_t> keep_objects_of) {
  const LidarProvider& lidar = *clip.lidar;
  // [R | t]: one matrix product per point instead of a quaternion rotation
  // (these loops run over every point of every sweep, and every frame).
  const Matrix3x4d cam0_from_world =
      clip.frames.front().world_from_cam.Inverse().ToMatrix3x4();
  PointCloud cloud;
  const auto add = [&](const Eigen::Vector3d& g, int64_t t) {
    cloud.positions.push_back(
        (cam0_from_world.leftCols<3>() * g + cam0_from_world.col(3))
            .cast<float>());
    point_time->push_back(t);
  };
  for (size_t s : lidar.SweepsBetween(lo, hi)) {
    const LidarSweepInfo& info = lidar.Sweeps()[s];
    if (keep_objects_of != s) {
      // The provider's static returns (memoised where cameras share it).
      const auto points = lidar.StaticInWorld(s);  // held for the loop
      for (const Eigen::Vector3d& g : *points) add(g, info.timestamp_us);
      continue;
    }
    // The objects' returns kept: only the ego vehicle's own are dropped.
    const PointCloud sweep = lidar.Load(s);
    const Matrix3x4d world_from_lidar = info.WorldFromSensor().ToMatrix3x4();
    for (size_t i = 0; i < sweep.size(); ++i) {
      const Eigen::Vector3d p = sweep.positions[i].cast<double>();
      if (p.head<2>().norm() < LidarProvider::kEgoReturnRadiusM) continue;
      add(world_from_lidar.leftCols<3>() * p + world_from_lidar.col(3),
          info.timestamp_us);
    }
  }
  return cloud;
}

}  // namespace geodrive

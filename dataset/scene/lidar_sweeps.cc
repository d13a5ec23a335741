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
  constexpr double kBoxMargin = 0.3;
  PointCloud cloud;
  for (size_t s : lidar.SweepsBetween(lo, hi)) {
    const LidarSweepInfo& info = lidar.Sweeps()[s];
    const PointCloud sweep = lidar.Load(s);
    const Matrix3x4d world_from_lidar = info.WorldFromSensor().ToMatrix3x4();
    const std::vector<ClipBox> boxes =
        keep_objects_of == s ? std::vector<ClipBox>() : lidar.Boxes(s);
    // Each box's bounding sphere (grown by the margin): the exact test runs
    // only for points inside it.
    std::vector<double> radius2(boxes.size());
    for (size_t b = 0; b < boxes.size(); ++b) {
      const double r =
          boxes[b].box.HalfExtents().norm() + kBoxMargin * std::sqrt(3.0);
      radius2[b] = r * r;
    }
    for (size_t i = 0; i < sweep.size(); ++i) {
      const Eigen::Vector3d p = sweep.positions[i].cast<double>();
      if (p.head<2>().norm() < 2.5) continue;  // ego vehicle returns
      const Eigen::Vector3d g =
          world_from_lidar.leftCols<3>() * p + world_from_lidar.col(3);
      bool in_box = false;
      for (size_t b = 0; b < boxes.size() && !in_box; ++b) {
        in_box = (g - boxes[b].box.center).squaredNorm() <= radius2[b] &&
                 boxes[b].box.Contains(g, kBoxMargin);
      }
      if (in_box) continue;
      cloud.positions.push_back(
          (cam0_from_world.leftCols<3>() * g + cam0_from_world.col(3))
              .cast<float>());
      point_time->push_back(info.timestamp_us);
    }
  }
  return cloud;
}

}  // namespace geodrive

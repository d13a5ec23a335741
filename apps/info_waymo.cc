#include "apps/info_waymo.h"

#include <iomanip>
#include <iostream>
#include <sstream>
#include <vector>

#include "dataset/waymo/waymo_frame.h"

namespace geodrive {

namespace {

// The three rows of a rigid 4x4 (the fourth is 0 0 0 1).
std::string RigidRows(const Eigen::Matrix4d& m) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(6);
  for (int r = 0; r < 3; ++r) {
    os << (r ? "; " : "[");
    for (int c = 0; c < 4; ++c) os << (c ? " " : "") << m(r, c);
  }
  os << "]";
  return os.str();
}

}  // namespace

void DescribeWaymoSegment(const std::string& path) {
  const std::vector<WaymoFrame> frames = ReadWaymoFrames(path);
  std::cout << path << ": Waymo Open Dataset v1 TFRecord, " << frames.size()
            << " frame(s)";
  if (!frames.empty()) std::cout << ", segment " << frames[0].context_name;
  std::cout << "\n";
  for (size_t i = 0; i < frames.size(); ++i) {
    const WaymoFrame& f = frames[i];
    std::cout << "  frame " << i << ": timestamp " << f.timestamp_micros
              << " us, world_from_vehicle " << RigidRows(f.world_from_vehicle)
              << "\n    " << f.images.size() << " camera image(s), "
              << f.laser_labels.size() << " laser_labels, "
              << f.projected_lidar_labels.size()
              << " cameras with projected_lidar_labels, "
              << f.camera_labels.size() << " with camera_labels, "
              << f.num_lasers << " lasers, "
              << (f.has_range_images ? "range images" : "no range images")
              << "\n";
  }
  if (frames.empty()) return;
  // Calibrations are the segment's context: frame 0's.
  std::cout << "  camera calibrations (vehicle_from_camera in OpenCV axes: x "
               "right, y down, z forward):\n";
  for (const WaymoCameraCalibration& c : frames[0].camera_calibrations) {
    const WaymoIntrinsics& k = c.intrinsics;
    std::cout << "    " << ToString(c.name) << ": " << c.width << "x"
              << c.height << ", f_u " << k.f_u << " f_v " << k.f_v << " c_u "
              << k.c_u << " c_v " << k.c_v << ", k1 " << k.k1 << " k2 " << k.k2
              << " p1 " << k.p1 << " p2 " << k.p2 << " k3 " << k.k3
              << ", rolling shutter " << ToString(c.rolling_shutter)
              << "\n      vehicle_from_camera "
              << RigidRows(c.vehicle_from_camera) << "\n";
  }
}

}  // namespace geodrive

#ifndef GEODRIVE_COMMANDS_BUILT_IN
// The plugin's entry point for `info FILE.tfrecord` (apps/info_command.cc).
extern "C" __attribute__((visibility("default"))) void
GeodriveDescribeWaymoSegment(const std::string& path) {
  geodrive::DescribeWaymoSegment(path);
}
#endif

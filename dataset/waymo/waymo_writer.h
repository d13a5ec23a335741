#pragma once
// Writing Waymo Open Dataset v1 frames: the inverse of waymo_frame.h and
// waymo_range_image.h on the same plain structs, so that a writer (the
// synthetic world's `geodrive synth --format waymo`) and the reader share one
// definition of every convention. Protobuf stays inside waymo_writer.cc.

#include <string>
#include <utility>
#include <vector>

#include "dataset/waymo/waymo_frame.h"
#include "dataset/waymo/waymo_range_image.h"

namespace geodrive {

// Context.stats of a segment.
struct WaymoContextStats {
  // "Day", "Dawn/Dusk" or "Night" in Waymo's segments.
  std::string time_of_day;
  std::string location;
  std::string weather;
  // Objects per type in the frame's laser labels and camera labels.
  std::vector<std::pair<WaymoObjectType, int>> laser_object_counts;
  std::vector<std::pair<WaymoObjectType, int>> camera_object_counts;
};

// zlib (level 6) of a serialized MatrixFloat with shape [height, width,
// channels] holding image.values: what DecodeWaymoRangeImage reads.
std::string CompressWaymoRangeImage(const WaymoRangeImage& image);

// One serialized `Frame`: context (name, the camera and laser calibrations,
// `stats`), timestamp, pose, camera images, lasers (each return's
// range_image_compressed, TOP's range_image_pose_compressed), laser_labels,
// projected_lidar_labels and camera_labels. Camera extrinsics are written in
// Waymo's camera axes (VehicleFromWaymoCamera). Deterministic bytes.
// ParseWaymoFrame of the result gives `frame` back.
std::string SerializeWaymoFrame(const WaymoFrame& frame,
                                const WaymoContextStats& stats);

}  // namespace geodrive

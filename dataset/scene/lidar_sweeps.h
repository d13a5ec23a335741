#pragma once
// For the LiDAR scene sources of dataset/scene/ and the planning scene
// (planning/clip_scene.cc) only: the clip's sweeps in a
// time window, motion-compensated with each sweep's ego pose into camera 0's
// frame. Points near the ego vehicle (< 2.5 m horizontally) and inside any
// annotated box of the sweep (grown 0.3 m) are dropped: what is left is the
// static scene (optionally with the objects of one sweep kept).

#include <cstdint>
#include <optional>
#include <vector>

#include "dataset/drive_clip.h"
#include "geometry/point_cloud.h"

namespace geodrive {

// Static points of the sweeps with timestamps in [lo, hi] (microseconds), in
// camera 0's frame; `point_time` receives each point's sweep time. The sweep
// `keep_objects_of` (an index into the provider's Sweeps()) keeps the points
// inside its boxes too.
PointCloud AggregateStaticSweeps(
    const DriveClip& clip,
    int64_t lo,
    int64_t hi,
    std::vector<int64_t>* point_time,
    std::optional<size_t> keep_objects_of = std::nullopt);

}  // namespace geodrive

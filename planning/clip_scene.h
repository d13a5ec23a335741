#pragma once
// The planning scene of a dataset clip (dataset/drive_clip.h): its boxes as
// obstacle tracks, its static LiDAR cloud and its logged ego trajectory, all
// in the ego frame of the clip's first frame (planning/candidates.h).

#include "dataset/drive_clip.h"
#include "planning/scores.h"

namespace geodrive {

struct ClipSceneOptions {
  // LiDAR sweeps from this long before the first frame to the last frame
  // make the static cloud (s): the ground under and behind the ego at frame
  // 0 is seen only by earlier sweeps.
  double lidar_before_s = 1.0;
  // At most this many sweeps of that window, evenly strided; in [1, 256]
  // (ground is segmented per sweep, PlanningScene::static_cloud_sweep).
  int max_sweeps = 40;
  // Without LiDAR (or with this off) the scene has no static cloud.
  bool static_cloud = true;

  bool Check() const;
};

// Obstacles: one track per box instance of the clip's frames (times in
// seconds since frame 0); static cloud: the clip's sweeps with the points
// near the ego and inside any box of their sweep dropped
// (AggregateStaticSweeps); logged: the frames' ego poses. Throws InputError
// for an empty clip or a sweep that cannot be read.
PlanningScene PlanningSceneFromClip(const DriveClip& clip,
                                    const ClipSceneOptions& options = {});

// ego0_from_world of a clip (the inverse of frame 0's world_from_ego).
Rigid3d Ego0FromWorld(const DriveClip& clip);

}  // namespace geodrive

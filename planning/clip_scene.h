#pragma once
// The planning scene of a dataset clip (dataset/drive_clip.h): its boxes as
// obstacle tracks, its static LiDAR cloud and its logged ego trajectory, all
// in the ego frame of the clip's first frame (planning/candidates.h).

#include <vector>

#include "dataset/drive_clip.h"
#include "planning/candidates.h"
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

// The logged trajectory as a candidate named "logged".
Candidate LoggedCandidate(const PlanningScene& scene);
// The lattice of a scene: from the logged start speed, over the logged time
// span with one waypoint per logged pose (at least 1 s), on a grid denser
// than LatticeOptions' default (lateral offsets every 0.5 m in [-3.5, 3.5],
// accelerations {-3, -2, -1, -0.5, 0, 0.5, 1, 2}, yaw rates {0, +-0.05,
// +-0.1, +-0.15}), thinned to `max_candidates`.
LatticeOptions SceneLatticeOptions(const PlanningScene& scene,
                                   int max_candidates,
                                   const KinematicEnvelope& envelope = {});
// What `geodrive plan` and geodrive.plan() score: the logged trajectory
// (with_logged), its lateral shifts by +-each of `shifts` (m; named
// "logged+1m", "logged-1m"), then `extra`, then `sample` lattice cells.
// Throws InputError when that is no candidate at all.
std::vector<Candidate> GatherCandidates(const PlanningScene& scene,
                                        bool with_logged,
                                        const std::vector<double>& shifts,
                                        std::vector<Candidate> extra,
                                        int sample,
                                        const KinematicEnvelope& envelope = {});

// ego0_from_world of a clip (the inverse of frame 0's world_from_ego).
Rigid3d Ego0FromWorld(const DriveClip& clip);

}  // namespace geodrive

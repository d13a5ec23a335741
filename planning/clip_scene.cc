#include "planning/clip_scene.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include "dataset/scene/lidar_sweeps.h"
#include "geometry/util/status.h"

namespace geodrive {

bool ClipSceneOptions::Check() const {
  return std::isfinite(lidar_before_s) && lidar_before_s >= 0 &&
         max_sweeps >= 1 && max_sweeps <= 256;
}

Rigid3d Ego0FromWorld(const DriveClip& clip) {
  GEODRIVE_CHECK_INPUT(!clip.frames.empty(), "clip ", clip.id, ": no frames");
  return clip.frames.front().world_from_ego.Inverse();
}

PlanningScene PlanningSceneFromClip(const DriveClip& clip,
                                    const ClipSceneOptions& options) {
  GEODRIVE_CHECK_INPUT(options.Check(),
                       "clip scene options: lidar_before_s must be >= 0 "
                       "and max_sweeps in [1, 256]");
  const Rigid3d ego0_from_world = Ego0FromWorld(clip);
  const int64_t t0 = clip.frames.front().timestamp_us;
  PlanningScene scene;
  std::map<std::string, size_t> track_of;
  for (const DriveFrame& f : clip.frames) {
    const double t = (f.timestamp_us - t0) * 1e-6;
    scene.logged.Add(t, ego0_from_world * f.world_from_ego);
    for (const ClipBox& b : f.boxes) {
      auto [it, added] =
          track_of.emplace(b.instance_id, scene.obstacles.size());
      if (added) {
        ObstacleTrack track;
        track.id = b.instance_id;
        track.category = b.category;
        scene.obstacles.push_back(track);
      }
      ObstacleTrack& track = scene.obstacles[it->second];
      // Frames sharing a timestamp keep the first box.
      if (!track.times.empty() && t <= track.times.back()) continue;
      track.times.push_back(t);
      track.boxes.push_back(b.box.Transformed(ego0_from_world));
    }
  }
  if (!options.static_cloud || !clip.lidar) return scene;
  const int64_t lo =
      t0 - static_cast<int64_t>(std::llround(options.lidar_before_s * 1e6));
  const int64_t hi = clip.frames.back().timestamp_us;
  std::vector<size_t> sweeps = clip.lidar->SweepsBetween(lo, hi);
  if (sweeps.size() > static_cast<size_t>(options.max_sweeps)) {
    std::vector<size_t> some;
    const size_t m = static_cast<size_t>(options.max_sweeps);
    for (size_t k = 0; k < m; ++k)
      some.push_back(sweeps[m == 1 ? 0 : k * (sweeps.size() - 1) / (m - 1)]);
    sweeps = some;
  }
  // AggregateStaticSweeps gives camera 0's frame: ego0 = ego_from_cam0 * p.
  const Matrix3x4d ego0_from_cam0 =
      clip.frames.front().ego_from_cam.ToMatrix3x4();
  std::vector<int64_t> point_time;
  for (size_t k = 0; k < sweeps.size(); ++k) {
    const LidarSweepInfo& info = clip.lidar->Sweeps()[sweeps[k]];
    const int64_t ts = info.timestamp_us;
    scene.sweep_origins.push_back(
        (ego0_from_world * info.WorldFromSensor()).translation);
    const PointCloud part = AggregateStaticSweeps(clip, ts, ts, &point_time);
    for (const Eigen::Vector3f& p : part.positions) {
      scene.static_cloud.positions.push_back(
          (ego0_from_cam0.leftCols<3>() * p.cast<double>() +
           ego0_from_cam0.col(3))
              .cast<float>());
      scene.static_cloud_sweep.push_back(static_cast<int32_t>(k));
    }
  }
  return scene;
}

Candidate LoggedCandidate(const PlanningScene& scene) {
  Candidate logged;
  logged.name = "logged";
  logged.source = "the clip's ego poses";
  logged.ego0_from_ego = scene.logged;
  return logged;
}

LatticeOptions SceneLatticeOptions(const PlanningScene& scene,
                                   int max_candidates,
                                   const KinematicEnvelope& envelope) {
  LatticeOptions lattice;
  const std::vector<double> speeds = scene.logged.SegmentSpeeds();
  lattice.initial_speed = speeds.empty() ? 0.0 : speeds.front();
  lattice.max_speed = std::max(lattice.max_speed, lattice.initial_speed);
  lattice.horizon_s = std::max(scene.logged.Duration(), 1.0);
  lattice.dt_s =
      lattice.horizon_s /
      static_cast<double>(std::max<size_t>(scene.logged.size(), 2) - 1);
  lattice.lane_change_s = std::min(lattice.lane_change_s, lattice.horizon_s);
  lattice.lateral_offsets.clear();
  for (int k = -7; k <= 7; ++k) lattice.lateral_offsets.push_back(0.5 * k);
  lattice.accelerations = {-3.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0};
  lattice.yaw_rates = {-0.15, -0.1, -0.05, 0.0, 0.05, 0.1, 0.15};
  lattice.max_candidates = max_candidates;
  lattice.envelope = envelope;
  return lattice;
}

std::vector<Candidate> GatherCandidates(const PlanningScene& scene,
                                        bool with_logged,
                                        const std::vector<double>& shifts,
                                        std::vector<Candidate> extra,
                                        int sample,
                                        const KinematicEnvelope& envelope) {
  std::vector<Candidate> out;
  const Candidate logged = LoggedCandidate(scene);
  if (with_logged) out.push_back(logged);
  for (double d : shifts) {
    for (double sign : {1.0, -1.0}) {
      char suffix[32];
      std::snprintf(suffix, sizeof suffix, "%+gm", sign * d);
      out.push_back(ShiftLaterally(logged, sign * d, suffix));
    }
  }
  for (Candidate& c : extra) out.push_back(std::move(c));
  if (sample > 0) {
    for (Candidate& c :
         SampleLattice(SceneLatticeOptions(scene, sample, envelope)))
      out.push_back(std::move(c));
  }
  GEODRIVE_CHECK_INPUT(!out.empty(),
                       "no candidates: give candidate files, a lattice "
                       "sample or shifts, or keep the logged trajectory");
  return out;
}

}  // namespace geodrive

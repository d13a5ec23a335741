// `geodrive plan`: scores candidate ego trajectories of a clip against its
// geometry (boxes over time, static LiDAR cloud, logged trajectory) and
// writes plan.json and a bird's-eye view.

#include <cstdio>
#include <iostream>
#include <memory>

#include "apps/cli/cli.h"
#include "dataset/drive_dataset.h"
#include "geometry/image_io.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"
#include "planning/bev.h"
#include "planning/candidates.h"
#include "planning/clip_scene.h"
#include "planning/plan_json.h"
#include "planning/scores.h"

namespace geodrive {
namespace {

struct PlanArgs {
  std::string dataroot, version = "v1.0-mini", clip, out;
  std::string frames = "all";
  std::vector<std::string> candidates;
  int sample = 0;
  std::vector<double> shifts;
  bool no_logged = false;
  PlanScoreOptions score;
};

// The logged trajectory as a candidate, its lateral shifts, the files and
// the lattice.
std::vector<Candidate> GatherCandidates(const PlanArgs& a,
                                        const DriveClip& clip,
                                        const PlanningScene& scene) {
  std::vector<Candidate> out;
  Candidate logged;
  logged.name = "logged";
  logged.source = "the clip's ego poses";
  logged.ego0_from_ego = scene.logged;
  if (!a.no_logged) out.push_back(logged);
  for (double d : a.shifts) {
    for (double sign : {1.0, -1.0}) {
      char suffix[32];
      std::snprintf(suffix, sizeof suffix, "%+gm", sign * d);
      out.push_back(ShiftLaterally(logged, sign * d, suffix));
    }
  }
  for (const std::string& path : a.candidates) {
    for (Candidate& c : ReadCandidates(path, clip.frames.front().ego_from_cam))
      out.push_back(std::move(c));
  }
  if (a.sample > 0) {
    LatticeOptions lattice;
    const std::vector<double> speeds = scene.logged.SegmentSpeeds();
    lattice.initial_speed = speeds.empty() ? 0.0 : speeds.front();
    lattice.max_speed = std::max(lattice.max_speed, lattice.initial_speed);
    // The clip's time span and frame count: one waypoint per frame.
    lattice.horizon_s = std::max(scene.logged.Duration(), 1.0);
    lattice.dt_s =
        lattice.horizon_s / std::max<size_t>(scene.logged.size() - 1, 1);
    lattice.lane_change_s = std::min(lattice.lane_change_s, lattice.horizon_s);
    // A denser grid than the library's default (15 x 8 x 7 cells), thinned
    // to --sample evenly.
    lattice.lateral_offsets.clear();
    for (int k = -7; k <= 7; ++k) lattice.lateral_offsets.push_back(0.5 * k);
    lattice.accelerations = {-3.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0};
    lattice.yaw_rates = {-0.15, -0.1, -0.05, 0.0, 0.05, 0.1, 0.15};
    lattice.max_candidates = a.sample;
    lattice.envelope = a.score.envelope;
    for (Candidate& c : SampleLattice(lattice)) out.push_back(std::move(c));
  }
  GEODRIVE_CHECK_INPUT(!out.empty(),
                       "no candidates: give --candidates, --sample or "
                       "--shifts, or drop --no-logged");
  return out;
}

int Run(const PlanArgs& a) {
  CreateOutputDirectory(a.out);
  DriveDatasetOptions dso;
  dso.root = a.dataroot;
  dso.version = a.version;
  dso.clip_stride = 1;  // every start: any clip id resolves
  dso.frames = ParseClipFrameSource(a.frames);
  const std::unique_ptr<DriveDataset> dataset = OpenDriveDataset(dso);
  DriveClip clip;
  try {
    clip = dataset->LoadClip(a.clip);
  } catch (const InputError& e) {
    ThrowInputError("--clip", e.what());
  }
  const PlanningScene scene = PlanningSceneFromClip(clip);
  const std::vector<Candidate> candidates = GatherCandidates(a, clip, scene);
  const PlanResult result = ScoreCandidates(scene, candidates, a.score);
  WriteFileAtomic(a.out + "/plan.json",
                  PlanResultToJson(clip.id, candidates, result, a.score));
  WriteImageRgb(a.out + "/bev.png",
                DrawPlanBev(scene, candidates, result, a.score));
  std::printf("plan %s: %s\n", clip.id.c_str(), result.BriefReport().c_str());
  std::printf("%-4s %-28s %10s %9s %9s %9s %8s  %s\n", "rank", "candidate",
              "cost", "min_d_m", "drivable", "clear_m@s", "ade_m", "rejected");
  for (int i : result.ranking) {
    const CandidateScores& s = result.candidates[i];
    std::printf("%-4d %-28s %10.3f %9.3f %9.3f %5.2f@%-4.1f %8.3f  %s\n",
                s.rank, s.name.c_str(), s.cost, s.min_box_distance,
                s.drivable_fraction, s.static_clearance,
                s.static_clearance_time, s.ade, s.reject_detail.c_str());
  }
  std::printf("wrote %s/{plan.json, bev.png}\n", a.out.c_str());
  return kExitOk;
}

CommandRunner SetupPlan(CLI::App& app) {
  auto a = std::make_shared<PlanArgs>();
  app.footer(
      "Candidates are in the ego frame of the clip's first frame (x forward, "
      "y left, metres;\n"
      "times in seconds since that frame): JSON-lines files of waypoints {t, "
      "x, y[, z, yaw]}, or\n"
      "any trajectory file geodrive reads (a camera trajectory, put on the "
      "ego through the\n"
      "clip's camera mounting). Each is scored for collision with the boxes "
      "(BEV), drivable\n"
      "ground and clearance from the static LiDAR, kinematics and ADE/FDE to "
      "the logged\n"
      "trajectory, then ranked by a weighted cost (docs/PLANNING.md).");
  app.add_option("--dataroot", a->dataroot, "nuScenes root")->required();
  app.add_option("--version", a->version, "Table folder")
      ->capture_default_str();
  app.add_option("--clip", a->clip, "Clip id, e.g. scene-0001_0024")
      ->required();
  app.add_option("--frames", a->frames,
                 "Clip frames: all or keyframes (ids end in _kf)")
      ->check(CLI::IsMember({"all", "keyframes"}))
      ->capture_default_str();
  app.add_option("--out", a->out, "Output folder (plan.json, bev.png)")
      ->required();
  app.add_option("--candidates", a->candidates,
                 "Candidate files (.jsonl waypoints or trajectory files)");
  app.add_option("--sample", a->sample,
                 "Also sample up to N lattice candidates from the logged "
                 "start speed")
      ->check(CLI::Range(0, 100000));
  app.add_option("--shifts", a->shifts,
                 "Also score the logged trajectory shifted by +/- each "
                 "distance (m), e.g. 1 2 3");
  app.add_flag("--no-logged", a->no_logged,
               "Do not score the logged trajectory itself");
  app.add_option("--ego-length", a->score.ego_length, "Ego box length (m)")
      ->capture_default_str();
  app.add_option("--ego-width", a->score.ego_width, "Ego box width (m)")
      ->capture_default_str();
  app.add_option("--min-drivable", a->score.min_drivable_fraction,
                 "Reject below this drivable fraction")
      ->capture_default_str();
  return [a] { return Run(*a); };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(plan,
                          "plan",
                          "Score candidate ego trajectories against a clip's "
                          "geometry",
                          SetupPlan);

}  // namespace geodrive

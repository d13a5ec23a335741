// `geodrive plan`: scores candidate ego trajectories of a clip against its
// geometry (boxes over time, static LiDAR cloud, logged trajectory) and
// writes plan.json and a bird's-eye view.

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
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
#include "planning/visibility.h"
#include "render/video/video.h"

namespace geodrive {
namespace {

struct PlanArgs {
  std::string dataroot, version = "v1.0-mini", clip, out;
  std::string frames = "all";
  std::vector<std::string> candidates;
  int sample = 0;
  std::vector<double> shifts;
  bool no_logged = false;
  bool visibility = false;
  int videos = 0;
  std::vector<std::string> weights;
  VisibilityOptions visibility_options;
  PlanScoreOptions score;
};

// --weight NAME=VALUE: the cost weights of PlanScoreOptions by the names
// plan.json writes them under "weights".
void ApplyWeights(const std::vector<std::string>& items, PlanScoreOptions* o) {
  const std::pair<const char*, double*> fields[] = {
      {"collision", &o->weight_collision},
      {"clearance_per_m", &o->weight_clearance},
      {"clearance_target_m", &o->clearance_target},
      {"offroad", &o->weight_offroad},
      {"static_clearance_per_m", &o->weight_static_clearance},
      {"ade_per_m", &o->weight_ade},
      {"accel_per_mps2", &o->weight_accel},
      {"jerk_per_mps3", &o->weight_jerk},
      {"progress_per_m", &o->weight_progress}};
  for (const std::string& item : items) {
    const size_t eq = item.find('=');
    double* field = nullptr;
    for (const auto& [name, ptr] : fields)
      if (eq != std::string::npos && item.compare(0, eq, name) == 0 &&
          std::strlen(name) == eq)
        field = ptr;
    if (field == nullptr)
      ThrowInputError("--weight", "'", item,
                      "' is not NAME=VALUE with NAME one of collision, "
                      "clearance_per_m, clearance_target_m, offroad, "
                      "static_clearance_per_m, ade_per_m, accel_per_mps2, "
                      "jerk_per_mps3, progress_per_m");
    const std::string value = item.substr(eq + 1);
    char* end = nullptr;
    const double v = std::strtod(value.c_str(), &end);
    if (value.empty() || *end != '\0' || !std::isfinite(v))
      ThrowInputError("--weight", "'", item, "': the value is not a number");
    *field = v;
  }
}

// A candidate name as a file name: letters, digits and "+-._" kept, any
// other byte '_'.
std::string FileSafe(const std::string& name) {
  std::string out;
  for (char c : name) {
    const bool ok = std::isalnum(static_cast<unsigned char>(c)) || c == '+' ||
                    c == '-' || c == '.' || c == '_';
    out += ok ? c : '_';
  }
  return out.empty() || out[0] == '.' ? "_" + out : out;
}

// The condition videos of the `videos` best-ranked candidates:
// OUT/videos/<rank>_<name>.mp4 (paper preset, the clip's frame rate), and
// the clip's frame 0 as OUT/videos/first_frame.png: with a video, the
// inputs of `geodrive-diffusion generate --image ... --condition ...`.
void WriteConditionVideos(const PlanArgs& a,
                          const DriveClip& clip,
                          const ConditionScene& condition,
                          const std::vector<Candidate>& candidates,
                          const PlanResult& result) {
  if (a.videos <= 0) return;
  CreateOutputDirectory(a.out + "/videos");
  const cv::Mat first = !condition.frame0_rgb.empty()
                            ? condition.frame0_rgb
                            : ReadImageRgb(clip.frames.front().image_path);
  WriteImageRgb(a.out + "/videos/first_frame.png", first);
  VideoWriteOptions video;
  const double dt = clip.FrameIntervalSeconds();
  video.fps = dt > 0 ? std::max(1.0, std::round(1.0 / dt)) : 10.0;
  const size_t n = std::min<size_t>(a.videos, result.ranking.size());
  for (size_t r = 0; r < n; ++r) {
    const int i = result.ranking[r];
    char prefix[32];
    std::snprintf(prefix, sizeof prefix, "%03zu_", r + 1);
    WriteVideo(a.out + "/videos/" + prefix +
                   FileSafe(result.candidates[i].name) + ".mp4",
               CandidateConditionFrames(condition, clip, candidates[i]), video);
  }
}

int Run(PlanArgs a) {
  ApplyWeights(a.weights, &a.score);
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
  std::vector<Candidate> files;
  for (const std::string& path : a.candidates) {
    for (Candidate& c : ReadCandidates(path, clip.frames.front().ego_from_cam))
      files.push_back(std::move(c));
  }
  const std::vector<Candidate> candidates =
      GatherCandidates(scene, !a.no_logged, a.shifts, std::move(files),
                       a.sample, a.score.envelope);
  PlanResult result = ScoreCandidates(scene, candidates, a.score);
  if (a.visibility || a.videos > 0) {
    const ConditionScene condition =
        VisibilityScene(clip, a.visibility_options);
    if (a.visibility)
      ScoreVisibility(condition, clip, candidates, a.visibility_options,
                      &result);
    WriteConditionVideos(a, clip, condition, candidates, result);
  }
  WriteFileAtomic(a.out + "/plan.json",
                  PlanResultToJson(clip.id, candidates, result, a.score));
  WriteImageRgb(a.out + "/bev.png",
                DrawPlanBev(scene, candidates, result, a.score));
  std::printf("plan %s: %s\n", clip.id.c_str(), result.BriefReport().c_str());
  std::printf("%-4s %-28s %10s %9s %9s %9s %8s %8s  %s\n", "rank", "candidate",
              "cost", "min_d_m", "drivable", "clear_m@s", "ade_m", "coverage",
              "rejected");
  for (int i : result.ranking) {
    const CandidateScores& s = result.candidates[i];
    std::printf("%-4d %-28s %10.3f %9.3f %9.3f %5.2f@%-4.1f %8.3f %8.3f  %s\n",
                s.rank, s.name.c_str(), s.cost, s.min_box_distance,
                s.drivable_fraction, s.static_clearance,
                s.static_clearance_time, s.ade, s.mean_coverage,
                s.reject_detail.c_str());
  }
  std::printf("wrote %s/{plan.json, bev.png%s}\n", a.out.c_str(),
              a.videos > 0 ? ", videos/" : "");
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
  app.add_flag("--visibility", a->visibility,
               "Also render each candidate's front-camera condition coverage "
               "(mean, min)");
  app.add_option("--videos", a->videos,
                 "Write the condition videos of the N best-ranked candidates "
                 "(videos/<rank>_<name>.mp4, paper preset)")
      ->check(CLI::Range(0, 100000));
  app.add_option(
         "--visibility-source", a->visibility_options.source,
         "Scene source of the condition cloud for --visibility and --videos")
      ->check(CLI::IsMember({"lidar", "lidar-dense"}))
      ->capture_default_str();
  app.add_option("--weight", a->weights,
                 "A cost weight NAME=VALUE, as plan.json names them "
                 "(docs/PLANNING.md), e.g. ade_per_m=2; repeatable");
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

#include "planning/visibility.h"

#include <algorithm>
#include <cmath>

#include "geometry/util/status.h"
#include "render/renderer.h"

namespace geodrive {

bool VisibilityOptions::Check() const {
  return !source.empty() && width >= 8 && width <= 4096 && height >= 8 &&
         height <= 4096 && std::isfinite(radius_px) && radius_px >= 0 &&
         radius_px <= 16;
}

ConditionScene VisibilityScene(const DriveClip& clip,
                               const VisibilityOptions& options) {
  GEODRIVE_CHECK_INPUT(options.Check(),
                       "visibility options: a source, a size in [8, 4096] "
                       "and radius_px in [0, 16]");
  SceneInputs inputs;
  inputs.clip = &clip;
  return BuildConditionScene(options.source, inputs, SceneSourceOptions());
}

void ScoreVisibility(const ConditionScene& scene,
                     const DriveClip& clip,
                     const std::vector<Candidate>& candidates,
                     const VisibilityOptions& options,
                     PlanResult* result) {
  GEODRIVE_CHECK_INPUT(options.Check(),
                       "visibility options: a source, a size in [8, 4096] "
                       "and radius_px in [0, 16]");
  GEODRIVE_CHECK_INPUT(!clip.frames.empty(), "clip ", clip.id, ": no frames");
  GEODRIVE_CHECK_INPUT(result->candidates.size() == candidates.size(),
                       "visibility: ", candidates.size(), " candidates for ",
                       result->candidates.size(), " scores");
  GEODRIVE_CHECK_INPUT(scene.has_camera && !scene.cloud.positions.empty(),
                       "visibility: the condition scene (", scene.description,
                       ") has no camera or no points");
  const PinholeCamera camera =
      scene.CameraAt(options.width, options.height, ResizeMode::kResize);
  RenderOptions render;
  render.width = options.width;
  render.height = options.height;
  render.radius_px = options.radius_px;
  render.num_threads = 1;
  RenderResult frames;
  for (size_t i = 0; i < candidates.size(); ++i) {
    RenderFramesInto(scene.cloud, {camera},
                     CandidateCameraPoses(scene, clip, candidates[i]), render,
                     &frames);
    CandidateScores& s = result->candidates[i];
    s.mean_coverage = frames.summary.mean_coverage;
    s.min_coverage = frames.summary.min_coverage;
  }
}

std::vector<Rigid3d> CandidateCameraPoses(const ConditionScene& scene,
                                          const DriveClip& clip,
                                          const Candidate& candidate) {
  GEODRIVE_CHECK_INPUT(!clip.frames.empty(), "clip ", clip.id, ": no frames");
  const Rigid3d& ego_from_cam = clip.frames.front().ego_from_cam;
  const Rigid3d scene_from_ego0 =
      scene.scene_from_cam0 * ego_from_cam.Inverse();
  std::vector<Rigid3d> cam_from_scene;
  for (const Rigid3d& pose : candidate.ego0_from_ego.world_from_cam)
    cam_from_scene.push_back((scene_from_ego0 * pose * ego_from_cam).Inverse());
  return cam_from_scene;
}

std::vector<cv::Mat> CandidateConditionFrames(const ConditionScene& scene,
                                              const DriveClip& clip,
                                              const Candidate& candidate,
                                              RenderPreset preset) {
  GEODRIVE_CHECK_INPUT(scene.has_camera && !scene.cloud.positions.empty(),
                       "condition frames: the scene (", scene.description,
                       ") has no camera or no points");
  const RenderOptions render = PresetRenderOptions(preset);
  const PinholeCamera camera =
      scene.CameraAt(render.width, render.height, ResizeMode::kResize);
  const RenderResult result =
      RenderFrames(scene.cloud, {camera},
                   CandidateCameraPoses(scene, clip, candidate), render);
  return FinalFrames(result, preset);
}

}  // namespace geodrive

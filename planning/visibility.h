#pragma once
// Visibility along a candidate: how much of what the front camera would see
// from each waypoint is known geometry (the condition cloud's coverage of
// the render), the world model's reliability proxy.

#include <string>
#include <vector>

#include "dataset/drive_clip.h"
#include "dataset/scene_source.h"
#include "planning/candidates.h"
#include "planning/scores.h"
#include "render/presets.h"

namespace geodrive {

struct VisibilityOptions {
  // The scene source of the condition cloud (dataset/scene/registry.inc):
  // "lidar" (the sweeps around frame 0, coloured by the images) or
  // "lidar-dense".
  std::string source = "lidar";
  // Render size (pixels): coverage is a fraction, a small render suffices.
  int width = 160;
  int height = 90;
  // z-buffer splat radius at that size (pixels).
  double radius_px = 1.0;

  bool Check() const;
};

// The condition scene of a clip (camera 0's frame), as build-dataset makes
// it with `options.source`.
ConditionScene VisibilityScene(const DriveClip& clip,
                               const VisibilityOptions& options = {});

// Fills each candidate's visibility scores in `result` (same order as
// `candidates`): the front camera (the clip's frame-0 mounting) at each
// waypoint, scene_from_cam = scene_from_cam0 * cam_from_ego * ego0_from_ego
// * ego_from_cam, rendered with the z-buffer; coverage = valid pixels / all
// pixels (sky never counts). Throws InputError on bad options.
void ScoreVisibility(const ConditionScene& scene,
                     const DriveClip& clip,
                     const std::vector<Candidate>& candidates,
                     const VisibilityOptions& options,
                     PlanResult* result);

// The front camera's cam_from_scene at each waypoint of `candidate` (the
// poses ScoreVisibility renders).
std::vector<Rigid3d> CandidateCameraPoses(const ConditionScene& scene,
                                          const DriveClip& clip,
                                          const Candidate& candidate);

// The candidate's condition frames: the front camera along its waypoints
// rendered from the condition scene with `preset` (paper: 720 x 480,
// z-buffer, one pixel per point), RGB CV_8UC3, one per waypoint.
std::vector<cv::Mat> CandidateConditionFrames(
    const ConditionScene& scene,
    const DriveClip& clip,
    const Candidate& candidate,
    RenderPreset preset = RenderPreset::kPaper);

}  // namespace geodrive

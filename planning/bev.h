#pragma once
// A bird's-eye view of a plan: the static cloud, every obstacle box over
// time, the logged trajectory and the candidates coloured by cost.

#include <opencv2/core.hpp>
#include <vector>

#include "planning/candidates.h"
#include "planning/scores.h"

namespace geodrive {

struct PlanBevOptions {
  // Image scale (m per pixel) and the margin around the candidates (m).
  double metres_per_pixel = 0.1;
  double margin = 10.0;
  // The longer image side is capped (the scale grows to fit).
  int max_side = 2000;

  bool Check() const;
};

// RGB CV_8UC3 image, ego0's x axis (forward) up, y (left) to the left.
// Static points: ground grey, obstacles (ClassifyStaticPoints) orange, the
// rest dark grey; obstacle boxes as outlines at their
// annotation times, from dark blue (first) to cyan (last); the logged
// trajectory white; each accepted candidate from green (rank 1) to yellow
// (last accepted), rejected candidates red; the ego box at frame 0 white.
cv::Mat DrawPlanBev(const PlanningScene& scene,
                    const std::vector<Candidate>& candidates,
                    const PlanResult& result,
                    const PlanScoreOptions& score_options,
                    const PlanBevOptions& options = {});

}  // namespace geodrive

#include "planning/bev.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "geometry/util/status.h"

namespace geodrive {
namespace {

struct View {
  double x_max = 0, y_max = 0, res = 0.1;
  cv::Point Pixel(double x, double y) const {
    return cv::Point(static_cast<int>(std::lround((y_max - y) / res)),
                     static_cast<int>(std::lround((x_max - x) / res)));
  }
};

void DrawBox(cv::Mat* image,
             const View& v,
             const Box3d& box,
             const cv::Scalar& colour,
             int thickness) {
  // The footprint's four corners in order, from the box axes.
  const Eigen::Vector3d u = box.rotation * Eigen::Vector3d::UnitX();
  const Eigen::Vector3d n = box.rotation * Eigen::Vector3d::UnitY();
  const double hl = 0.5 * box.size.y(), hw = 0.5 * box.size.x();
  std::vector<cv::Point> poly;
  for (const auto& [a, b] : {std::pair{1, 1}, {-1, 1}, {-1, -1}, {1, -1}}) {
    const Eigen::Vector3d p = box.center + a * hl * u + b * hw * n;
    poly.push_back(v.Pixel(p.x(), p.y()));
  }
  cv::polylines(*image, poly, true, colour, thickness, cv::LINE_AA);
}

void DrawPath(cv::Mat* image,
              const View& v,
              const Trajectory& tr,
              const cv::Scalar& colour,
              int thickness) {
  std::vector<cv::Point> line;
  for (const Rigid3d& p : tr.world_from_cam)
    line.push_back(v.Pixel(p.translation.x(), p.translation.y()));
  cv::polylines(*image, line, false, colour, thickness, cv::LINE_AA);
}

}  // namespace

bool PlanBevOptions::Check() const {
  return std::isfinite(metres_per_pixel) && metres_per_pixel > 0 &&
         std::isfinite(margin) && margin >= 0 && max_side >= 16 &&
         max_side <= 16384;
}

cv::Mat DrawPlanBev(const PlanningScene& scene,
                    const std::vector<Candidate>& candidates,
                    const PlanResult& result,
                    const PlanScoreOptions& score_options,
                    const PlanBevOptions& options) {
  GEODRIVE_CHECK_INPUT(options.Check(),
                       "plan BEV options: metres_per_pixel > 0, margin >= 0, "
                       "max_side in [16, 16384]");
  // Extent: the candidates, the logged path and the ego, plus the margin.
  double x0 = -5, x1 = 5, y0 = -5, y1 = 5;
  auto grow = [&](const Trajectory& tr) {
    for (const Rigid3d& p : tr.world_from_cam) {
      x0 = std::min(x0, p.translation.x()),
      x1 = std::max(x1, p.translation.x());
      y0 = std::min(y0, p.translation.y()),
      y1 = std::max(y1, p.translation.y());
    }
  };
  for (const Candidate& c : candidates) grow(c.ego0_from_ego);
  grow(scene.logged);
  x0 -= options.margin, x1 += options.margin;
  y0 -= options.margin, y1 += options.margin;
  View v;
  v.x_max = x1, v.y_max = y1;
  v.res = std::max(options.metres_per_pixel,
                   std::max(x1 - x0, y1 - y0) / options.max_side);
  const int rows = static_cast<int>(std::ceil((x1 - x0) / v.res)) + 1;
  const int cols = static_cast<int>(std::ceil((y1 - y0) / v.res)) + 1;
  cv::Mat image(rows, cols, CV_8UC3, cv::Scalar(20, 20, 24));
  // Static points: ground grey, obstacles orange, the rest dark grey.
  const std::vector<PointClass> labels =
      ClassifyStaticPoints(scene, score_options);
  for (size_t n = 0; n < labels.size(); ++n) {
    const Eigen::Vector3f& p = scene.static_cloud.positions[n];
    const cv::Point px = v.Pixel(p.x(), p.y());
    if (px.x < 0 || px.y < 0 || px.x >= cols || px.y >= rows) continue;
    cv::Vec3b& out = image.at<cv::Vec3b>(px);
    if (labels[n] == PointClass::kObstacle) {
      out = cv::Vec3b(255, 140, 0);
    } else if (out[0] != 255) {
      out = labels[n] == PointClass::kGround ? cv::Vec3b(150, 150, 150)
                                             : cv::Vec3b(80, 80, 80);
    }
  }
  for (const ObstacleTrack& track : scene.obstacles) {
    for (size_t i = 0; i < track.boxes.size(); ++i) {
      const double f =
          track.boxes.size() > 1 ? double(i) / (track.boxes.size() - 1) : 1.0;
      DrawBox(&image, v, track.boxes[i],
              cv::Scalar(30, 60 + 160 * f, 140 + 100 * f), 1);
    }
  }
  DrawPath(&image, v, scene.logged, cv::Scalar(255, 255, 255), 2);
  // Worst first, so that the best is drawn on top.
  int accepted = 0;
  for (const CandidateScores& s : result.candidates)
    accepted += s.reject == RejectReason::kNone ? 1 : 0;
  for (auto it = result.ranking.rbegin(); it != result.ranking.rend(); ++it) {
    const CandidateScores& s = result.candidates[*it];
    cv::Scalar colour(230, 40, 40);
    if (s.reject == RejectReason::kNone) {
      const double f = accepted > 1 ? double(s.rank - 1) / (accepted - 1) : 0.0;
      colour = cv::Scalar(40 + 200 * f, 220, 40);
    }
    DrawPath(&image, v, candidates[*it].ego0_from_ego, colour,
             s.rank == 1 ? 3 : 1);
  }
  DrawBox(&image, v, EgoBox(Rigid3d(), score_options),
          cv::Scalar(255, 255, 255), 2);
  return image;
}

}  // namespace geodrive

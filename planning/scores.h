#pragma once
// Scores of candidate ego trajectories against a scene's geometry: collision
// with the boxes over time, drivable ground and clearance to static
// obstacles, kinematics, agreement with the logged trajectory, and a weighted
// cost with a rejection reason. Formulas and units: docs/PLANNING.md.
//
// Everything is in the ego frame of frame 0 ("ego0": x forward, y left, z
// up, metres) and in seconds since frame 0, as planning/candidates.h says.
// Collision and clearance are measured in the ground plane (bird's-eye view,
// BEV): nuScenes ego poses have z = 0 while box bottoms vary by metres, so
// heights are not compared.

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "geometry/box3d.h"
#include "geometry/point_cloud.h"
#include "geometry/trajectory.h"
#include "planning/candidates.h"

namespace geodrive {

// One object to avoid: its box at each annotation time (ego0), interpolated
// between annotations (lerp of centre and size, slerp of rotation) and held
// before the first and after the last (a parked car is one box).
struct ObstacleTrack {
  std::string id;
  // e.g. "vehicle.car"; empty when unknown.
  std::string category;
  // Seconds since frame 0, strictly increasing; one per box.
  std::vector<double> times;
  std::vector<Box3d> boxes;

  Box3d At(double t) const;
};

// What candidates are scored against.
struct PlanningScene {
  std::vector<ObstacleTrack> obstacles;
  // Static scene points in ego0 (metres), moving objects removed; empty: no
  // drivable or clearance scores.
  PointCloud static_cloud;
  // The sweep (0..255) of each static point, or empty (one cloud). Ground is
  // segmented per sweep: sweeps placed by ego poses with z = 0 (nuScenes)
  // disagree in height on a slope by more than the ground margin.
  std::vector<int32_t> static_cloud_sweep;
  // The LiDAR position (ego0) of each sweep id, or empty. With it, points
  // farther than PlanScoreOptions::max_point_range from their sweep's
  // sensor are not classified (far rings are too sparse to find the ground).
  std::vector<Eigen::Vector3d> sweep_origins;
  // The logged ego trajectory (ego0_from_ego, seconds since frame 0); empty:
  // no ADE/FDE.
  Trajectory logged;
};

// Kind of rejection, in the order they are tested.
enum class RejectReason {
  kNone,
  kCollision,    // the ego box meets an obstacle box
  kOffDrivable,  // too little of the footprint path is over ground, or the
                 // footprint covers an obstacle point
  kKinematics,   // outside the kinematic envelope
};
// "none", "collision", "off-drivable", "kinematics".
std::string ToString(RejectReason reason);

struct PlanScoreOptions {
  // Ego box (m). Default: the mean nuScenes "vehicle.car" box, rounded.
  double ego_length = 4.6;
  double ego_width = 1.95;
  double ego_height = 1.75;
  // How far ahead of the ego origin (nuScenes: the rear axle) the box centre
  // lies (m).
  double ego_center_ahead = 1.3;
  // Boxes are tested at each waypoint and at this many evenly spaced times
  // in between (poses and boxes interpolated); the first contact time is
  // then refined by bisection to collision_time_tolerance_s.
  int collision_substeps = 4;
  double collision_time_tolerance_s = 1e-3;

  // ---- Ground segmentation of the static cloud (BEV grid).
  // Grid cell (m).
  double ground_cell = 0.5;
  // A cell's ground is its third-lowest point (or the highest of fewer);
  // the local ground of a point is the median of the cell grounds within
  // this radius (m) of its cell, in cells rounded up.
  double ground_window = 1.0;
  // Points farther than this (BEV, m) from their sweep's sensor are left
  // unclassified (when the scene gives sweep_origins).
  double max_point_range = 20.0;
  // Points at most this high above the local ground are ground (m).
  double ground_margin = 0.12;
  // Points higher than ground_margin and at most this high above the local
  // ground are obstacles (kerbs, poles, walls); higher ones (trees, bridges)
  // are neither (m).
  double obstacle_max_height = 3.0;
  // A footprint sample is over ground when a ground point lies within this
  // BEV distance (m): LiDAR rings leave gaps on the road.
  double ground_support_radius = 1.0;
  // Footprint samples are spaced at most this far apart (m).
  double footprint_spacing = 0.5;
  // Obstacle points farther than this from the ego box are not searched;
  // the clearance is then reported as this value (m).
  double clearance_search_radius = 10.0;

  // ---- Rejection.
  // Rejected as off-drivable below this drivable fraction.
  double min_drivable_fraction = 0.9;
  KinematicEnvelope envelope;

  // ---- Cost = sum of the weighted terms (docs/PLANNING.md); lower is
  // better.
  // Per collision (a rejected candidate also gets its reason).
  double weight_collision = 1000.0;
  // Per metre that the minimum box distance falls short of clearance_target.
  double weight_clearance = 10.0;
  double clearance_target = 1.0;
  // Per unit of (1 - drivable fraction).
  double weight_offroad = 100.0;
  // Per metre of clearance to static obstacles short of clearance_target.
  double weight_static_clearance = 5.0;
  // Per metre of ADE to the logged trajectory.
  double weight_ade = 1.0;
  // Per m/s^2 of peak lateral and longitudinal acceleration.
  double weight_accel = 0.5;
  // Per m/s^3 of peak jerk (the larger of lateral and longitudinal).
  double weight_jerk = 0.1;
  // Per metre of progress (subtracted: progress is good).
  double weight_progress = 0.1;

  bool Check() const;
};

struct CandidateScores {
  std::string name;
  // ---- Collision (BEV).
  bool collides = false;
  // Time of the first contact (s), NaN when none.
  double first_collision_time = std::numeric_limits<double>::quiet_NaN();
  std::string first_collision_with;
  // Its category (ObstacleTrack::category; may be empty).
  std::string first_collision_category;
  // Minimum BEV distance between the ego box and any obstacle box over the
  // candidate's time (m; 0 when they meet), when it happens (s) and with
  // what; +inf with no obstacles.
  double min_box_distance = std::numeric_limits<double>::infinity();
  double min_box_distance_time = std::numeric_limits<double>::quiet_NaN();
  std::string closest_obstacle;
  // ---- Drivable (NaN without a static cloud).
  // Fraction of footprint samples over ground, in [0, 1].
  double drivable_fraction = std::numeric_limits<double>::quiet_NaN();
  // Minimum BEV distance from the ego box to an obstacle point (m), at most
  // clearance_search_radius.
  double static_clearance = std::numeric_limits<double>::quiet_NaN();
  // The waypoint time of that minimum (s).
  double static_clearance_time = std::numeric_limits<double>::quiet_NaN();
  // ---- Kinematics.
  CandidateKinematics kinematics;
  // Empty when inside the envelope.
  std::string envelope_violation;
  // ---- Against the logged trajectory (NaN without one): mean and final
  // BEV distance at the candidate's times inside the logged time span (m).
  double ade = std::numeric_limits<double>::quiet_NaN();
  double fde = std::numeric_limits<double>::quiet_NaN();
  // Distance travelled along the candidate's path (m).
  double progress = 0;
  // ---- Visibility (planning/visibility.h; NaN unless computed): mean and
  // minimum over the waypoints of the front camera's condition coverage,
  // in [0, 1]. Not part of the cost.
  double mean_coverage = std::numeric_limits<double>::quiet_NaN();
  double min_coverage = std::numeric_limits<double>::quiet_NaN();
  // ---- Decision.
  double cost = 0;
  RejectReason reject = RejectReason::kNone;
  // One line: why (e.g. "collision with car-3 at 4.25 s").
  std::string reject_detail;
  // 1 = best; rejected candidates rank after every accepted one.
  int rank = 0;
};

struct PlanResult {
  // In the order of the input candidates.
  std::vector<CandidateScores> candidates;
  // Indices into `candidates`, best first.
  std::vector<int> ranking;
  // Static cloud points classified as ground and as obstacles.
  int64_t ground_points = 0, obstacle_points = 0;
  double seconds = 0;

  // One line: candidates, accepted, rejected by reason, best, time.
  std::string BriefReport() const;
};

// Scores every candidate (each checked with ValidateCandidate first). Throws
// InputError when the options fail Check() or a candidate is invalid.
PlanResult ScoreCandidates(const PlanningScene& scene,
                           const std::vector<Candidate>& candidates,
                           const PlanScoreOptions& options = {});

// Ground segmentation of the static cloud (docs/PLANNING.md), per point.
enum class PointClass : uint8_t {
  kOther,     // too high (trees, bridges) or not finite
  kGround,    // at most ground_margin above the local ground
  kObstacle,  // above ground_margin, at most obstacle_max_height
};
std::vector<PointClass> ClassifyStaticPoints(const PlanningScene& scene,
                                             const PlanScoreOptions& options);

// The ego box at an ego pose (ego0; z from the pose, bottom on it).
Box3d EgoBox(const Rigid3d& ego0_from_ego, const PlanScoreOptions& options);
// Euclidean distance between the BEV rectangles of two boxes (their
// footprints projected on z = 0, yaw about z only), 0 when they overlap
// (separating-axis test, then the closest vertex-edge pair).
double BevBoxDistance(const Box3d& a, const Box3d& b);

}  // namespace geodrive

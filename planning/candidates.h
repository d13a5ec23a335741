#pragma once
// Candidate ego trajectories for planning assistance: reading them (any
// trajectory file the toolkit reads, or a JSON-lines file of ego waypoints),
// checking them, and sampling a lattice within a kinematic envelope.
//
// Frame: every candidate is expressed in the ego frame of frame 0 ("ego0":
// x forward, y left, z up, metres, origin at the ego pose of the clip's first
// frame), and its times are seconds since frame 0. The poses are
// ego0_from_ego, kept in a Trajectory whose "world" is ego0 and whose "cam" is
// the ego (ego axes, not camera axes).

#include <string>
#include <vector>

#include "geometry/rigid3.h"
#include "geometry/trajectory.h"

namespace geodrive {

struct Candidate {
  // Short name for tables and plots (file stem, JSONL "candidate" field, or
  // the lattice cell, e.g. "lat+1.75_acc-1.0_yaw+0.00").
  std::string name;
  // Where it came from, as errors name it (a path, "path:line", "lattice").
  std::string source;
  // ego0_from_ego per waypoint; timestamps in seconds since frame 0.
  Trajectory ego0_from_ego;

  size_t size() const { return ego0_from_ego.size(); }
};

// What a readable candidate must satisfy.
struct CandidateLimits {
  // A step between consecutive waypoints faster than this is a jump, not a
  // motion (m/s; 100 m/s = 360 km/h: 100 m in 0.1 s is 1000 m/s).
  double max_speed_mps = 100.0;
  // At least this many waypoints.
  int min_waypoints = 2;

  bool Check() const;
};

// Throws one InputError "<source>: waypoint <k>: <problem>" (or
// "<source>: no waypoints") for: fewer than min_waypoints waypoints, a
// non-finite time or pose, a non-unit quaternion, a time not after the
// previous one, or a step faster than max_speed_mps.
void ValidateCandidate(const Candidate& candidate,
                       const CandidateLimits& limits = {});

// The ego's camera mounting of the trajectory files (ego_from_cam: OpenCV
// camera axes in the ego frame). Default: a camera at the ego origin looking
// forward (camera z = ego x, camera x = ego -y, camera y = ego -z).
Rigid3d ForwardCameraMounting();

// Reads one candidate from `path`:
//  - *.jsonl: one waypoint per line, {"t": s, "x": m, "y": m} with optional
//    "z" (m, default 0) and "yaw" (rad, counter-clockwise from ego0's x axis;
//    default: the direction of motion), in ego0; blank lines and lines
//    starting with '#' are skipped. A "candidate" field on the lines splits
//    the file into several candidates (ReadCandidatesJsonl).
//  - any other file: a camera trajectory (geometry/trajectory_json.h's
//    ReadTrajectoryAny: JSON, TUM, MonST3R, KITTI, COLMAP, a reconstruction),
//    re-expressed relative to its first pose, put on the ego through
//    `ego_from_cam` (ego0_from_ego = ego_from_cam * cam0_from_cam *
//    cam_from_ego: the first pose is the ego at frame 0) and timed from its
//    first timestamp.
// Throws InputError naming the file (and line) and the problem; the result
// passes ValidateCandidate.
std::vector<Candidate> ReadCandidates(
    const std::string& path,
    const Rigid3d& ego_from_cam = ForwardCameraMounting(),
    const CandidateLimits& limits = {});
// The JSON-lines form only (one candidate per distinct "candidate" value, in
// order of first appearance; one candidate named after the file without it).
std::vector<Candidate> ReadCandidatesJsonl(const std::string& path,
                                           const CandidateLimits& limits = {});
// Writes a candidate as JSON lines (t, x, y, z, yaw per waypoint; %.9g).
void WriteCandidateJsonl(const std::string& path, const Candidate& candidate);

// The candidate moved sideways by `offset` metres (+ to the left) at every
// waypoint, along each pose's own left axis (y), named "<name>" + suffix.
Candidate ShiftLaterally(const Candidate& candidate,
                         double offset,
                         const std::string& suffix);

// Ego pose in ego0 from a planar waypoint (x, y, z in metres, yaw in radians
// about z).
Rigid3d EgoPose(double x, double y, double z, double yaw);
// Yaw (rad, about z) of an ego pose.
double EgoYaw(const Rigid3d& ego0_from_ego);

// Peak kinematic quantities of a candidate, by finite differences over its
// waypoints (planning/PLANNING.md in docs gives the formulas).
struct CandidateKinematics {
  // Peak |longitudinal| and |lateral| acceleration (m/s^2).
  double max_lon_accel = 0, max_lat_accel = 0;
  // Peak |longitudinal| and |lateral| jerk (m/s^3).
  double max_lon_jerk = 0, max_lat_jerk = 0;
  // Peak |curvature| of the path (1/m), where the speed is at least
  // min_speed_for_curvature.
  double max_curvature = 0;
  // Peak speed (m/s) and path length (m).
  double max_speed = 0, path_length = 0;
};
// Speeds below this (m/s) give no curvature sample (the heading of a
// standing vehicle is not a path).
constexpr double kMinSpeedForCurvature = 0.5;
CandidateKinematics ComputeKinematics(const Candidate& candidate);

// The kinematic envelope a lattice stays in and a candidate is judged by.
struct KinematicEnvelope {
  // |curvature| (1/m): 0.2 is a 5 m turning radius, about a passenger car's
  // minimum.
  double max_curvature = 0.2;
  // |longitudinal acceleration| (m/s^2): 4 covers firm braking and brisk
  // acceleration without an emergency stop.
  double max_lon_accel = 4.0;
  // |lateral acceleration| (m/s^2): 4 is the edge of comfortable cornering.
  double max_lat_accel = 4.0;
  // |jerk| (m/s^3), longitudinal and lateral: 10 is well above comfort (~2)
  // and below an abrupt manoeuvre.
  double max_jerk = 10.0;

  bool Check() const;
  // Empty if `k` is inside the envelope, else which bound it exceeds, with
  // the value and the bound (e.g. "lateral acceleration 5.2 m/s^2 > 4").
  std::string Violation(const CandidateKinematics& k) const;
};

// A lattice of candidates from the ego at frame 0: lateral offsets (reached
// by a quintic lane change), constant accelerations from the initial speed,
// constant yaw rates, every combination inside the envelope.
struct LatticeOptions {
  // Initial speed along ego0's x axis (m/s); typically the logged speed.
  double initial_speed = 5.0;
  // Waypoint times: 0, dt, ..., horizon (s). 12 s at 0.5 s is a 25-keyframe
  // nuScenes clip.
  double horizon_s = 12.0;
  double dt_s = 0.5;
  // Lateral offsets (m, + to the left) reached at lane_change_s.
  std::vector<double> lateral_offsets = {-3.5, -1.75, 0.0, 1.75, 3.5};
  double lane_change_s = 4.0;
  // Constant longitudinal accelerations (m/s^2); the speed stops at 0 and
  // at max_speed.
  std::vector<double> accelerations = {-2.0, -1.0, 0.0, 1.0};
  double max_speed = 20.0;
  // Constant yaw rates of the base path (rad/s, + counter-clockwise).
  std::vector<double> yaw_rates = {-0.1, 0.0, 0.1};
  // Keep at most this many (0 = all): an evenly strided subset of the
  // feasible cells in lattice order, always with the straight keep-speed
  // cell when it is feasible. Deterministic (no randomness).
  int max_candidates = 0;
  KinematicEnvelope envelope;

  bool Check() const;
};

// The feasible lattice cells as candidates (source "lattice"). Throws
// InputError when the options fail Check().
std::vector<Candidate> SampleLattice(const LatticeOptions& options);

}  // namespace geodrive

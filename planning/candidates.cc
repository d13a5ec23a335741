#include "planning/candidates.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "geometry/trajectory_json.h"
#include "geometry/util/files.h"
#include "geometry/util/input_file.h"
#include "geometry/util/json_depth.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

// A JSON-lines candidate file larger than this is refused (1 GiB is millions
// of waypoints: not a plan).
constexpr uint64_t kMaxCandidateFileBytes = uint64_t{1} << 30;

// Checks waypoints; where[k] names waypoint k in errors ("path:3" or
// "name: waypoint 3").
void ValidateWaypoints(const Candidate& c,
                       const std::vector<std::string>& where,
                       const CandidateLimits& limits) {
  const Trajectory& tr = c.ego0_from_ego;
  GEODRIVE_CHECK_INPUT(tr.timestamps.size() == tr.world_from_cam.size(),
                       c.source, ": ", tr.timestamps.size(), " times but ",
                       tr.world_from_cam.size(), " poses");
  if (tr.empty()) ThrowInputError(c.source, "no waypoints");
  GEODRIVE_CHECK_INPUT(static_cast<int>(tr.size()) >= limits.min_waypoints,
                       c.source, ": ", tr.size(), " waypoint(s), at least ",
                       limits.min_waypoints, " needed");
  for (size_t k = 0; k < tr.size(); ++k) {
    const double t = tr.timestamps[k];
    const Rigid3d& pose = tr.world_from_cam[k];
    if (!std::isfinite(t)) ThrowInputError(where[k], "time is not finite");
    if (!pose.translation.allFinite() || !pose.rotation.coeffs().allFinite())
      ThrowInputError(where[k], "position or rotation is not finite");
    if (!pose.IsValid(1e-3))
      ThrowInputError(where[k], "rotation is not a unit quaternion");
    if (k == 0) continue;
    const double t0 = tr.timestamps[k - 1];
    if (!(t > t0))
      ThrowInputError(where[k], "time ", t,
                      " s is not after the previous waypoint's ", t0,
                      " s (times must increase strictly)");
    const double d =
        (pose.translation - tr.world_from_cam[k - 1].translation).norm();
    if (d / (t - t0) > limits.max_speed_mps)
      ThrowInputError(where[k], "jumps ", d, " m in ", t - t0, " s (",
                      d / (t - t0), " m/s > the limit ", limits.max_speed_mps,
                      " m/s)");
  }
}

std::string Stem(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
  const size_t dot = name.find_last_of('.');
  return dot == std::string::npos || dot == 0 ? name : name.substr(0, dot);
}

double FieldNumber(const nlohmann::json& j,
                   const char* key,
                   const std::string& where,
                   bool required,
                   double fallback) {
  const auto it = j.find(key);
  if (it == j.end()) {
    if (required) ThrowInputError(where, "missing \"", key, "\"");
    return fallback;
  }
  if (!it->is_number()) ThrowInputError(where, "\"", key, "\" is not a number");
  const double v = it->get<double>();
  if (!std::isfinite(v)) ThrowInputError(where, "\"", key, "\" is not finite");
  return v;
}

// Waypoints of one candidate while reading: positions, optional yaw.
struct Waypoints {
  std::string name;
  std::vector<double> t;
  std::vector<Eigen::Vector3d> p;
  std::vector<double> yaw;  // NaN = from the motion
  std::vector<std::string> where;
};

// Yaw from the direction of motion where none was given: towards the next
// waypoint that moved, else from the last one that did, else 0.
void FillMissingYaw(Waypoints* w) {
  const size_t n = w->p.size();
  std::vector<double> motion(n, std::nan(""));
  for (size_t k = 0; k + 1 < n; ++k) {
    const Eigen::Vector2d d = (w->p[k + 1] - w->p[k]).head<2>();
    if (d.norm() > 1e-6) motion[k] = std::atan2(d.y(), d.x());
  }
  double last = 0;
  for (size_t k = 0; k < n; ++k) {
    if (std::isnan(motion[k])) {
      motion[k] = k > 0 ? motion[k - 1] : std::nan("");
    }
  }
  // Leading stops take the first motion's direction.
  for (size_t k = n; k-- > 0;) {
    if (std::isnan(motion[k])) motion[k] = last;
    last = motion[k];
  }
  for (size_t k = 0; k < n; ++k)
    if (std::isnan(w->yaw[k])) w->yaw[k] = motion[k];
}

}  // namespace

bool CandidateLimits::Check() const {
  return std::isfinite(max_speed_mps) && max_speed_mps > 0 &&
         min_waypoints >= 1;
}

void ValidateCandidate(const Candidate& candidate,
                       const CandidateLimits& limits) {
  std::vector<std::string> where;
  for (size_t k = 0; k < candidate.ego0_from_ego.world_from_cam.size(); ++k)
    where.push_back(candidate.source + ": waypoint " + std::to_string(k));
  ValidateWaypoints(candidate, where, limits);
}

Rigid3d ForwardCameraMounting() {
  Eigen::Matrix3d r;
  // Columns: camera x, y, z in the ego frame.
  r << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  return Rigid3d(Eigen::Quaterniond(r), Eigen::Vector3d::Zero());
}

Rigid3d EgoPose(double x, double y, double z, double yaw) {
  return Rigid3d(
      Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ())),
      Eigen::Vector3d(x, y, z));
}

double EgoYaw(const Rigid3d& ego0_from_ego) {
  const Eigen::Vector3d x = ego0_from_ego.rotation * Eigen::Vector3d::UnitX();
  return std::atan2(x.y(), x.x());
}

std::vector<Candidate> ReadCandidatesJsonl(const std::string& path,
                                           const CandidateLimits& limits) {
  GEODRIVE_CHECK_INPUT(limits.Check(),
                       "candidate limits: max_speed_mps must "
                       "be > 0 and min_waypoints >= 1");
  const std::string text = ReadInputFileText(path, kMaxCandidateFileBytes);
  std::vector<Waypoints> groups;
  std::map<std::string, size_t> group_of;
  std::istringstream lines(text);
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::string where = path + ":" + std::to_string(number);
    nlohmann::json j;
    try {
      j = internal::ParseJson(line, where);
    } catch (const nlohmann::json::exception& e) {
      ThrowInputError(where, "malformed JSON (", e.what(), ")");
    }
    if (!j.is_object()) ThrowInputError(where, "a waypoint must be an object");
    std::string name = Stem(path);
    if (const auto it = j.find("candidate"); it != j.end()) {
      if (!it->is_string() || it->get<std::string>().empty())
        ThrowInputError(where, "\"candidate\" must be a non-empty string");
      name = it->get<std::string>();
    }
    auto [slot, added] = group_of.emplace(name, groups.size());
    if (added) groups.push_back(Waypoints{name, {}, {}, {}, {}});
    Waypoints& w = groups[slot->second];
    w.t.push_back(FieldNumber(j, "t", where, true, 0));
    w.p.emplace_back(FieldNumber(j, "x", where, true, 0),
                     FieldNumber(j, "y", where, true, 0),
                     FieldNumber(j, "z", where, false, 0));
    w.yaw.push_back(FieldNumber(j, "yaw", where, false, std::nan("")));
    w.where.push_back(where);
  }
  if (groups.empty()) ThrowInputError(path, "no waypoints");
  std::vector<Candidate> out;
  for (Waypoints& w : groups) {
    FillMissingYaw(&w);
    Candidate c;
    c.name = w.name;
    c.source = groups.size() == 1 ? path : path + " (candidate " + w.name + ")";
    for (size_t k = 0; k < w.t.size(); ++k)
      c.ego0_from_ego.Add(
          w.t[k], EgoPose(w.p[k].x(), w.p[k].y(), w.p[k].z(), w.yaw[k]));
    ValidateWaypoints(c, w.where, limits);
    out.push_back(std::move(c));
  }
  return out;
}

std::vector<Candidate> ReadCandidates(const std::string& path,
                                      const Rigid3d& ego_from_cam,
                                      const CandidateLimits& limits) {
  if (EndsWith(LowerFileName(path), ".jsonl"))
    return ReadCandidatesJsonl(path, limits);
  GEODRIVE_CHECK_INPUT(limits.Check(),
                       "candidate limits: max_speed_mps must "
                       "be > 0 and min_waypoints >= 1");
  const Trajectory tr = ReadTrajectoryAny(path);
  Candidate c;
  c.name = Stem(path);
  c.source = path;
  if (tr.empty()) ThrowInputError(path, "no waypoints");
  tr.Check(path);
  const Trajectory rel = tr.RelativeToFirst();
  const Rigid3d cam_from_ego = ego_from_cam.Inverse();
  for (size_t k = 0; k < rel.size(); ++k)
    c.ego0_from_ego.Add(rel.timestamps[k] - rel.timestamps[0],
                        ego_from_cam * rel.world_from_cam[k] * cam_from_ego);
  ValidateCandidate(c, limits);
  return {c};
}

Candidate ShiftLaterally(const Candidate& candidate,
                         double offset,
                         const std::string& suffix) {
  Candidate out = candidate;
  out.name += suffix;
  out.source += " shifted " + std::to_string(offset) + " m";
  for (Rigid3d& pose : out.ego0_from_ego.world_from_cam)
    pose.translation += pose.rotation * Eigen::Vector3d(0, offset, 0);
  return out;
}

void WriteCandidateJsonl(const std::string& path, const Candidate& candidate) {
  std::string out;
  char buf[256];
  for (size_t k = 0; k < candidate.size(); ++k) {
    const Rigid3d& p = candidate.ego0_from_ego.world_from_cam[k];
    std::snprintf(buf, sizeof buf,
                  "{\"t\": %.9g, \"x\": %.9g, \"y\": %.9g, \"z\": %.9g, "
                  "\"yaw\": %.9g}\n",
                  candidate.ego0_from_ego.timestamps[k], p.translation.x(),
                  p.translation.y(), p.translation.z(), EgoYaw(p));
    out += buf;
  }
  WriteFileAtomic(path, out);
}

CandidateKinematics ComputeKinematics(const Candidate& candidate) {
  CandidateKinematics k;
  const Trajectory& tr = candidate.ego0_from_ego;
  const size_t n = tr.size();
  if (n < 2) return k;
  const auto& t = tr.timestamps;
  auto pos = [&](size_t i) -> Eigen::Vector2d {
    return tr.world_from_cam[i].translation.head<2>();
  };
  // Segment velocities at the segment mid-times.
  std::vector<Eigen::Vector2d> vs(n - 1);
  for (size_t j = 0; j + 1 < n; ++j) {
    vs[j] = (pos(j + 1) - pos(j)) / (t[j + 1] - t[j]);
    k.max_speed = std::max(k.max_speed, vs[j].norm());
    k.path_length += (pos(j + 1) - pos(j)).norm();
  }
  // Interior samples: acceleration, its components, curvature.
  std::vector<double> lon, lat, at;
  for (size_t i = 1; i + 1 < n; ++i) {
    const double h0 = t[i] - t[i - 1], h1 = t[i + 1] - t[i];
    const Eigen::Vector2d a = (vs[i] - vs[i - 1]) / (0.5 * (h0 + h1));
    const Eigen::Vector2d v = (vs[i - 1] * h1 + vs[i] * h0) / (h0 + h1);
    Eigen::Vector2d u;
    if (v.norm() > 1e-3) {
      u = v.normalized();
    } else {
      const double yaw = EgoYaw(tr.world_from_cam[i]);
      u = Eigen::Vector2d(std::cos(yaw), std::sin(yaw));
    }
    const Eigen::Vector2d normal(-u.y(), u.x());
    lon.push_back(a.dot(u));
    lat.push_back(a.dot(normal));
    at.push_back(t[i]);
    k.max_lon_accel = std::max(k.max_lon_accel, std::abs(lon.back()));
    k.max_lat_accel = std::max(k.max_lat_accel, std::abs(lat.back()));
    const double speed = v.norm();
    if (speed >= kMinSpeedForCurvature) {
      const double kappa =
          (v.x() * a.y() - v.y() * a.x()) / (speed * speed * speed);
      k.max_curvature = std::max(k.max_curvature, std::abs(kappa));
    }
  }
  for (size_t i = 1; i < lon.size(); ++i) {
    const double dt = at[i] - at[i - 1];
    k.max_lon_jerk =
        std::max(k.max_lon_jerk, std::abs(lon[i] - lon[i - 1]) / dt);
    k.max_lat_jerk =
        std::max(k.max_lat_jerk, std::abs(lat[i] - lat[i - 1]) / dt);
  }
  return k;
}

bool KinematicEnvelope::Check() const {
  for (double v : {max_curvature, max_lon_accel, max_lat_accel, max_jerk})
    if (!std::isfinite(v) || v <= 0) return false;
  return true;
}

std::string KinematicEnvelope::Violation(const CandidateKinematics& k) const {
  auto over = [](const char* what, double value, double bound,
                 const char* unit) {
    return internal::StrCat(what, " ", value, " ", unit, " > ", bound);
  };
  if (k.max_curvature > max_curvature)
    return over("curvature", k.max_curvature, max_curvature, "1/m");
  if (k.max_lon_accel > max_lon_accel)
    return over("longitudinal acceleration", k.max_lon_accel, max_lon_accel,
                "m/s^2");
  if (k.max_lat_accel > max_lat_accel)
    return over("lateral acceleration", k.max_lat_accel, max_lat_accel,
                "m/s^2");
  if (k.max_lon_jerk > max_jerk)
    return over("longitudinal jerk", k.max_lon_jerk, max_jerk, "m/s^3");
  if (k.max_lat_jerk > max_jerk)
    return over("lateral jerk", k.max_lat_jerk, max_jerk, "m/s^3");
  return "";
}

bool LatticeOptions::Check() const {
  auto finite = [](const std::vector<double>& v) {
    return !v.empty() && std::all_of(v.begin(), v.end(),
                                     [](double x) { return std::isfinite(x); });
  };
  return std::isfinite(initial_speed) && initial_speed >= 0 &&
         std::isfinite(max_speed) && initial_speed <= max_speed &&
         std::isfinite(horizon_s) && std::isfinite(dt_s) && dt_s > 0 &&
         horizon_s >= dt_s && horizon_s / dt_s <= 1e5 &&
         std::isfinite(lane_change_s) && lane_change_s > 0 &&
         finite(lateral_offsets) && finite(accelerations) &&
         finite(yaw_rates) && max_candidates >= 0 && envelope.Check();
}

namespace {

// Distance travelled by time t at constant acceleration a from v0, the speed
// held in [0, vmax].
double DistanceAt(double v0, double a, double vmax, double t) {
  if (a == 0) return v0 * t;
  const double t_sat = a > 0 ? (vmax - v0) / a : v0 / -a;
  const double tt = std::min(t, t_sat);
  const double v_end = a > 0 ? vmax : 0.0;
  return v0 * tt + 0.5 * a * tt * tt + (t > t_sat ? v_end * (t - t_sat) : 0.0);
}

double SpeedAt(double v0, double a, double vmax, double t) {
  return std::clamp(v0 + a * t, 0.0, vmax);
}

Candidate LatticeCell(const LatticeOptions& o,
                      double offset,
                      double accel,
                      double yaw_rate) {
  char name[96];
  std::snprintf(name, sizeof name, "lat%+.2f_acc%+.1f_yaw%+.2f", offset, accel,
                yaw_rate);
  Candidate c;
  c.name = name;
  c.source = std::string("lattice ") + name;
  // Constant curvature: the yaw rate at the initial speed (1 m/s at least).
  const double kappa = yaw_rate / std::max(o.initial_speed, 1.0);
  const int n = static_cast<int>(std::floor(o.horizon_s / o.dt_s + 1e-9)) + 1;
  for (int i = 0; i < n; ++i) {
    const double t = i * o.dt_s;
    const double s = DistanceAt(o.initial_speed, accel, o.max_speed, t);
    const double v = SpeedAt(o.initial_speed, accel, o.max_speed, t);
    const double th = kappa * s;
    Eigen::Vector2d base;
    if (std::abs(kappa) < 1e-12) {
      base = Eigen::Vector2d(s, 0);
    } else {
      base = Eigen::Vector2d(std::sin(th) / kappa, (1 - std::cos(th)) / kappa);
    }
    // Quintic lane change: d = D (10u^3 - 15u^4 + 6u^5), u = t / T.
    const double u = std::min(t / o.lane_change_s, 1.0);
    const double d = offset * u * u * u * (10 - 15 * u + 6 * u * u);
    const double dd = t < o.lane_change_s ? offset * 30 * u * u * (1 - u) *
                                                (1 - u) / o.lane_change_s
                                          : 0.0;
    const Eigen::Vector2d tangent(std::cos(th), std::sin(th));
    const Eigen::Vector2d normal(-tangent.y(), tangent.x());
    const Eigen::Vector2d p = base + d * normal;
    const Eigen::Vector2d vel = v * (1 - kappa * d) * tangent + dd * normal;
    const double yaw = vel.norm() > 1e-6 ? std::atan2(vel.y(), vel.x()) : th;
    c.ego0_from_ego.Add(t, EgoPose(p.x(), p.y(), 0.0, yaw));
  }
  return c;
}

}  // namespace

std::vector<Candidate> SampleLattice(const LatticeOptions& options) {
  GEODRIVE_CHECK_INPUT(options.Check(),
                       "lattice options: need 0 <= initial_speed <= "
                       "max_speed, 0 < dt_s <= horizon_s, lane_change_s > 0, "
                       "non-empty finite offsets, accelerations and yaw "
                       "rates, max_candidates >= 0 and a positive envelope");
  std::vector<Candidate> feasible;
  int straight = -1;
  for (double offset : options.lateral_offsets) {
    for (double accel : options.accelerations) {
      for (double yaw_rate : options.yaw_rates) {
        Candidate c = LatticeCell(options, offset, accel, yaw_rate);
        if (!options.envelope.Violation(ComputeKinematics(c)).empty()) continue;
        if (offset == 0 && accel == 0 && yaw_rate == 0)
          straight = static_cast<int>(feasible.size());
        feasible.push_back(std::move(c));
      }
    }
  }
  const size_t m = static_cast<size_t>(options.max_candidates);
  if (m == 0 || feasible.size() <= m) return feasible;
  // The straight keep-speed cell first, then an even stride over the rest.
  std::vector<Candidate> out;
  std::vector<Candidate> rest;
  for (size_t i = 0; i < feasible.size(); ++i) {
    if (static_cast<int>(i) == straight) {
      out.push_back(feasible[i]);
    } else {
      rest.push_back(feasible[i]);
    }
  }
  const size_t want = m - out.size();
  for (size_t k = 0; k < want; ++k) {
    const size_t i = want == 1 ? 0 : k * (rest.size() - 1) / (want - 1);
    out.push_back(rest[i]);
  }
  return out;
}

}  // namespace geodrive

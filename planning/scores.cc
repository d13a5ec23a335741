#include "planning/scores.h"

#include <glog/logging.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <unordered_map>

#include "geometry/util/status.h"

namespace geodrive {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A box's footprint on z = 0: centre, unit axes (u along the length, n along
// the width) and half extents.
struct Rect {
  Eigen::Vector2d c, u, n;
  double hl = 0, hw = 0;

  std::array<Eigen::Vector2d, 4> Corners() const {
    return {c + hl * u + hw * n, c - hl * u + hw * n, c - hl * u - hw * n,
            c + hl * u - hw * n};
  }
  double Radius() const { return std::hypot(hl, hw); }
};

Rect RectOf(const Box3d& box) {
  Rect r;
  r.c = box.center.head<2>();
  Eigen::Vector2d u = (box.rotation * Eigen::Vector3d::UnitX()).head<2>();
  // A box standing on its end has no heading in the plane: any axis will do.
  r.u = u.norm() > 1e-9 ? u.normalized() : Eigen::Vector2d::UnitX();
  r.n = Eigen::Vector2d(-r.u.y(), r.u.x());
  r.hl = 0.5 * box.size.y();
  r.hw = 0.5 * box.size.x();
  return r;
}

// Separating-axis test on the four face normals of two rectangles.
bool Overlap(const Rect& a, const Rect& b) {
  const Eigen::Vector2d d = b.c - a.c;
  for (const Eigen::Vector2d& axis : {a.u, a.n, b.u, b.n}) {
    const double ra =
        a.hl * std::abs(a.u.dot(axis)) + a.hw * std::abs(a.n.dot(axis));
    const double rb =
        b.hl * std::abs(b.u.dot(axis)) + b.hw * std::abs(b.n.dot(axis));
    if (std::abs(d.dot(axis)) > ra + rb) return false;
  }
  return true;
}

double PointSegmentDistance(const Eigen::Vector2d& p,
                            const Eigen::Vector2d& a,
                            const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double s =
      len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + s * ab)).norm();
}

// Distance between two disjoint convex polygons: the closest pair has a
// vertex of one of them.
double RectDistance(const Rect& a, const Rect& b) {
  if (Overlap(a, b)) return 0.0;
  const auto ca = a.Corners(), cb = b.Corners();
  double best = kInf;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      best =
          std::min(best, PointSegmentDistance(ca[i], cb[j], cb[(j + 1) % 4]));
      best =
          std::min(best, PointSegmentDistance(cb[i], ca[j], ca[(j + 1) % 4]));
    }
  }
  return best;
}

// Distance from a point to a rectangle (0 inside).
double PointRectDistance(const Eigen::Vector2d& p, const Rect& r) {
  const Eigen::Vector2d d = p - r.c;
  const double du = std::max(0.0, std::abs(d.dot(r.u)) - r.hl);
  const double dn = std::max(0.0, std::abs(d.dot(r.n)) - r.hw);
  return std::hypot(du, dn);
}

// Two 32-bit cell indices in one key (shifted as unsigned: a negative index
// shifted left is undefined).
int64_t CellKey(int64_t i, int64_t j) {
  return static_cast<int64_t>((static_cast<uint64_t>(i) << 32) ^
                              (static_cast<uint64_t>(j) & 0xffffffffu));
}

// Points of one class (ground or obstacle) bucketed in a BEV grid.
struct PointGrid {
  double cell = 1.0;
  std::unordered_map<int64_t, std::vector<Eigen::Vector2d>> cells;

  int64_t Index(double v) const {
    return static_cast<int64_t>(std::floor(v / cell));
  }
  void Add(const Eigen::Vector2d& p) {
    cells[CellKey(Index(p.x()), Index(p.y()))].push_back(p);
  }
  const std::vector<Eigen::Vector2d>* At(int64_t i, int64_t j) const {
    const auto it = cells.find(CellKey(i, j));
    return it == cells.end() ? nullptr : &it->second;
  }
  // True if a point lies within `radius` of p.
  bool AnyWithin(const Eigen::Vector2d& p, double radius) const {
    const int64_t i0 = Index(p.x() - radius), i1 = Index(p.x() + radius);
    const int64_t j0 = Index(p.y() - radius), j1 = Index(p.y() + radius);
    for (int64_t i = i0; i <= i1; ++i)
      for (int64_t j = j0; j <= j1; ++j)
        if (const auto* pts = At(i, j))
          for (const Eigen::Vector2d& q : *pts)
            if ((q - p).squaredNorm() <= radius * radius) return true;
    return false;
  }
  // Distance from the rectangle to the nearest point, at most `limit`.
  double Nearest(const Rect& r, double limit) const {
    const double reach = r.Radius() + limit;
    const int64_t i0 = Index(r.c.x() - reach), i1 = Index(r.c.x() + reach);
    const int64_t j0 = Index(r.c.y() - reach), j1 = Index(r.c.y() + reach);
    double best = limit;
    for (int64_t i = i0; i <= i1; ++i) {
      for (int64_t j = j0; j <= j1; ++j) {
        const auto* pts = At(i, j);
        if (!pts) continue;
        // Lower bound: the cell's centre distance minus its half diagonal.
        const Eigen::Vector2d centre((i + 0.5) * cell, (j + 0.5) * cell);
        if (PointRectDistance(centre, r) - cell * M_SQRT1_2 >= best) continue;
        for (const Eigen::Vector2d& q : *pts)
          best = std::min(best, PointRectDistance(q, r));
      }
    }
    return best;
  }
};

// Ground segmentation of the static cloud (docs/PLANNING.md): per BEV cell
// the lowest point; a cell's local ground is the lowest of the cells within
// ground_window; a point is ground up to ground_margin above it, an obstacle
// up to obstacle_max_height.
void SegmentGround(const PlanningScene& scene,
                   const PlanScoreOptions& o,
                   std::vector<PointClass>* labels) {
  const PointCloud& cloud = scene.static_cloud;
  labels->assign(cloud.positions.size(), PointClass::kOther);
  const double cell = o.ground_cell;
  // Cells of one sweep: (i, j) within 2^23 cells of the origin (thousands of
  // km) and the sweep in the top byte keep the key unique.
  auto key = [&](size_t point, int64_t i, int64_t j) {
    const int64_t sweep =
        scene.static_cloud_sweep.empty() ? 0 : scene.static_cloud_sweep[point];
    return CellKey(i, j) ^
           static_cast<int64_t>(static_cast<uint64_t>(sweep) << 56);
  };
  auto index = [cell](double v) {
    return static_cast<int64_t>(std::floor(v / cell));
  };
  const bool ranged = !scene.sweep_origins.empty();
  std::vector<char> usable(cloud.positions.size());
  for (size_t n = 0; n < usable.size(); ++n) {
    const Eigen::Vector3f& p = cloud.positions[n];
    bool ok = p.allFinite() && std::abs(p.x()) < cell * (1 << 22) &&
              std::abs(p.y()) < cell * (1 << 22);
    if (ok && ranged) {
      const int32_t sweep =
          scene.static_cloud_sweep.empty() ? 0 : scene.static_cloud_sweep[n];
      ok = (p.cast<double>() - scene.sweep_origins[sweep]).head<2>().norm() <=
           o.max_point_range;
    }
    usable[n] = ok;
  }
  // Per cell its three lowest heights: the third lowest (or the highest of
  // fewer) is the cell's ground, so that a stray point below the ground
  // (multipath, noise) does not lower it.
  struct Lowest {
    float z[3];
    int n = 0;
    void Add(float v) {
      if (n < 3) {
        z[n++] = v;
      } else if (v < z[2]) {
        z[2] = v;
      } else {
        return;
      }
      std::sort(z, z + n);
    }
    float Ground() const { return z[n - 1]; }
  };
  std::unordered_map<int64_t, Lowest> lowest;
  for (size_t n = 0; n < cloud.positions.size(); ++n) {
    const Eigen::Vector3f& p = cloud.positions[n];
    if (!usable[n]) continue;
    lowest[key(n, index(p.x()), index(p.y()))].Add(p.z());
  }
  // A cell's local ground: the median of the cell grounds within the window
  // (robust to the few cells whose lowest points are on an obstacle).
  const int64_t w = static_cast<int64_t>(std::ceil(o.ground_window / cell));
  std::unordered_map<int64_t, float> local;
  std::vector<float> around;
  for (size_t n = 0; n < cloud.positions.size(); ++n) {
    const Eigen::Vector3f& p = cloud.positions[n];
    if (!usable[n]) continue;
    const int64_t i = index(p.x()), j = index(p.y());
    auto [it, added] = local.emplace(key(n, i, j), 0.0f);
    if (added) {
      around.clear();
      for (int64_t a = i - w; a <= i + w; ++a)
        for (int64_t b = j - w; b <= j + w; ++b)
          if (const auto f = lowest.find(key(n, a, b)); f != lowest.end())
            around.push_back(f->second.Ground());
      std::nth_element(around.begin(), around.begin() + around.size() / 2,
                       around.end());
      it->second = around[around.size() / 2];
    }
    const double h = p.z() - it->second;
    if (h <= o.ground_margin) {
      (*labels)[n] = PointClass::kGround;
    } else if (h <= o.obstacle_max_height) {
      (*labels)[n] = PointClass::kObstacle;
    }
  }
}

int64_t CountPoints(const PointGrid& g) {
  int64_t n = 0;
  for (const auto& [key, pts] : g.cells) n += static_cast<int64_t>(pts.size());
  return n;
}

Rect EgoRect(const Rigid3d& pose, const PlanScoreOptions& o) {
  return RectOf(EgoBox(pose, o));
}

// Collision scores: distances at the waypoints and `substeps` times between
// each pair, first contact refined by bisection.
void ScoreCollision(const PlanningScene& scene,
                    const Candidate& c,
                    const PlanScoreOptions& o,
                    CandidateScores* s) {
  const Trajectory& tr = c.ego0_from_ego;
  if (scene.obstacles.empty()) return;
  std::vector<double> times;
  for (size_t i = 0; i + 1 < tr.size(); ++i) {
    for (int k = 0; k <= o.collision_substeps; ++k) {
      times.push_back(tr.timestamps[i] +
                      (tr.timestamps[i + 1] - tr.timestamps[i]) * k /
                          (o.collision_substeps + 1));
    }
  }
  times.push_back(tr.timestamps.back());
  auto contact = [&](size_t obstacle, double t) {
    return Overlap(EgoRect(tr.PoseAt(t), o),
                   RectOf(scene.obstacles[obstacle].At(t)));
  };
  double previous = kNaN;
  for (double t : times) {
    const Rect ego = EgoRect(tr.PoseAt(t), o);
    for (size_t k = 0; k < scene.obstacles.size(); ++k) {
      const Rect box = RectOf(scene.obstacles[k].At(t));
      if ((box.c - ego.c).norm() - box.Radius() - ego.Radius() >
          s->min_box_distance)
        continue;
      const double d = RectDistance(ego, box);
      if (d < s->min_box_distance) {
        s->min_box_distance = d;
        s->min_box_distance_time = t;
        s->closest_obstacle = scene.obstacles[k].id;
      }
      if (d > 0 || s->collides) continue;
      // First contact: bisect between the previous sample (clear of this
      // obstacle up to the sampling) and t.
      double lo = std::isnan(previous) ? t : previous, hi = t;
      while (hi - lo > o.collision_time_tolerance_s) {
        const double mid = 0.5 * (lo + hi);
        (contact(k, mid) ? hi : lo) = mid;
      }
      if (std::isnan(s->first_collision_time) || hi < s->first_collision_time) {
        s->first_collision_time = hi;
        s->first_collision_with = scene.obstacles[k].id;
        s->first_collision_category = scene.obstacles[k].category;
      }
    }
    if (!std::isnan(s->first_collision_time)) s->collides = true;
    previous = t;
  }
}

void ScoreDrivable(const PointGrid& ground,
                   const PointGrid& obstacles,
                   const Candidate& c,
                   const PlanScoreOptions& o,
                   CandidateScores* s) {
  const int nl =
      static_cast<int>(std::ceil(o.ego_length / o.footprint_spacing)) + 1;
  const int nw =
      static_cast<int>(std::ceil(o.ego_width / o.footprint_spacing)) + 1;
  int64_t over = 0, total = 0;
  double clearance = o.clearance_search_radius;
  double clearance_time = c.ego0_from_ego.timestamps.front();
  for (size_t k = 0; k < c.size(); ++k) {
    const Rect r = EgoRect(c.ego0_from_ego.world_from_cam[k], o);
    for (int a = 0; a < nl; ++a) {
      for (int b = 0; b < nw; ++b) {
        const Eigen::Vector2d p = r.c +
                                  r.u * (-r.hl + 2 * r.hl * a / (nl - 1)) +
                                  r.n * (-r.hw + 2 * r.hw * b / (nw - 1));
        over += ground.AnyWithin(p, o.ground_support_radius) ? 1 : 0;
        ++total;
      }
    }
    const double d = obstacles.Nearest(r, clearance);
    if (d < clearance) {
      clearance = d;
      clearance_time = c.ego0_from_ego.timestamps[k];
    }
  }
  s->drivable_fraction = total > 0 ? double(over) / double(total) : kNaN;
  s->static_clearance = clearance;
  s->static_clearance_time = clearance_time;
}

void ScoreLogged(const Trajectory& logged,
                 const Candidate& c,
                 CandidateScores* s) {
  if (logged.size() < 1) return;
  const double lo = logged.timestamps.front(), hi = logged.timestamps.back();
  double sum = 0, last = kNaN;
  int n = 0;
  for (size_t i = 0; i < c.size(); ++i) {
    const double t = c.ego0_from_ego.timestamps[i];
    if (t < lo - 1e-9 || t > hi + 1e-9) continue;
    const Eigen::Vector2d d = (c.ego0_from_ego.world_from_cam[i].translation -
                               logged.PoseAt(t).translation)
                                  .head<2>();
    last = d.norm();
    sum += last;
    ++n;
  }
  if (n == 0) return;
  s->ade = sum / n;
  s->fde = last;
}

// Weighted cost (docs/PLANNING.md); a term whose score is NaN adds nothing.
double Cost(const CandidateScores& s, const PlanScoreOptions& o) {
  auto finite_or_zero = [](double v) { return std::isfinite(v) ? v : 0.0; };
  double cost = o.weight_collision * (s.collides ? 1.0 : 0.0);
  cost += o.weight_clearance *
          std::max(0.0, o.clearance_target - s.min_box_distance);
  cost += o.weight_offroad * finite_or_zero(1.0 - s.drivable_fraction);
  cost +=
      o.weight_static_clearance *
      finite_or_zero(std::max(0.0, o.clearance_target - s.static_clearance));
  cost += o.weight_ade * finite_or_zero(s.ade);
  cost += o.weight_accel *
          (s.kinematics.max_lat_accel + s.kinematics.max_lon_accel);
  cost += o.weight_jerk *
          std::max(s.kinematics.max_lat_jerk, s.kinematics.max_lon_jerk);
  cost -= o.weight_progress * s.progress;
  return cost;
}

void Decide(const PlanScoreOptions& o, CandidateScores* s) {
  char buf[160];
  if (s->collides) {
    s->reject = RejectReason::kCollision;
    std::snprintf(buf, sizeof buf, "collision with %s%s%s at %.3f s",
                  s->first_collision_category.c_str(),
                  s->first_collision_category.empty() ? "" : " ",
                  s->first_collision_with.c_str(), s->first_collision_time);
    s->reject_detail = buf;
  } else if (s->drivable_fraction < o.min_drivable_fraction) {
    s->reject = RejectReason::kOffDrivable;
    std::snprintf(buf, sizeof buf, "drivable fraction %.3f < %.3f",
                  s->drivable_fraction, o.min_drivable_fraction);
    s->reject_detail = buf;
  } else if (s->static_clearance <= 0) {
    s->reject = RejectReason::kOffDrivable;
    std::snprintf(buf, sizeof buf,
                  "footprint over an obstacle point (kerb, pole, wall) at "
                  "%.3f s",
                  s->static_clearance_time);
    s->reject_detail = buf;
  } else if (!s->envelope_violation.empty()) {
    s->reject = RejectReason::kKinematics;
    s->reject_detail = s->envelope_violation;
  }
}

}  // namespace

Box3d ObstacleTrack::At(double t) const {
  CHECK_EQ(times.size(), boxes.size());
  CHECK(!boxes.empty());
  if (t <= times.front()) return boxes.front();
  if (t >= times.back()) return boxes.back();
  const size_t i =
      std::upper_bound(times.begin(), times.end(), t) - times.begin();
  const double a = (t - times[i - 1]) / (times[i] - times[i - 1]);
  return Interpolate(boxes[i - 1], boxes[i], a);
}

std::string ToString(RejectReason reason) {
  switch (reason) {
    case RejectReason::kNone:
      return "none";
    case RejectReason::kCollision:
      return "collision";
    case RejectReason::kOffDrivable:
      return "off-drivable";
    case RejectReason::kKinematics:
      return "kinematics";
  }
  return "?";
}

bool PlanScoreOptions::Check() const {
  for (double v :
       {ego_length, ego_width, ego_height, ground_cell, ground_margin,
        obstacle_max_height, ground_support_radius, footprint_spacing,
        clearance_search_radius, collision_time_tolerance_s})
    if (!std::isfinite(v) || v <= 0) return false;
  for (double v :
       {ego_center_ahead, weight_collision, weight_clearance, clearance_target,
        weight_offroad, weight_static_clearance, weight_ade, weight_accel,
        weight_jerk, weight_progress, ground_window})
    if (!std::isfinite(v)) return false;
  return collision_substeps >= 0 && collision_substeps <= 1000 &&
         obstacle_max_height > ground_margin && ground_window >= 0 &&
         min_drivable_fraction >= 0 && min_drivable_fraction <= 1 &&
         envelope.Check();
}

std::vector<PointClass> ClassifyStaticPoints(const PlanningScene& scene,
                                             const PlanScoreOptions& options) {
  GEODRIVE_CHECK_INPUT(
      scene.static_cloud_sweep.empty() ||
          scene.static_cloud_sweep.size() == scene.static_cloud.size(),
      "planning scene: ", scene.static_cloud_sweep.size(), " sweep ids for ",
      scene.static_cloud.size(), " static points");
  const size_t num_sweeps =
      scene.sweep_origins.empty()
          ? 256
          : std::min<size_t>(256, scene.sweep_origins.size());
  for (int32_t sweep : scene.static_cloud_sweep)
    GEODRIVE_CHECK_INPUT(sweep >= 0 && size_t(sweep) < num_sweeps,
                         "planning scene: sweep id ", sweep, " is outside [0, ",
                         num_sweeps - 1, "]");
  std::vector<PointClass> labels;
  SegmentGround(scene, options, &labels);
  return labels;
}

Box3d EgoBox(const Rigid3d& ego0_from_ego, const PlanScoreOptions& o) {
  Box3d box;
  box.size = Eigen::Vector3d(o.ego_width, o.ego_length, o.ego_height);
  box.rotation = ego0_from_ego.rotation;
  box.center = ego0_from_ego *
               Eigen::Vector3d(o.ego_center_ahead, 0, 0.5 * o.ego_height);
  return box;
}

double BevBoxDistance(const Box3d& a, const Box3d& b) {
  return RectDistance(RectOf(a), RectOf(b));
}

PlanResult ScoreCandidates(const PlanningScene& scene,
                           const std::vector<Candidate>& candidates,
                           const PlanScoreOptions& options) {
  GEODRIVE_CHECK_INPUT(
      options.Check(),
      "plan score options: lengths, tolerances and radii must be > 0, "
      "weights finite, obstacle_max_height > ground_margin, "
      "min_drivable_fraction in [0, 1], collision_substeps in [0, 1000]");
  for (const ObstacleTrack& track : scene.obstacles) {
    GEODRIVE_CHECK_INPUT(
        !track.boxes.empty() && track.times.size() == track.boxes.size(),
        "obstacle ", track.id, ": needs one time per box, at least one");
    for (size_t i = 0; i < track.boxes.size(); ++i) {
      GEODRIVE_CHECK_INPUT(
          track.boxes[i].IsValid() && std::isfinite(track.times[i]) &&
              (i == 0 || track.times[i] > track.times[i - 1]),
          "obstacle ", track.id, ": box ", i,
          " is invalid or its time is not after the previous one");
    }
  }
  const auto start = std::chrono::steady_clock::now();
  PlanResult result;
  PointGrid ground, obstacles;
  const bool has_cloud = !scene.static_cloud.positions.empty();
  if (has_cloud) {
    const std::vector<PointClass> labels = ClassifyStaticPoints(scene, options);
    ground.cell = options.ground_cell;
    obstacles.cell = std::max(options.ground_cell, 2.0);
    for (size_t n = 0; n < labels.size(); ++n) {
      const Eigen::Vector3f& p = scene.static_cloud.positions[n];
      if (labels[n] == PointClass::kGround)
        ground.Add(Eigen::Vector2d(p.x(), p.y()));
      if (labels[n] == PointClass::kObstacle)
        obstacles.Add(Eigen::Vector2d(p.x(), p.y()));
    }
    result.ground_points = CountPoints(ground);
    result.obstacle_points = CountPoints(obstacles);
  }
  for (const Candidate& c : candidates) {
    ValidateCandidate(c);
    CandidateScores s;
    s.name = c.name;
    ScoreCollision(scene, c, options, &s);
    if (has_cloud) ScoreDrivable(ground, obstacles, c, options, &s);
    s.kinematics = ComputeKinematics(c);
    s.envelope_violation = options.envelope.Violation(s.kinematics);
    ScoreLogged(scene.logged, c, &s);
    s.progress = s.kinematics.path_length;
    s.cost = Cost(s, options);
    Decide(options, &s);
    result.candidates.push_back(std::move(s));
  }
  for (size_t i = 0; i < result.candidates.size(); ++i)
    result.ranking.push_back(int(i));
  std::stable_sort(result.ranking.begin(), result.ranking.end(),
                   [&](int a, int b) {
                     const CandidateScores &sa = result.candidates[a],
                                           &sb = result.candidates[b];
                     const bool ra = sa.reject != RejectReason::kNone,
                                rb = sb.reject != RejectReason::kNone;
                     if (ra != rb) return !ra;
                     return sa.cost < sb.cost;
                   });
  for (size_t r = 0; r < result.ranking.size(); ++r)
    result.candidates[result.ranking[r]].rank = static_cast<int>(r) + 1;
  result.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  return result;
}

std::string PlanResult::BriefReport() const {
  int rejected[4] = {0, 0, 0, 0};
  for (const CandidateScores& s : candidates)
    ++rejected[static_cast<int>(s.reject)];
  const int n = static_cast<int>(candidates.size());
  char buf[512];
  std::snprintf(
      buf, sizeof buf,
      "%d candidates: %d accepted, %d rejected (%d collision, %d off-drivable, "
      "%d kinematics)",
      n, rejected[0], n - rejected[0], rejected[1], rejected[2], rejected[3]);
  std::string out = buf;
  if (!ranking.empty()) {
    const CandidateScores& best = candidates[ranking.front()];
    std::snprintf(buf, sizeof buf, "; best %s (cost %.3f%s)", best.name.c_str(),
                  best.cost,
                  best.reject == RejectReason::kNone ? "" : ", rejected");
    out += buf;
  }
  std::snprintf(buf, sizeof buf, "; %.3f s", seconds);
  return out + buf;
}

}  // namespace geodrive

#include "dataset/synthetic/synthetic_world.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "geometry/util/status.h"

namespace geodrive {

std::string ToString(EgoManeuver maneuver) {
  switch (maneuver) {
    case EgoManeuver::kLaneChange:
      return "lane-change";
    case EgoManeuver::kLeftTurn:
      return "left-turn";
    case EgoManeuver::kBrakeAndStop:
      return "brake-and-stop";
    case EgoManeuver::kStraight:
      return "straight";
  }
  return "?";
}

std::string SyntheticWorldOptions::Validate() const {
  std::ostringstream os;
  if (!(duration_s >= 1.0 && duration_s <= 3600.0)) {
    os << "duration_s must be in [1, 3600] (got " << duration_s << ")";
  } else if (scene_index < 0) {
    os << "scene_index must be >= 0";
  } else if (maneuver < -1 || maneuver > 3) {
    os << "maneuver must be -1 (auto) or 0..3";
  }
  return os.str();
}

namespace {

constexpr double kLaneWidth = 3.5;
constexpr double kRoadHalfWidth = 7.0;  // two lanes per direction
constexpr double kSidewalkWidth = 4.0;  // kerb to facade line
constexpr double kKerbHeight = 0.15;
constexpr double kStopLineOffset =
    9.35;  // stop line centre distance from the intersection
constexpr double kTurnRadius = 10.0;
constexpr double kInf = std::numeric_limits<double>::infinity();

// ---------------------------------------------------------------------------------------------
// Deterministic randomness (platform independent).
uint64_t SplitMix64(uint64_t& state) {
  uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
struct Rng {
  uint64_t state;
  explicit Rng(uint64_t seed) : state(seed) {}
  double Uniform(double lo, double hi) {
    return lo + (hi - lo) * static_cast<double>(SplitMix64(state) >> 11) *
                    (1.0 / 9007199254740992.0);
  }
  uint32_t U32() { return static_cast<uint32_t>(SplitMix64(state) >> 32); }
};

inline uint32_t Hash3(int32_t a, int32_t b, uint32_t c) {
  uint32_t h = static_cast<uint32_t>(a) * 0x8da6b343u ^
               static_cast<uint32_t>(b) * 0xd8163841u ^ c * 0xcb1ab31fu;
  h ^= h >> 15;
  h *= 0x2c1b3c6du;
  h ^= h >> 12;
  h *= 0x297a2d39u;
  h ^= h >> 15;
  return h;
}
inline double Hash01(int32_t a, int32_t b, uint32_t c) {
  return Hash3(a, b, c) * (1.0 / 4294967296.0);
}
inline int32_t FloorInt(double x) {
  const int32_t i = static_cast<int32_t>(x);
  return x < i ? i - 1 : i;
}
// Bilinear value noise in [0, 1) with smoothstep weights.
double ValueNoise(double x, double y, uint32_t seed) {
  const int32_t ix = FloorInt(x), iy = FloorInt(y);
  double fx = x - ix, fy = y - iy;
  fx = fx * fx * (3 - 2 * fx);
  fy = fy * fy * (3 - 2 * fy);
  const double a = Hash01(ix, iy, seed), b = Hash01(ix + 1, iy, seed);
  const double c = Hash01(ix, iy + 1, seed), d = Hash01(ix + 1, iy + 1, seed);
  return (a + (b - a) * fx) + ((c + (d - c) * fx) - (a + (b - a) * fx)) * fy;
}
inline double Frac(double x) { return x - std::floor(x); }

// ---------------------------------------------------------------------------------------------
// Piecewise-constant-acceleration 1D motion.
class SpeedProfile {
 public:
  explicit SpeedProfile(double v0 = 0) { segs_.push_back({0, 0, v0, 0}); }
  // The current (last) segment lasts `duration` seconds; the next one has
  // acceleration `accel` (the last segment lasts forever).
  SpeedProfile& Then(double duration, double accel) {
    const Seg last = segs_.back();
    segs_.push_back(
        {last.t0 + duration,
         last.p0 + last.v0 * duration + 0.5 * last.a * duration * duration,
         last.v0 + last.a * duration, accel});
    return *this;
  }
  // Sets the acceleration of the current (last) segment.
  SpeedProfile& Accel(double a) {
    segs_.back().a = a;
    return *this;
  }
  double Pos(double t) const {
    const Seg& s = Find(t);
    const double dt = t - s.t0;
    return s.p0 + s.v0 * dt + 0.5 * s.a * dt * dt;
  }
  double Vel(double t) const {
    const Seg& s = Find(t);
    return s.v0 + s.a * (t - s.t0);
  }

 private:
  struct Seg {
    double t0, p0, v0, a;
  };
  const Seg& Find(double t) const {
    size_t i = 0;
    while (i + 1 < segs_.size() && t >= segs_[i + 1].t0) ++i;
    return segs_[i];
  }
  std::vector<Seg> segs_;
};

// Builds "cruise at v, then brake at `decel` so as to stop after travelling
// `distance`".
SpeedProfile CruiseThenStop(double v, double distance, double decel) {
  const double brake_dist = v * v / (2 * decel);
  if (distance <= 0.05) return SpeedProfile(0);
  if (distance < brake_dist) {
    const double a = v * v / (2 * distance);
    SpeedProfile p(v);
    p.Accel(-a).Then(v / a, 0);
    return p;
  }
  SpeedProfile p(v);
  p.Then((distance - brake_dist) / v, -decel).Then(v / decel, 0);
  return p;
}

// A vehicle driving along a straight lane of the main street (axis 0: along x,
// offset = y) or of the cross street (axis 1: along y, offset = x).
struct Track {
  int axis = 0;
  double offset = 0;
  int dir = 1;
  double s0 = 0;
  SpeedProfile profile;
  std::string category;
  Eigen::Vector3d size_wlh;
  bool parked = false;
  Eigen::Vector3f color;
  uint32_t tex = 0;

  // (x, y, heading) in the street frame.
  Eigen::Vector3d Pose(double t) const {
    const double s = s0 + dir * profile.Pos(t);
    const double heading =
        (axis == 0 ? 0.0 : M_PI / 2) + (dir < 0 ? M_PI : 0.0);
    return axis == 0 ? Eigen::Vector3d(s, offset, heading)
                     : Eigen::Vector3d(offset, s, heading);
  }
  double Speed(double t) const { return profile.Vel(t); }
};

enum Material : uint8_t {
  kGround,
  kSidewalk,
  kBuilding,
  kBrickBuilding,
  kPole,
  kPlanter,
  kVehicleBody,
};

// Upright box (yaw about z) in the street frame.
struct Box {
  double cx = 0, cy = 0, c = 1, s = 0;  // centre, cos/sin yaw
  double hx = 0, hy = 0;                // half extents along local x, y
  double z0 = 0, z1 = 0;
  Material material = kSidewalk;
  uint16_t instance = kStaticInstance;
  uint32_t tex = 0;
  Eigen::Vector3f color = Eigen::Vector3f::Constant(0.5f);
  double min_dist = 0;  // per-query scratch: distance from the ray origin

  static Box Aabb(double x0,
                  double x1,
                  double y0,
                  double y1,
                  double z0,
                  double z1,
                  Material m) {
    Box b;
    b.cx = 0.5 * (x0 + x1);
    b.cy = 0.5 * (y0 + y1);
    b.hx = 0.5 * (x1 - x0);
    b.hy = 0.5 * (y1 - y0);
    b.z0 = z0;
    b.z1 = z1;
    b.material = m;
    return b;
  }
  // Local coordinates of a street-frame point.
  Eigen::Vector3d ToLocal(const Eigen::Vector3d& p) const {
    const double px = p.x() - cx, py = p.y() - cy;
    return {c * px + s * py, -s * px + c * py, p.z()};
  }
  Eigen::Vector3d ToStreet(double lx, double ly, double z) const {
    return {cx + c * lx - s * ly, cy + s * lx + c * ly, z};
  }
  // Euclidean distance from a point to the box (0 inside).
  double DistanceTo(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d l = ToLocal(p);
    const double dx = std::max(std::abs(l.x()) - hx, 0.0);
    const double dy = std::max(std::abs(l.y()) - hy, 0.0);
    const double dz = std::max({z0 - l.z(), l.z() - z1, 0.0});
    return std::sqrt(dx * dx + dy * dy + dz * dz);
  }
};

// Slab test. face: 0 -x, 1 +x, 2 -y, 3 +y, 4 bottom, 5 top. Returns false if
// missed or if the origin is inside the box.
inline bool IntersectBox(const Box& b,
                         const Eigen::Vector3d& o,
                         const Eigen::Vector3d& d,
                         double t_limit,
                         double* t_hit,
                         int* face) {
  const double px = o.x() - b.cx, py = o.y() - b.cy;
  const double lo[3] = {b.c * px + b.s * py, -b.s * px + b.c * py, o.z()};
  const double ld[3] = {b.c * d.x() + b.s * d.y(), -b.s * d.x() + b.c * d.y(),
                        d.z()};
  const double lo_b[3] = {-b.hx, -b.hy, b.z0};
  const double hi_b[3] = {b.hx, b.hy, b.z1};
  double tmin = 0, tmax = t_limit;
  int f = -1;
  for (int a = 0; a < 3; ++a) {
    if (ld[a] == 0.0) {
      if (lo[a] < lo_b[a] || lo[a] > hi_b[a]) return false;
      continue;
    }
    const double inv = 1.0 / ld[a];
    double t1 = (lo_b[a] - lo[a]) * inv, t2 = (hi_b[a] - lo[a]) * inv;
    int entering = 2 * a;  // ray moving +: enters through the low face
    if (t1 > t2) {
      std::swap(t1, t2);
      entering = 2 * a + 1;
    }
    if (t1 > tmin) {
      tmin = t1;
      f = entering;
    }
    if (t2 < tmax) tmax = t2;
    if (tmin > tmax) return false;
  }
  if (f < 0) return false;
  *t_hit = tmin;
  *face = f;
  return true;
}

// 2D oriented-rectangle overlap (separating axis), with a margin added to both
// half extents.
bool RectsOverlap(const Eigen::Vector3d& a,
                  double al,
                  double aw,
                  const Eigen::Vector3d& b,
                  double bl,
                  double bw,
                  double margin) {
  const Eigen::Vector2d ca(a.x(), a.y()), cb(b.x(), b.y());
  const Eigen::Vector2d ax[4] = {{std::cos(a.z()), std::sin(a.z())},
                                 {-std::sin(a.z()), std::cos(a.z())},
                                 {std::cos(b.z()), std::sin(b.z())},
                                 {-std::sin(b.z()), std::cos(b.z())}};
  const double ha[2] = {al / 2 + margin, aw / 2 + margin};
  const double hb[2] = {bl / 2 + margin, bw / 2 + margin};
  for (const auto& n : ax) {
    const double ra =
        ha[0] * std::abs(n.dot(ax[0])) + ha[1] * std::abs(n.dot(ax[1]));
    const double rb =
        hb[0] * std::abs(n.dot(ax[2])) + hb[1] * std::abs(n.dot(ax[3]));
    if (std::abs(n.dot(cb - ca)) > ra + rb) return false;
  }
  return true;
}

inline Eigen::Vector3f Mix(const Eigen::Vector3f& a,
                           const Eigen::Vector3f& b,
                           float t) {
  return a + (b - a) * t;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
struct SyntheticWorld::Impl {
  // Ego.
  EgoManeuver maneuver;
  SpeedProfile ego_profile;
  double lane_change_start = 0, lane_change_length = 30;
  double turn_start = 0;  // path parameter of the arc start (left turn)
  double xc = 60;         // intersection x
  // Scene.
  std::vector<Box> static_boxes;
  std::vector<Track> vehicles;
  Eigen::Vector3d sun = Eigen::Vector3d(0.45, 0.3, 0.84).normalized();
  uint32_t ground_tex = 1;

  // Ego (x, y, heading) in the street frame at time t.
  Eigen::Vector3d EgoStreetPose(double t) const {
    const double p = ego_profile.Pos(t);
    switch (maneuver) {
      case EgoManeuver::kLaneChange: {
        const double y0 = -kRoadHalfWidth + kLaneWidth / 2,
                     y1 = -kLaneWidth / 2;
        const double u =
            std::clamp((p - lane_change_start) / lane_change_length, 0.0, 1.0);
        const double y = y0 + (y1 - y0) * 0.5 * (1 - std::cos(M_PI * u));
        const double dy = (u > 0 && u < 1)
                              ? (y1 - y0) * 0.5 * M_PI * std::sin(M_PI * u) /
                                    lane_change_length
                              : 0.0;
        return {p, y, std::atan(dy)};
      }
      case EgoManeuver::kLeftTurn: {
        const double y0 = -kLaneWidth / 2;
        if (p <= turn_start) return {p, y0, 0.0};
        const double arc = M_PI / 2 * kTurnRadius;
        if (p <= turn_start + arc) {
          const double phi = (p - turn_start) / kTurnRadius;
          return {turn_start + kTurnRadius * std::sin(phi),
                  y0 + kTurnRadius - kTurnRadius * std::cos(phi), phi};
        }
        return {turn_start + kTurnRadius,
                y0 + kTurnRadius + (p - turn_start - arc), M_PI / 2};
      }
      case EgoManeuver::kBrakeAndStop:
      case EgoManeuver::kStraight:
        return {p, -kLaneWidth / 2, 0.0};
    }
    return {p, 0, 0};
  }

  Box VehicleBoxAt(int i, double t) const {
    const Track& tr = vehicles[i];
    const Eigen::Vector3d pose = tr.Pose(t);
    Box b;
    b.cx = pose.x();
    b.cy = pose.y();
    b.c = std::cos(pose.z());
    b.s = std::sin(pose.z());
    b.hx = tr.size_wlh[1] / 2;
    b.hy = tr.size_wlh[0] / 2;
    b.z0 = 0;
    b.z1 = tr.size_wlh[2];
    b.material = kVehicleBody;
    b.instance = static_cast<uint16_t>(i + 1);
    b.tex = tr.tex;
    b.color = tr.color;
    return b;
  }

  void AppendVehicles(double t, std::vector<Box>* boxes) const {
    for (int i = 0; i < static_cast<int>(vehicles.size()); ++i)
      boxes->push_back(VehicleBoxAt(i, t));
  }

  void Generate(const SyntheticWorldOptions& options,
                Rigid3d* global_from_street);
  // The steps of Generate, in the order of their random draws: the ego's
  // speed profile and the intersection position (jitter: a draw of Generate),
  // the seven vehicles, the crossing car's timing (no draws), and the sidewalk
  // blocks, facades, poles and planters.
  void PlanEgo(const SyntheticWorldOptions& options, double jitter);
  void AddVehicles(double duration_s, Rng* rng);
  void TimeCrossingCar(double duration_s);
  void AddStaticStructure(Rng* rng);
  void ShadeGround(const Eigen::Vector3d& p,
                   float rgb[3],
                   uint8_t* intensity) const;
  void Shade(const Box* box,
             int face,
             const Eigen::Vector3d& p,
             const Eigen::Vector3d& dir,
             float rgb[3],
             uint8_t* intensity) const;
  static void Sky(const Eigen::Vector3d& dir, float rgb[3]);

  // Nearest hit among `ids` (sorted by min_dist) and the ground; returns the
  // range parameter t (in units of |d|) or kInf; *hit_box = -1 ground, -2 none.
  double Trace(const std::vector<Box>& boxes,
               const int* ids,
               int n,
               const Eigen::Vector3d& o,
               const Eigen::Vector3d& d,
               double dn,
               double max_t,
               int* hit_box,
               int* face) const {
    double best = kInf;
    *hit_box = -2;
    if (d.z() < 0) {
      const double tg = -o.z() / d.z();
      if (tg <= max_t) {
        best = tg;
        *hit_box = -1;
      }
    }
    for (int k = 0; k < n; ++k) {
      const Box& b = boxes[ids[k]];
      if (b.min_dist >= std::min(best, max_t) * dn) break;
      double th;
      int f;
      if (IntersectBox(b, o, d, std::min(best, max_t), &th, &f) && th < best) {
        best = th;
        *hit_box = ids[k];
        *face = f;
      }
    }
    return best;
  }
};

void SyntheticWorld::Impl::Generate(const SyntheticWorldOptions& options,
                                    Rigid3d* global_from_street) {
  uint64_t st = options.seed * 0x9E3779B97F4A7C15ull + 0x1234567ull;
  st ^= static_cast<uint64_t>(options.scene_index) * 0xD1B54A32D192ED03ull;
  SplitMix64(st);
  Rng rng(st);
  maneuver = options.maneuver >= 0
                 ? static_cast<EgoManeuver>(options.maneuver)
                 : static_cast<EgoManeuver>(options.scene_index % 4);
  ground_tex = rng.U32();

  // Placement in the global frame.
  const double yaw = rng.Uniform(-M_PI, M_PI);
  const Eigen::Vector3d offset(rng.Uniform(300, 1700), rng.Uniform(300, 1700),
                               0.0);
  *global_from_street = Rigid3d(
      Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ())),
      offset);

  // Ego profile and intersection position.
  const double jitter = rng.Uniform(0, 5);
  PlanEgo(options, jitter);
  // Keep the stop-and-wait ego consistent with a far intersection for very
  // short scenes.
  AddVehicles(options.duration_s, &rng);
  TimeCrossingCar(options.duration_s);
  AddStaticStructure(&rng);
}

void SyntheticWorld::Impl::PlanEgo(const SyntheticWorldOptions& options,
                                   double jitter) {
  const double D = options.duration_s;
  const double v = 8.0;
  switch (maneuver) {
    case EgoManeuver::kLaneChange: {
      ego_profile = SpeedProfile(v);
      lane_change_start = ego_profile.Pos(0.15 * D);
      xc = std::max(60.0, ego_profile.Pos(0.5 * D)) + jitter;
      break;
    }
    case EgoManeuver::kStraight: {
      ego_profile = SpeedProfile(v);
      ego_profile.Then(0.3 * D, 0.5).Then(2.0, 0.0);
      xc = std::max(60.0, ego_profile.Pos(0.5 * D)) + jitter;
      break;
    }
    case EgoManeuver::kLeftTurn: {
      const double t_arc = 0.45 * D;
      const double t_brake = std::max(0.0, t_arc - 2.5);
      ego_profile = SpeedProfile(v);
      ego_profile.Then(t_brake, -1.5).Then(2.0, 0.0);
      const double arc_time = M_PI / 2 * kTurnRadius / 5.0;
      ego_profile.Then(t_arc + arc_time + 0.2 - (t_brake + 2.0), 1.0)
          .Then(3.0, 0.0);
      turn_start =
          std::max(60.0 + kLaneWidth / 2 - kTurnRadius, ego_profile.Pos(t_arc));
      xc = turn_start + kTurnRadius - kLaneWidth / 2;
      break;
    }
    case EgoManeuver::kBrakeAndStop: {
      const double t_brake = std::max(0.5, 0.55 * D - 4.0);
      ego_profile = SpeedProfile(v);
      ego_profile.Then(t_brake, -2.0).Then(4.0, 0.0);
      if (options.reverse_after_stop) {
        ego_profile.Then(1.5, -1.0).Then(1.5, 0.0).Then(1.0, 1.0).Then(1.5,
                                                                       0.0);
      }
      xc = ego_profile.Pos(t_brake + 4.0) + kStopLineOffset + 0.25 + 3.9;
      break;
    }
  }
}

void SyntheticWorld::Impl::AddVehicles(double duration_s, Rng* rng) {
  const double D = duration_s;
  // Vehicles.
  auto jit = [&](double x) { return x * rng->Uniform(0.95, 1.05); };
  const Eigen::Vector3d car(1.9, 4.6, 1.6), truck(2.5, 8.0, 3.4),
      bus(2.9, 11.0, 3.3);
  const Eigen::Vector3f palette[] = {
      {0.75f, 0.1f, 0.1f},   {0.1f, 0.25f, 0.7f}, {0.85f, 0.85f, 0.82f},
      {0.15f, 0.15f, 0.17f}, {0.9f, 0.7f, 0.1f},  {0.2f, 0.55f, 0.3f},
      {0.55f, 0.55f, 0.6f},  {0.95f, 0.45f, 0.1f}};
  auto add = [&](const std::string& cat, const Eigen::Vector3d& size, int axis,
                 double off, int dir, double s0, SpeedProfile prof,
                 bool parked = false) {
    Track tr;
    tr.category = cat;
    tr.size_wlh = Eigen::Vector3d(jit(size[0]), jit(size[1]), jit(size[2]));
    tr.axis = axis;
    tr.offset = off;
    tr.dir = dir;
    tr.s0 = s0;
    tr.profile = prof;
    tr.parked = parked;
    tr.color = palette[rng->U32() % 8];
    tr.tex = rng->U32();
    vehicles.push_back(tr);
  };
  const double lane_r =
      -kRoadHalfWidth + kLaneWidth / 2;   // -5.25: right lane (+x traffic)
  const double lane_l = -kLaneWidth / 2;  // -1.75: left lane (+x traffic)
  // 0: lead car in the ego lane; 1: truck behind it (occluded by the car from
  // the ego).
  add("vehicle.car", car, 0, lane_l, 1, 14.0, SpeedProfile(9.5));
  add("vehicle.truck", truck, 0, lane_l, 1, 14.0 + 2.4 + 3.0 + 4.1,
      SpeedProfile(9.5));
  // 2: oncoming car passing the intersection at 0.2 D.
  add("vehicle.car", car, 0, -lane_l, -1, xc + 9.0 * 0.2 * D,
      SpeedProfile(9.0));
  // 3: car in the right lane that brakes to a stop at the stop line.
  {
    const double stop_center = xc - kStopLineOffset - 0.25 - 2.4;
    add("vehicle.car", car, 0, lane_r, 1, 26.0,
        CruiseThenStop(7.0, stop_center - 26.0, 1.5));
  }
  // 5 (added after 4): oncoming bus passing at 0.3 D.
  // 4: crossing car (cross street, heading -y), timed below.
  add("vehicle.car", car, 1, xc - kLaneWidth / 2, -1, 0.0, SpeedProfile(9.0));
  add("vehicle.bus.rigid", bus, 0, -lane_r, -1, xc + 7.0 * 0.3 * D,
      SpeedProfile(7.0));
  // 6: parked car in the cross street.
  add("vehicle.car", car, 1, xc + kRoadHalfWidth - 1.0, 1, 24.0,
      SpeedProfile(0.0), true);
}

void SyntheticWorld::Impl::TimeCrossingCar(double duration_s) {
  const double D = duration_s;
  // Time the crossing car so that it never overlaps the ego or another vehicle.
  const double target = maneuver == EgoManeuver::kBrakeAndStop
                            ? std::max(0.5, 0.55 * D - 4.0) + 5.0
                            : 0.3 * D;
  Track& cross = vehicles[4];
  double best_tc = target, best_score = kInf;
  for (double tc = -2.0; tc <= D + 2.0; tc += 0.05) {
    const double score = std::abs(tc - target);
    if (score >= best_score) continue;
    cross.s0 = 9.0 * tc;  // y(t) = s0 - 9 t = 0 at tc
    bool ok = true;
    for (double tau = tc - 3.0; tau <= tc + 3.0 && ok; tau += 0.1) {
      const Eigen::Vector3d pc = cross.Pose(tau);
      const Eigen::Vector3d pe = EgoStreetPose(tau);
      const Eigen::Vector3d ego_c(pe.x() + 1.4 * std::cos(pe.z()),
                                  pe.y() + 1.4 * std::sin(pe.z()), pe.z());
      if (RectsOverlap(pc, cross.size_wlh[1], cross.size_wlh[0], ego_c, 4.8,
                       1.9, 1.0))
        ok = false;
      for (size_t j = 0; j < vehicles.size() && ok; ++j) {
        if (j == 4) continue;
        if (RectsOverlap(pc, cross.size_wlh[1], cross.size_wlh[0],
                         vehicles[j].Pose(tau), vehicles[j].size_wlh[1],
                         vehicles[j].size_wlh[0], 1.0)) {
          ok = false;
        }
      }
    }
    if (ok) {
      best_score = score;
      best_tc = tc;
    }
  }
  cross.s0 = 9.0 * best_tc;
}

void SyntheticWorld::Impl::AddStaticStructure(Rng* rng) {
  // ---- Static structure ----
  const double x_min = -200, x_max = xc + 300, y_far = 300;
  const double kerb = kRoadHalfWidth, facade = kRoadHalfWidth + kSidewalkWidth;
  // Sidewalk blocks (their sides are the kerbs).
  for (int sx = 0; sx < 2; ++sx) {
    for (int sy = 0; sy < 2; ++sy) {
      const double x0 = sx ? xc + kerb : x_min, x1 = sx ? x_max : xc - kerb;
      const double y0 = sy ? kerb : -y_far, y1 = sy ? y_far : -kerb;
      Box b = Box::Aabb(x0, x1, y0, y1, 0, kKerbHeight, kSidewalk);
      b.tex = rng->U32();
      static_boxes.push_back(b);
    }
  }
  const Eigen::Vector3f wall_palette[] = {
      {0.78f, 0.72f, 0.62f}, {0.62f, 0.35f, 0.28f}, {0.7f, 0.7f, 0.72f},
      {0.85f, 0.8f, 0.7f},   {0.5f, 0.55f, 0.6f},   {0.72f, 0.55f, 0.4f},
      {0.9f, 0.88f, 0.85f},  {0.45f, 0.42f, 0.4f}};
  auto add_building = [&](double x0, double x1, double y0, double y1) {
    Box b = Box::Aabb(x0, x1, y0, y1, 0, rng->Uniform(6, 30),
                      rng->Uniform(0, 1) < 0.35 ? kBrickBuilding : kBuilding);
    b.tex = rng->U32();
    b.color = wall_palette[rng->U32() % 8];
    static_boxes.push_back(b);
  };
  // Facades along the main street (both sides, both sides of the intersection).
  for (int side = -1; side <= 1; side += 2) {
    for (int part = 0; part < 2; ++part) {
      double x = part ? xc + facade : x_min;
      const double end = part ? x_max : xc - facade;
      while (x < end - 4) {
        const double w = std::min(rng->Uniform(8, 22), end - x);
        const double setback = rng->Uniform(0, 1.5),
                     depth = rng->Uniform(10, 20);
        const double ya = side * (facade + setback),
                     yb = side * (facade + setback + depth);
        add_building(x, x + w, std::min(ya, yb), std::max(ya, yb));
        x += w + (rng->Uniform(0, 1) < 0.2 ? rng->Uniform(4, 7)
                                           : rng->Uniform(0, 2));
      }
    }
  }
  // Facades along the cross street.
  for (int sx = -1; sx <= 1; sx += 2) {
    for (int sy = -1; sy <= 1; sy += 2) {
      double y = facade + 23.0;
      while (y < y_far - 4) {
        const double w = std::min(rng->Uniform(8, 22), y_far - y);
        const double setback = rng->Uniform(0, 1.5),
                     depth = rng->Uniform(10, 20);
        const double xa = xc + sx * (facade + setback),
                     xb = xc + sx * (facade + setback + depth);
        const double ya = sy * y, yb = sy * (y + w);
        add_building(std::min(xa, xb), std::max(xa, xb), std::min(ya, yb),
                     std::max(ya, yb));
        y += w + rng->Uniform(0, 2.5);
      }
    }
  }
  // Light poles and planters on the sidewalks.
  auto add_pole = [&](double x, double y) {
    Box b = Box::Aabb(x - 0.12, x + 0.12, y - 0.12, y + 0.12, kKerbHeight, 7.0,
                      kPole);
    b.tex = rng->U32();
    static_boxes.push_back(b);
  };
  auto add_planter = [&](double x, double y) {
    Box b = Box::Aabb(x - 0.6, x + 0.6, y - 0.6, y + 0.6, kKerbHeight, 0.9,
                      kPlanter);
    b.tex = rng->U32();
    static_boxes.push_back(b);
  };
  for (double x = x_min + 6; x < x_max - 6; x += 20) {
    if (std::abs(x - xc) < facade + 1) continue;
    add_pole(x, -(kerb + 0.6));
    add_pole(x + 10, kerb + 0.6);
    if (rng->Uniform(0, 1) < 0.35) add_planter(x + 5, -(kerb + 2.2));
    if (rng->Uniform(0, 1) < 0.35) add_planter(x + 15, kerb + 2.2);
  }
  for (double y = facade + 4; y < y_far - 6; y += 20) {
    add_pole(xc - kerb - 0.6, y);
    add_pole(xc + kerb + 0.6, -y);
    add_pole(xc - kerb - 0.6, -y - 10);
    add_pole(xc + kerb + 0.6, y + 10);
  }
}

void SyntheticWorld::Impl::Sky(const Eigen::Vector3d& dir, float rgb[3]) {
  const double e = dir.z() / dir.norm();
  const float t = static_cast<float>(std::clamp(e * 2.5, 0.0, 1.0));
  const Eigen::Vector3f horizon(0.86f, 0.9f, 0.95f),
      zenith(0.36f, 0.56f, 0.88f);
  const Eigen::Vector3f c = Mix(horizon, zenith, std::sqrt(t));
  rgb[0] = c[0];
  rgb[1] = c[1];
  rgb[2] = c[2];
}

void SyntheticWorld::Impl::ShadeGround(const Eigen::Vector3d& p,
                                       float rgb[3],
                                       uint8_t* intensity) const {
  const double x = p.x(), y = p.y();
  const double ax = std::abs(y), ay = std::abs(x - xc);
  const bool main_road = ax < kRoadHalfWidth, cross_road = ay < kRoadHalfWidth;
  const double fine =
      Hash01(FloorInt(x * 25), FloorInt(y * 25), ground_tex) - 0.5;
  if (!main_road && !cross_road) {  // grass beyond the blocks
    const double n = ValueNoise(x * 0.8, y * 0.8, ground_tex + 7);
    rgb[0] = static_cast<float>(0.22 + 0.08 * n + 0.05 * fine);
    rgb[1] = static_cast<float>(0.42 + 0.1 * n + 0.05 * fine);
    rgb[2] = static_cast<float>(0.18 + 0.05 * n);
    *intensity = 25;
    return;
  }
  const double g = 0.3 +
                   0.08 * (ValueNoise(x * 0.7, y * 0.7, ground_tex) - 0.5) +
                   0.06 * fine;
  int mark = 0;  // 1 white, 2 yellow
  auto lines = [&](double along, double across, double dist_to_intersection,
                   bool positive_side) {
    // along: coordinate along the road; across: signed offset from the road
    // centre line.
    const double a = std::abs(across);
    if (dist_to_intersection < kRoadHalfWidth) return;
    if (a > 0.08 && a < 0.2) mark = 2;
    if (a > 3.44 && a < 3.56 && Frac(along / 9.0) < 1.0 / 3.0) mark = 1;
    if (dist_to_intersection > kStopLineOffset - 0.25 &&
        dist_to_intersection < kStopLineOffset + 0.25 && positive_side &&
        a < kRoadHalfWidth) {
      mark = 1;
    }
    if (dist_to_intersection > 7.2 && dist_to_intersection < 8.8 && a < 6.5 &&
        Frac((across + 7.0) / 1.0) < 0.5) {
      mark = 1;
    }
  };
  if (main_road && !cross_road) {
    // +x traffic (y < 0) stops before the intersection (x < xc); -x traffic (y
    // > 0) after it.
    lines(x, y, ay, (x < xc) == (y < 0));
  } else if (cross_road && !main_road) {
    const double across = x - xc;
    lines(y, across, ax, (y < 0) == (across > 0));
  }
  if (mark == 0) {
    rgb[0] = rgb[1] = static_cast<float>(g);
    rgb[2] = static_cast<float>(g * 1.03);
    *intensity = static_cast<uint8_t>(10 + 8 * (fine + 0.5));
  } else if (mark == 1) {
    const float w = static_cast<float>(0.86 + 0.05 * fine);
    rgb[0] = rgb[1] = rgb[2] = w;
    *intensity = 160;
  } else {
    rgb[0] = static_cast<float>(0.88 + 0.04 * fine);
    rgb[1] = static_cast<float>(0.7 + 0.04 * fine);
    rgb[2] = 0.18f;
    *intensity = 140;
  }
}

void SyntheticWorld::Impl::Shade(const Box* box,
                                 int face,
                                 const Eigen::Vector3d& p,
                                 const Eigen::Vector3d& dir,
                                 float rgb[3],
                                 uint8_t* intensity) const {
  if (box == nullptr) {
    ShadeGround(p, rgb, intensity);
    const double lambert = sun.z();
    for (int k = 0; k < 3; ++k)
      rgb[k] *= static_cast<float>(0.6 + 0.4 * lambert);
    return;
  }
  const Box& b = *box;
  const Eigen::Vector3d l = b.ToLocal(p);
  // Local normal and its street-frame version.
  Eigen::Vector3d n_local = Eigen::Vector3d::Zero();
  n_local[face / 2] = (face % 2) ? 1.0 : -1.0;
  const Eigen::Vector3d n(b.c * n_local.x() - b.s * n_local.y(),
                          b.s * n_local.x() + b.c * n_local.y(), n_local.z());
  // Coordinate along the face (horizontal) for vertical faces.
  const double a = (face / 2 == 0) ? l.y() + b.hy : l.x() + b.hx;
  const double z = l.z();
  Eigen::Vector3f c = b.color;
  double refl = 40;
  const double fine = Hash01(FloorInt(a * 30), FloorInt(z * 30), b.tex) - 0.5;
  switch (b.material) {
    case kSidewalk: {
      if (face == 5) {
        const double tx = p.x() / 0.6, ty = p.y() / 0.6;
        const bool grout = Frac(tx) < 0.05 || Frac(ty) < 0.05;
        const double tile = Hash01(FloorInt(tx), FloorInt(ty), b.tex);
        const float v =
            static_cast<float>(grout ? 0.42 : 0.6 + 0.12 * tile + 0.05 * fine);
        c = Eigen::Vector3f(v, v * 0.98f, v * 0.95f);
      } else {
        const float v = static_cast<float>(0.72 + 0.08 * fine);
        c = Eigen::Vector3f(v, v, v);
      }
      refl = 35;
      break;
    }
    case kBuilding:
    case kBrickBuilding: {
      if (face == 5) {
        const float v = static_cast<float>(
            0.38 + 0.1 * ValueNoise(p.x(), p.y(), b.tex) + 0.04 * fine);
        c = Eigen::Vector3f(v, v, v);
        break;
      }
      const double fz = Frac(z / 3.2) * 3.2, fa = Frac(a / 2.6) * 2.6;
      const bool window = z > 0.9 && fz > 0.9 && fz < 2.4 && fa > 0.6 &&
                          fa < 1.9 && z < b.z1 - 0.8;
      if (window) {
        const double r = ValueNoise(a * 0.7, z * 0.7, b.tex + 3);
        c = Eigen::Vector3f(0.1f, 0.14f, 0.2f) +
            Eigen::Vector3f::Constant(static_cast<float>(0.25 * r));
        refl = 6;
      } else if (b.material == kBrickBuilding) {
        const int row = FloorInt(z / 0.075);
        const double off = (row & 1) ? 0.11 : 0.0;
        const bool mortar =
            Frac(z / 0.075) < 0.16 || Frac((a + off) / 0.22) < 0.07;
        if (mortar) {
          c = Eigen::Vector3f(0.72f, 0.7f, 0.66f);
        } else {
          c *= static_cast<float>(
              0.8 + 0.35 * Hash01(row, FloorInt((a + off) / 0.22), b.tex));
        }
      } else {
        c *= static_cast<float>(
            0.85 + 0.25 * ValueNoise(a * 1.5, z * 1.5, b.tex) + 0.08 * fine);
      }
      break;
    }
    case kPole: {
      const float v = static_cast<float>(0.33 + 0.05 * fine);
      c = Eigen::Vector3f(v, v, v * 1.05f);
      refl = 120;
      break;
    }
    case kPlanter: {
      if (face == 5) {
        const double r = ValueNoise(p.x() * 6, p.y() * 6, b.tex);
        c = Eigen::Vector3f(0.15f, static_cast<float>(0.35 + 0.25 * r), 0.12f);
      } else {
        const float v = static_cast<float>(0.55 + 0.08 * fine);
        c = Eigen::Vector3f(v, v * 0.95f, v * 0.9f);
      }
      break;
    }
    case kVehicleBody: {
      const double h = b.z1, len = 2 * b.hx, wid = 2 * b.hy;
      const double lx = l.x(), ly = l.y();
      refl = 60;
      c *= static_cast<float>(0.95 + 0.1 * fine);
      if (face == 5) {
        c *= 0.85f;
      } else if (face / 2 == 1) {  // sides
        const double wr = std::min(0.34, 0.3 * h);
        for (double cxw : {-0.32 * len, 0.32 * len}) {
          if ((lx - cxw) * (lx - cxw) + (z - wr) * (z - wr) < wr * wr) {
            c = Eigen::Vector3f(0.06f, 0.06f, 0.06f);
            refl = 15;
          }
        }
        if (z > 0.55 * h && z < 0.9 * h && std::abs(lx) < 0.38 * len) {
          c = Eigen::Vector3f(0.12f, 0.16f, 0.22f) *
              static_cast<float>(1.0 + 0.6 * (fine + 0.5));
          refl = 10;
        }
      } else if (face / 2 == 0) {  // front (+x) / back (-x)
        const double ay = std::abs(ly);
        if (z > 0.55 * h && z < 0.9 * h && ay < 0.42 * wid) {
          c = Eigen::Vector3f(0.12f, 0.16f, 0.22f);
          refl = 10;
        } else if (z > 0.35 * h && z < 0.45 * h && ay > 0.28 * wid &&
                   ay < 0.45 * wid) {
          c = face == 1 ? Eigen::Vector3f(0.95f, 0.95f, 0.85f)
                        : Eigen::Vector3f(0.8f, 0.1f, 0.08f);
          refl = 200;
        } else if (z > 0.18 * h && z < 0.28 * h && ay < 0.13 * wid) {
          c = Eigen::Vector3f(0.92f, 0.92f, 0.9f);
          refl = 220;
        }
      }
      break;
    }
    default:
      break;
  }
  const double lambert = std::max(0.0, n.dot(sun));
  const float shade = static_cast<float>(0.55 + 0.45 * lambert);
  rgb[0] = c[0] * shade;
  rgb[1] = c[1] * shade;
  rgb[2] = c[2] * shade;
  const double cos_inc = std::abs(n.dot(dir)) / dir.norm();
  *intensity = static_cast<uint8_t>(
      std::clamp(refl * (0.4 + 0.6 * cos_inc), 0.0, 255.0));
}

// ---------------------------------------------------------------------------------------------
SyntheticWorld::SyntheticWorld(const SyntheticWorldOptions& options)
    : options_(options), impl_(std::make_unique<Impl>()) {
  const std::string err = options.Validate();
  GEODRIVE_CHECK_INPUT(err.empty(), "synthetic world options: ", err);
  impl_->Generate(options, &global_from_street_);
  maneuver_ = impl_->maneuver;
  intersection_x_ = impl_->xc;
}

SyntheticWorld::~SyntheticWorld() = default;

Rigid3d SyntheticWorld::GlobalFromEgo(double t) const {
  const Eigen::Vector3d pose = impl_->EgoStreetPose(t);
  const Rigid3d street_from_ego(
      Eigen::Quaterniond(Eigen::AngleAxisd(pose.z(), Eigen::Vector3d::UnitZ())),
      Eigen::Vector3d(pose.x(), pose.y(), 0.0));
  Rigid3d g = global_from_street_ * street_from_ego;
  g.translation.z() = 0.0;
  g.rotation.normalize();
  return g;
}

double SyntheticWorld::EgoSpeed(double t) const {
  return impl_->ego_profile.Vel(t);
}

int SyntheticWorld::NumVehicles() const {
  return static_cast<int>(impl_->vehicles.size());
}

VehicleBox SyntheticWorld::Vehicle(int id, double t) const {
  const Track& tr = impl_->vehicles.at(id);
  const Eigen::Vector3d pose = tr.Pose(t);
  VehicleBox vb;
  vb.id = id;
  vb.category = tr.category;
  vb.size_wlh = tr.size_wlh;
  vb.speed = tr.Speed(t);
  vb.moving = std::abs(vb.speed) > 0.1;
  vb.attribute = tr.parked ? "vehicle.parked"
                           : (vb.moving ? "vehicle.moving" : "vehicle.stopped");
  const Eigen::Vector3d center_street(pose.x(), pose.y(), tr.size_wlh[2] / 2);
  vb.center = global_from_street_ * center_street;
  vb.rotation =
      (global_from_street_.rotation * Eigen::Quaterniond(Eigen::AngleAxisd(
                                          pose.z(), Eigen::Vector3d::UnitZ())))
          .normalized();
  return vb;
}

std::vector<VehicleBox> SyntheticWorld::Vehicles(double t) const {
  std::vector<VehicleBox> out;
  for (int i = 0; i < NumVehicles(); ++i) out.push_back(Vehicle(i, t));
  return out;
}

RenderedView SyntheticWorld::RenderCamera(const PinholeCamera& camera,
                                          const Rigid3d& global_from_cam,
                                          double t) const {
  camera.Check("synthetic camera");
  const int W = camera.width, H = camera.height;
  const Rigid3d street_from_cam =
      global_from_street_.Inverse() * global_from_cam;
  const Eigen::Matrix3d R = street_from_cam.rotation.toRotationMatrix();
  const Eigen::Vector3d o = street_from_cam.translation;
  const Rigid3d cam_from_street = street_from_cam.Inverse();
  const Eigen::Matrix3d Rc = cam_from_street.rotation.toRotationMatrix();
  const Eigen::Vector3d tc = cam_from_street.translation;
  const double max_range = 1000.0;

  std::vector<Box> boxes = impl_->static_boxes;
  impl_->AppendVehicles(t, &boxes);

  // Bin boxes into 16x16 tiles by their exact near-clipped projected bounding
  // rectangles.
  constexpr int kTile = 16;
  const int tiles_x = (W + kTile - 1) / kTile,
            tiles_y = (H + kTile - 1) / kTile;
  struct Span {
    int id, tx0, tx1, ty0, ty1;
  };
  std::vector<Span> spans;
  spans.reserve(boxes.size());
  const double near = 1e-3;
  for (int i = 0; i < static_cast<int>(boxes.size()); ++i) {
    Box& b = boxes[i];
    b.min_dist = b.DistanceTo(o);
    if (b.min_dist > max_range) continue;
    Eigen::Vector3d cc[8];
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3d ps =
          b.ToStreet((k & 1) ? b.hx : -b.hx, (k & 2) ? b.hy : -b.hy,
                     (k & 4) ? b.z1 : b.z0);
      cc[k] = Rc * ps + tc;
    }
    double u0 = kInf, u1 = -kInf, v0 = kInf, v1 = -kInf;
    bool any = false;
    auto take = [&](const Eigen::Vector3d& q) {
      const double u = camera.fx * q.x() / q.z() + camera.cx;
      const double v = camera.fy * q.y() / q.z() + camera.cy;
      u0 = std::min(u0, u), u1 = std::max(u1, u), v0 = std::min(v0, v),
      v1 = std::max(v1, v);
      any = true;
    };
    for (int k = 0; k < 8; ++k) {
      if (cc[k].z() > near) take(cc[k]);
      for (int bit = 1; bit < 8; bit <<= 1) {
        const int m = k | bit;
        if (m == k) continue;
        const double za = cc[k].z(), zb = cc[m].z();
        if ((za > near) != (zb > near)) {
          const double s = (near - za) / (zb - za);
          take(cc[k] + s * (cc[m] - cc[k]));
        }
      }
    }
    if (!any) continue;
    const double lim = 1e7;
    u0 = std::clamp(u0, -lim, lim), u1 = std::clamp(u1, -lim, lim);
    v0 = std::clamp(v0, -lim, lim), v1 = std::clamp(v1, -lim, lim);
    const int tx0 = std::max(0, static_cast<int>(std::floor((u0 - 1) / kTile)));
    const int tx1 =
        std::min(tiles_x - 1, static_cast<int>(std::floor((u1 + 1) / kTile)));
    const int ty0 = std::max(0, static_cast<int>(std::floor((v0 - 1) / kTile)));
    const int ty1 =
        std::min(tiles_y - 1, static_cast<int>(std::floor((v1 + 1) / kTile)));
    if (tx0 > tx1 || ty0 > ty1) continue;
    spans.push_back({i, tx0, tx1, ty0, ty1});
  }
  std::stable_sort(spans.begin(), spans.end(),
                   [&](const Span& a, const Span& b) {
                     return boxes[a.id].min_dist < boxes[b.id].min_dist;
                   });
  std::vector<int> counts(tiles_x * tiles_y + 1, 0);
  for (const Span& s : spans)
    for (int ty = s.ty0; ty <= s.ty1; ++ty)
      for (int tx = s.tx0; tx <= s.tx1; ++tx) ++counts[ty * tiles_x + tx + 1];
  for (size_t k = 1; k < counts.size(); ++k) counts[k] += counts[k - 1];
  std::vector<int> lists(counts.back());
  {
    std::vector<int> fill(counts.begin(), counts.end() - 1);
    for (const Span& s : spans)
      for (int ty = s.ty0; ty <= s.ty1; ++ty)
        for (int tx = s.tx0; tx <= s.tx1; ++tx)
          lists[fill[ty * tiles_x + tx]++] = s.id;
  }

  RenderedView view;
  view.rgb.create(H, W, CV_8UC3);
  view.depth.create(H, W, CV_32F);
  view.instance.create(H, W, CV_16U);
  const Eigen::Vector3d d00 =
      R * Eigen::Vector3d(-camera.cx / camera.fx, -camera.cy / camera.fy, 1);
  const Eigen::Vector3d du = R.col(0) / camera.fx, dv = R.col(1) / camera.fy;

#pragma omp parallel for schedule(dynamic, 1)
  for (int ty = 0; ty < tiles_y; ++ty) {
    for (int tx = 0; tx < tiles_x; ++tx) {
      const int* ids = lists.data() + counts[ty * tiles_x + tx];
      const int n = counts[ty * tiles_x + tx + 1] - counts[ty * tiles_x + tx];
      const int v_end = std::min(H, (ty + 1) * kTile),
                u_end = std::min(W, (tx + 1) * kTile);
      for (int v = ty * kTile; v < v_end; ++v) {
        uint8_t* rgb_row = view.rgb.ptr<uint8_t>(v);
        float* depth_row = view.depth.ptr<float>(v);
        uint16_t* inst_row = view.instance.ptr<uint16_t>(v);
        for (int u = tx * kTile; u < u_end; ++u) {
          const Eigen::Vector3d d = d00 + u * du + v * dv;
          const double dn = d.norm();
          int hit, face = 0;
          const double th = impl_->Trace(boxes, ids, n, o, d, dn,
                                         max_range / dn, &hit, &face);
          float c[3];
          uint8_t inten;
          if (hit == -2) {
            Impl::Sky(d, c);
            depth_row[u] = 0.f;
            inst_row[u] = kSkyInstance;
          } else {
            const Eigen::Vector3d p = o + th * d;
            const Box* b = hit >= 0 ? &boxes[hit] : nullptr;
            impl_->Shade(b, face, p, d, c, &inten);
            depth_row[u] =
                static_cast<float>(th);  // d has unit z in the camera frame
            inst_row[u] = b ? b->instance : kStaticInstance;
          }
          for (int k = 0; k < 3; ++k) {
            rgb_row[3 * u + k] = static_cast<uint8_t>(
                std::clamp(c[k] * 255.0f + 0.5f, 0.0f, 255.0f));
          }
        }
      }
    }
  }
  return view;
}

RayHit SyntheticWorld::CastRay(const Eigen::Vector3d& origin,
                               const Eigen::Vector3d& direction,
                               double t,
                               double max_range) const {
  const Rigid3d street_from_global = global_from_street_.Inverse();
  const Eigen::Vector3d o = street_from_global * origin;
  const Eigen::Vector3d d =
      (street_from_global.rotation * direction).normalized();
  std::vector<Box> boxes = impl_->static_boxes;
  impl_->AppendVehicles(t, &boxes);
  std::vector<int> ids(boxes.size());
  for (size_t i = 0; i < boxes.size(); ++i) {
    ids[i] = static_cast<int>(i);
    boxes[i].min_dist = boxes[i].DistanceTo(o);
  }
  std::sort(ids.begin(), ids.end(), [&](int a, int b) {
    return boxes[a].min_dist < boxes[b].min_dist;
  });
  int hit, face = 0;
  const double th =
      impl_->Trace(boxes, ids.data(), static_cast<int>(ids.size()), o, d, 1.0,
                   max_range, &hit, &face);
  RayHit out;
  if (hit == -2) return out;
  out.range = th;
  float c[3];
  const Box* b = hit >= 0 ? &boxes[hit] : nullptr;
  impl_->Shade(b, face, o + th * d, d, c, &out.intensity);
  out.instance = b ? b->instance : kStaticInstance;
  return out;
}

double SyntheticWorld::CameraDepthAt(const PinholeCamera& camera,
                                     const Rigid3d& global_from_cam,
                                     double t,
                                     const Eigen::Vector2d& pixel,
                                     uint16_t* instance) const {
  const Eigen::Vector3d d_cam((pixel.x() - camera.cx) / camera.fx,
                              (pixel.y() - camera.cy) / camera.fy, 1.0);
  const RayHit hit =
      CastRay(global_from_cam.translation, global_from_cam.rotation * d_cam, t,
              1000.0 * d_cam.norm());
  if (instance) *instance = hit.instance;
  if (hit.range <= 0) return 0.0;
  return hit.range / d_cam.norm();
}

LidarSweep SyntheticWorld::CastLidar(const Rigid3d& global_from_lidar,
                                     double t,
                                     const LidarOptions& lidar) const {
  GEODRIVE_CHECK_INPUT(lidar.num_rings > 0 && lidar.num_rings <= 256 &&
                           lidar.azimuth_steps > 0 &&
                           lidar.azimuth_steps <= 100000 &&
                           lidar.max_range_m > lidar.min_range_m,
                       "synthetic lidar: invalid options");
  const Rigid3d street_from_lidar =
      global_from_street_.Inverse() * global_from_lidar;
  const Eigen::Matrix3d R = street_from_lidar.rotation.toRotationMatrix();
  const Eigen::Vector3d o = street_from_lidar.translation;
  std::vector<Box> boxes = impl_->static_boxes;
  impl_->AppendVehicles(t, &boxes);

  // Azimuth bins (street frame) holding the boxes whose footprint spans them.
  constexpr int kBins = 720;
  const double bin_scale = kBins / (2 * M_PI);
  std::vector<std::vector<int>> bins(kBins);
  std::vector<int> order;
  for (int i = 0; i < static_cast<int>(boxes.size()); ++i) {
    boxes[i].min_dist = boxes[i].DistanceTo(o);
    if (boxes[i].min_dist <= lidar.max_range_m) order.push_back(i);
  }
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return boxes[a].min_dist < boxes[b].min_dist;
  });
  for (int i : order) {
    const Box& b = boxes[i];
    const Eigen::Vector3d l = b.ToLocal(o);
    int lo_bin = 0, hi_bin = kBins - 1;
    if (!(std::abs(l.x()) <= b.hx + 1e-6 && std::abs(l.y()) <= b.hy + 1e-6)) {
      const Eigen::Vector3d c0 = b.ToStreet(-b.hx, -b.hy, 0) - o;
      const double ref = std::atan2(c0.y(), c0.x());
      double dmin = 0, dmax = 0;
      for (int k = 1; k < 4; ++k) {
        const Eigen::Vector3d ck =
            b.ToStreet((k & 1) ? b.hx : -b.hx, (k & 2) ? b.hy : -b.hy, 0) - o;
        double da = std::atan2(ck.y(), ck.x()) - ref;
        while (da > M_PI) da -= 2 * M_PI;
        while (da < -M_PI) da += 2 * M_PI;
        dmin = std::min(dmin, da), dmax = std::max(dmax, da);
      }
      lo_bin =
          static_cast<int>(std::floor((ref + dmin + M_PI) * bin_scale)) - 1;
      hi_bin =
          static_cast<int>(std::floor((ref + dmax + M_PI) * bin_scale)) + 1;
    }
    for (int k = lo_bin; k <= hi_bin; ++k)
      bins[((k % kBins) + kBins) % kBins].push_back(i);
  }

  const int nr = lidar.num_rings, na = lidar.azimuth_steps;
  std::vector<RayHit> hits(static_cast<size_t>(nr) * na);
  std::vector<Eigen::Vector3d> dirs_sensor(static_cast<size_t>(nr) * na);
#pragma omp parallel for schedule(dynamic, 16)
  for (int a = 0; a < na; ++a) {
    const double az = 2 * M_PI * a / na;
    for (int r = 0; r < nr; ++r) {
      const double el =
          (lidar.min_elevation_deg +
           (nr > 1 ? (lidar.max_elevation_deg - lidar.min_elevation_deg) * r /
                         (nr - 1)
                   : 0.0)) *
          M_PI / 180.0;
      const Eigen::Vector3d ds(std::cos(el) * std::cos(az),
                               std::cos(el) * std::sin(az), std::sin(el));
      const Eigen::Vector3d d = R * ds;
      int bin = static_cast<int>(
          std::floor((std::atan2(d.y(), d.x()) + M_PI) * bin_scale));
      bin = std::clamp(bin, 0, kBins - 1);
      const std::vector<int>& ids = bins[bin];
      int hit, face = 0;
      const double th =
          impl_->Trace(boxes, ids.data(), static_cast<int>(ids.size()), o, d,
                       1.0, lidar.max_range_m, &hit, &face);
      RayHit& out = hits[static_cast<size_t>(a) * nr + r];
      dirs_sensor[static_cast<size_t>(a) * nr + r] = ds;
      if (hit == -2 || th < lidar.min_range_m) continue;
      out.range = th;
      float c[3];
      const Box* b = hit >= 0 ? &boxes[hit] : nullptr;
      impl_->Shade(b, face, o + th * d, d, c, &out.intensity);
      out.instance = b ? b->instance : kStaticInstance;
    }
  }
  LidarSweep sweep;
  for (int a = 0; a < na; ++a) {
    for (int r = 0; r < nr; ++r) {
      const size_t k = static_cast<size_t>(a) * nr + r;
      if (hits[k].range <= 0) continue;
      sweep.points.push_back((hits[k].range * dirs_sensor[k]).cast<float>());
      sweep.intensity.push_back(hits[k].intensity);
      sweep.ring.push_back(static_cast<float>(r));
      sweep.instance.push_back(hits[k].instance);
    }
  }
  return sweep;
}

}  // namespace geodrive

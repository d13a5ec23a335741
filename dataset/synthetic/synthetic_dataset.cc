#include "dataset/synthetic/synthetic_dataset.h"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>
#include <utility>

#include "dataset/clip_id.h"
#include "geometry/image_io.h"
#include "geometry/npy.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// Deterministic tokens: 32 hex digits from (seed, kind, a, b, c).
enum TokenKind : uint64_t {
  kTokLog = 1,
  kTokScene,
  kTokSample,
  kTokSampleData,
  kTokEgoPose,
  kTokCalib,
  kTokSensor,
  kTokInstance,
  kTokAnnotation,
  kTokMap,
  kTokCategory,
  kTokAttribute,
};

uint64_t Mix64(uint64_t z) {
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

struct Tokens {
  uint64_t seed;
  std::string Make(uint64_t kind,
                   uint64_t a = 0,
                   uint64_t b = 0,
                   uint64_t c = 0) const {
    uint64_t h1 = Mix64(seed ^ Mix64(kind * 0x100000001B3ull));
    h1 = Mix64(h1 ^ a);
    h1 = Mix64(h1 ^ (b * 0xC2B2AE3D27D4EB4Full));
    h1 = Mix64(h1 ^ (c * 0x165667B19E3779F9ull));
    const uint64_t h2 = Mix64(h1 ^ 0xA0761D6478BD642Full);
    static const char* hex = "0123456789abcdef";
    std::string s(32, '0');
    for (int i = 0; i < 16; ++i) {
      s[i] = hex[(h1 >> (60 - 4 * i)) & 15];
      s[16 + i] = hex[(h2 >> (60 - 4 * i)) & 15];
    }
    return s;
  }
};

// Counter-based uniform/normal randoms for per-pixel noise (independent of
// evaluation order).
double U01(uint64_t key) {
  return (Mix64(key) >> 11) * (1.0 / 9007199254740992.0);
}
double Normal(uint64_t key) {
  const double u1 = std::max(U01(key), 1e-300),
               u2 = U01(key ^ 0x5851F42D4C957F2Dull);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2 * M_PI * u2);
}

// ---------------------------------------------------------------------------------------------
// Streaming writer of one nuScenes table: a JSON array of records, one key per
// line (the layout of the official files).
class JsonTableWriter {
 public:
  explicit JsonTableWriter(const std::string& path) : path_(path) {
    file_ = std::fopen(path.c_str(), "wb");
    if (!file_) ThrowInputError(path, "cannot open for writing");
    buf_.reserve(1 << 20);
    buf_ = "[";
  }
  ~JsonTableWriter() {
    if (file_) std::fclose(file_);
  }
  void Begin() {
    buf_ += first_ ? "\n{" : ",\n{";
    first_ = false;
    first_field_ = true;
  }
  void End() {
    buf_ += "\n}";
    ++rows_;
    if (buf_.size() > (1 << 20) - 4096) Flush();
  }
  void Str(const char* key, const std::string& value) {
    Key(key);
    buf_ += '"';
    for (char c : value) {
      if (c == '"' || c == '\\') buf_ += '\\';
      buf_ += c;
    }
    buf_ += '"';
  }
  void Int(const char* key, int64_t v) {
    Key(key);
    char tmp[32];
    buf_.append(tmp, std::to_chars(tmp, tmp + sizeof(tmp), v).ptr);
  }
  void Bool(const char* key, bool v) {
    Key(key);
    buf_ += v ? "true" : "false";
  }
  void Num(const char* key, double v) {
    Key(key);
    AppendDouble(v);
  }
  void Nums(const char* key, const double* v, int n) {
    Key(key);
    buf_ += '[';
    for (int i = 0; i < n; ++i) {
      if (i) buf_ += ", ";
      AppendDouble(v[i]);
    }
    buf_ += ']';
  }
  void Strs(const char* key, const std::vector<std::string>& v) {
    Key(key);
    buf_ += '[';
    for (size_t i = 0; i < v.size(); ++i) {
      if (i) buf_ += ", ";
      buf_ += '"' + v[i] + '"';
    }
    buf_ += ']';
  }
  void Raw(const char* key, const std::string& raw) {
    Key(key);
    buf_ += raw;
  }
  int64_t rows() const { return rows_; }
  void Close() {
    buf_ += first_ ? "]\n" : "\n]\n";
    Flush();
    const bool bad = std::fclose(file_) != 0;
    file_ = nullptr;
    if (bad) ThrowInputError(path_, "write failed");
  }

 private:
  void Key(const char* key) {
    buf_ += first_field_ ? "\n\"" : ",\n\"";
    buf_ += key;
    buf_ += "\": ";
    first_field_ = false;
  }
  void AppendDouble(double v) {
    if (v == 0.0) v = 0.0;  // no "-0"
    char tmp[64];
    buf_.append(tmp, std::to_chars(tmp, tmp + sizeof(tmp), v).ptr);
  }
  void Flush() {
    if (!buf_.empty() &&
        std::fwrite(buf_.data(), 1, buf_.size(), file_) != buf_.size()) {
      ThrowInputError(path_, "write failed (disk full?)");
    }
    buf_.clear();
  }
  std::string path_;
  std::FILE* file_ = nullptr;
  std::string buf_;
  bool first_ = true, first_field_ = true;
  int64_t rows_ = 0;
};

// Python repr() of a float (MonST3R writes pred_traj.txt with str()).
std::string PyFloat(double v) {
  if (v == 0.0) return std::signbit(v) ? "-0.0" : "0.0";
  char buf[64];
  const auto res =
      std::to_chars(buf, buf + sizeof(buf), v, std::chars_format::scientific);
  const std::string sci(buf, res.ptr);  // e.g. "-1.2345e+02"
  const size_t epos = sci.find('e');
  const int exp = std::stoi(sci.substr(epos + 1));
  std::string mant = sci.substr(0, epos);
  const bool neg = mant[0] == '-';
  if (neg) mant.erase(0, 1);
  std::string digits;
  for (char c : mant)
    if (c != '.') digits += c;
  std::string out;
  if (exp >= -5 && exp < 16) {
    if (exp >= 0) {
      if (static_cast<int>(digits.size()) <= exp + 1) {
        out = digits + std::string(exp + 1 - digits.size(), '0') + ".0";
      } else {
        out = digits.substr(0, exp + 1) + "." + digits.substr(exp + 1);
      }
    } else {
      out = "0." + std::string(-exp - 1, '0') + digits;
    }
    // Python switches to exponent notation below 1e-4.
    if (exp < -4) out.clear();
  }
  if (out.empty()) {
    out = digits.substr(0, 1);
    if (digits.size() > 1) out += "." + digits.substr(1);
    char e[16];
    std::snprintf(e, sizeof(e), "e%c%02d", exp < 0 ? '-' : '+', std::abs(exp));
    out += e;
  }
  return neg ? "-" + out : out;
}

std::string Fmt6(double v) {
  char b[64];
  std::snprintf(b, sizeof(b), "%.6f", v);
  return b;
}

void WriteBytes(const std::string& path, const void* data, size_t n) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) ThrowInputError(path, "cannot open for writing");
  const bool ok = std::fwrite(data, 1, n, f) == n;
  if (std::fclose(f) != 0 || !ok) ThrowInputError(path, "write failed");
}

void WriteText(const std::string& path, const std::string& text) {
  WriteBytes(path, text.data(), text.size());
}

void MakeDirs(const fs::path& p) {
  std::error_code ec;
  fs::create_directories(p, ec);
  if (ec)
    ThrowInputError(p.string(), "cannot create directory: ", ec.message());
}

std::string Ts16(int64_t us) {
  char b[32];
  std::snprintf(b, sizeof(b), "%016lld", static_cast<long long>(us));
  return b;
}

const char* kLocations[] = {"boston-seaport", "singapore-onenorth"};

const std::vector<std::string>& Categories() {
  static const std::vector<std::string> c = {
      "animal",
      "human.pedestrian.adult",
      "human.pedestrian.child",
      "human.pedestrian.construction_worker",
      "human.pedestrian.personal_mobility",
      "human.pedestrian.police_officer",
      "human.pedestrian.stroller",
      "human.pedestrian.wheelchair",
      "movable_object.barrier",
      "movable_object.debris",
      "movable_object.pushable_pullable",
      "movable_object.trafficcone",
      "static_object.bicycle_rack",
      "vehicle.bicycle",
      "vehicle.bus.bendy",
      "vehicle.bus.rigid",
      "vehicle.car",
      "vehicle.construction",
      "vehicle.emergency.ambulance",
      "vehicle.emergency.police",
      "vehicle.motorcycle",
      "vehicle.trailer",
      "vehicle.truck"};
  return c;
}
const std::vector<std::string>& Attributes() {
  static const std::vector<std::string> a = {
      "vehicle.moving",      "vehicle.stopped",
      "vehicle.parked",      "cycle.with_rider",
      "cycle.without_rider", "pedestrian.sitting_lying_down",
      "pedestrian.standing", "pedestrian.moving"};
  return a;
}
int IndexOf(const std::vector<std::string>& v, const std::string& s) {
  return static_cast<int>(std::find(v.begin(), v.end(), s) - v.begin());
}

int ChannelId(const std::string& ch) {
  return IndexOf(SyntheticChannels(), ch);
}
bool IsRadar(const std::string& ch) { return ch.rfind("RADAR_", 0) == 0; }

// Rate and per-channel time offset (µs) of a channel relative to the
// lidar/sample clock.
int RateHz(const std::string& ch) {
  if (IsCameraChannel(ch)) return kSyntheticCameraRateHz;
  if (IsRadar(ch)) return kSyntheticRadarRateHz;
  return kSyntheticLidarRateHz;
}
int64_t OffsetUs(const std::string& ch) {
  static const std::map<std::string, int64_t> off = {
      {"CAM_FRONT", 12000},       {"CAM_FRONT_RIGHT", 20500},
      {"CAM_BACK_RIGHT", 28000},  {"CAM_BACK", 37500},
      {"CAM_BACK_LEFT", 45000},   {"CAM_FRONT_LEFT", 4500},
      {"LIDAR_TOP", 0},           {"RADAR_FRONT", 7000},
      {"RADAR_FRONT_LEFT", 9000}, {"RADAR_FRONT_RIGHT", 11000},
      {"RADAR_BACK_LEFT", 13000}, {"RADAR_BACK_RIGHT", 15000}};
  return off.at(ch);
}

std::vector<std::string> WrittenChannels(const SyntheticDatasetOptions& o) {
  std::vector<std::string> out;
  for (const auto& ch : SyntheticChannels()) {
    const bool want = IsCameraChannel(ch)
                          ? std::find(o.cameras.begin(), o.cameras.end(), ch) !=
                                o.cameras.end()
                          : (ch == "LIDAR_TOP" || (IsRadar(ch) && o.radars));
    if (want) out.push_back(ch);
  }
  return out;
}

void Quat(const Eigen::Quaterniond& q, double out[4]) {
  Eigen::Quaterniond n = q.normalized();
  out[0] = n.w(), out[1] = n.x(), out[2] = n.y(), out[3] = n.z();
}

std::string SweepFilename(const std::string& log,
                          const std::string& ch,
                          int64_t us,
                          bool key) {
  const char* ext =
      IsCameraChannel(ch) ? ".jpg" : (IsRadar(ch) ? ".pcd" : ".pcd.bin");
  return std::string(key ? "samples/" : "sweeps/") + ch + "/" + log + "__" +
         ch + "__" + Ts16(us) + ext;
}

std::string LogName(uint64_t seed, int scene) {
  char b[64];
  std::snprintf(b, sizeof(b), "synth-%llu-%04d",
                static_cast<unsigned long long>(seed), scene);
  return b;
}

// Rotation with a small random axis-angle perturbation of `sigma_deg`.
Eigen::Quaterniond Perturb(const Eigen::Quaterniond& q,
                           double sigma_deg,
                           uint64_t key) {
  if (sigma_deg <= 0) return q;
  const Eigen::Vector3d aa(Normal(key + 1), Normal(key + 2), Normal(key + 3));
  return (q * QuaternionFromAngleAxis(aa * sigma_deg * M_PI / 180.0))
      .normalized();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
const std::vector<std::string>& SyntheticChannels() {
  static const std::vector<std::string> c = {
      "CAM_FRONT",         "CAM_FRONT_RIGHT", "CAM_BACK_RIGHT",
      "CAM_BACK",          "CAM_BACK_LEFT",   "CAM_FRONT_LEFT",
      "LIDAR_TOP",         "RADAR_FRONT",     "RADAR_FRONT_LEFT",
      "RADAR_FRONT_RIGHT", "RADAR_BACK_LEFT", "RADAR_BACK_RIGHT"};
  return c;
}

bool IsCameraChannel(const std::string& ch) { return ch.rfind("CAM_", 0) == 0; }

Rigid3d SyntheticEgoFromSensor(const std::string& channel) {
  auto rz = [](double deg) {
    return Eigen::Quaterniond(
        Eigen::AngleAxisd(deg * M_PI / 180.0, Eigen::Vector3d::UnitZ()));
  };
  if (IsCameraChannel(channel)) {
    // CAM_FRONT of nuScenes (mmdet3d fixture), normalised; the others are yawed
    // copies.
    const Eigen::Quaterniond front =
        QuaternionFromWxyz(0.4998015430569128, -0.5030316162024876,
                           0.4997798114386805, -0.49737083824542755)
            .normalized();
    static const std::map<std::string, std::pair<double, Eigen::Vector3d>>
        cams = {{"CAM_FRONT",
                 {0.0, {1.70079118954, 0.0159456324149, 1.51095763913}}},
                {"CAM_FRONT_RIGHT",
                 {-55.0, {1.5508477543, -0.493404796419, 1.49574800619}}},
                {"CAM_BACK_RIGHT",
                 {-110.0, {1.0148780988, -0.480568219723, 1.56239545128}}},
                {"CAM_BACK",
                 {180.0, {0.0283260309358, 0.00345136761476, 1.57910346144}}},
                {"CAM_BACK_LEFT",
                 {110.0, {1.03569100218, 0.484795032713, 1.59097014818}}},
                {"CAM_FRONT_LEFT",
                 {55.0, {1.52387798135, 0.494631336551, 1.50932822144}}}};
    const auto& c = cams.at(channel);
    return Rigid3d((rz(c.first) * front).normalized(), c.second);
  }
  if (channel == "LIDAR_TOP") {
    return Rigid3d(QuaternionFromWxyz(0.7077955119163518, -0.006492242056004365,
                                      0.010646214713995808, -0.7063073142877817)
                       .normalized(),
                   Eigen::Vector3d(0.943713, 0.0, 1.84023));
  }
  static const std::map<std::string, std::pair<double, Eigen::Vector3d>>
      radars = {{"RADAR_FRONT", {0.0, {3.412, 0.0, 0.5}}},
                {"RADAR_FRONT_LEFT", {90.0, {2.422, 0.8, 0.78}}},
                {"RADAR_FRONT_RIGHT", {-90.0, {2.422, -0.8, 0.77}}},
                {"RADAR_BACK_LEFT", {180.0 - 5.0, {-0.562, 0.628, 0.53}}},
                {"RADAR_BACK_RIGHT", {180.0 + 5.0, {-0.562, -0.618, 0.53}}}};
  const auto it = radars.find(channel);
  GEODRIVE_CHECK_INPUT(it != radars.end(), "synthetic rig: unknown channel '",
                       channel, "'");
  return Rigid3d(rz(it->second.first), it->second.second);
}

PinholeCamera SyntheticCameraIntrinsics(const std::string& channel,
                                        int width,
                                        int height) {
  GEODRIVE_CHECK_INPUT(IsCameraChannel(channel), "synthetic rig: '", channel,
                       "' is no camera");
  const double f0 =
      channel == "CAM_BACK" ? 809.2209905677063 : 1266.417203046554;
  const double f = f0 * width / 1600.0;
  // Principal point that MonST3R's resize maps exactly to the processed image
  // centre: u' = (u + 0.5) * s - 0.5 - crop  =>  u = (W'/2 + crop + 0.5) / s -
  // 0.5.
  const ImageResizeSpec spec = ComputeMonst3rResizeSpec(width, height);
  const double sx = static_cast<double>(spec.resized_width) / width;
  const double sy = static_cast<double>(spec.resized_height) / height;
  const double cx = (spec.width / 2.0 + spec.crop_left + 0.5) / sx - 0.5;
  const double cy = (spec.height / 2.0 + spec.crop_top + 0.5) / sy - 0.5;
  return PinholeCamera(f, f, cx, cy, width, height);
}

PinholeCamera SyntheticMonst3rCamera(int width, int height) {
  const ImageResizeSpec spec = ComputeMonst3rResizeSpec(width, height);
  PinholeCamera cam = ApplyResizeSpec(
      SyntheticCameraIntrinsics("CAM_FRONT", width, height), spec);
  cam.cx = spec.width / 2.0;  // exact (the formula above gives it up to ~1e-13)
  cam.cy = spec.height / 2.0;
  return cam;
}

std::string SyntheticSceneName(int scene_index) {
  char b[32];
  std::snprintf(b, sizeof(b), "scene-%04d", scene_index + 1);
  return b;
}

SyntheticWorldOptions SyntheticWorldOptionsFor(
    const SyntheticDatasetOptions& options, int scene_index) {
  SyntheticWorldOptions w;
  w.seed = options.seed;
  w.scene_index = scene_index;
  w.duration_s = options.scene_duration_s;
  w.reverse_after_stop = options.reverse_after_stop;
  return w;
}

SyntheticTimeline MakeSyntheticTimeline(const SyntheticDatasetOptions& options,
                                        int scene_index) {
  SyntheticTimeline tl;
  const int64_t span_us =
      static_cast<int64_t>(std::ceil(options.scene_duration_s)) * 1000000;
  tl.start_us = 1700000000000000LL +
                static_cast<int64_t>(scene_index) * (span_us + 60000000LL) +
                static_cast<int64_t>(options.seed % 1000) * 1000;
  tl.num_samples = std::max(
      2, static_cast<int>(std::floor(options.scene_duration_s * 2 + 1e-9)));
  const int64_t sample_period = 1000000 / kSyntheticSampleRateHz;
  for (int n = 0; n < tl.num_samples; ++n)
    tl.sample_us.push_back(tl.start_us + n * sample_period);
  const int64_t last = (tl.num_samples - 1) * sample_period;
  for (const std::string& ch : WrittenChannels(options)) {
    const int rate = RateHz(ch);
    const int64_t off = OffsetUs(ch);
    auto& ts = tl.channel_us[ch];
    auto& key = tl.channel_key[ch];
    auto& smp = tl.channel_sample[ch];
    // Frame m at round(m / rate) seconds (+ channel offset); for cameras and
    // lidar the rate is a multiple of 2 Hz so every (rate/2)-th frame is a
    // keyframe; radar (13 Hz) keys the frame nearest each sample.
    const int64_t num_frames = last * rate / 1000000 + 1;
    std::set<int64_t> key_frames;
    for (int n = 0; n < tl.num_samples; ++n) {
      key_frames.insert((static_cast<int64_t>(n) * rate + 1) /
                        2);  // round(n * rate / 2)
    }
    for (int64_t m = 0; m < num_frames; ++m) {
      ts.push_back(tl.start_us + off + (m * 1000000 + rate / 2) / rate);
      key.push_back(key_frames.count(m) > 0);
    }
    // sample index: own for keyframes, else the next keyframe's sample.
    smp.assign(ts.size(), tl.num_samples - 1);
    int next_sample = tl.num_samples - 1;
    for (int64_t m = static_cast<int64_t>(ts.size()) - 1; m >= 0; --m) {
      if (key[m]) {
        // Which sample? the n with round(n*rate/2) == m.
        for (int n = 0; n < tl.num_samples; ++n)
          if ((static_cast<int64_t>(n) * rate + 1) / 2 == m) next_sample = n;
      }
      smp[m] = next_sample;
    }
  }
  return tl;
}

std::vector<int> SyntheticMonst3rClipStarts(
    const SyntheticDatasetOptions& options, int num_cam_front_frames) {
  std::vector<int> starts;
  for (int s = 0; s + kSyntheticClipLength <= num_cam_front_frames;
       s += options.monst3r_clip_stride) {
    if (options.monst3r_max_clips_per_scene > 0 &&
        static_cast<int>(starts.size()) >=
            options.monst3r_max_clips_per_scene) {
      break;
    }
    starts.push_back(s);
  }
  return starts;
}

std::string SyntheticDatasetOptions::Validate() const {
  std::ostringstream os;
  std::set<std::string> seen;
  for (const auto& c : cameras) {
    if (!IsCameraChannel(c) ||
        ChannelId(c) >= static_cast<int>(SyntheticChannels().size())) {
      return "unknown camera '" + c +
             "' (expected CAM_FRONT, CAM_FRONT_LEFT, CAM_FRONT_RIGHT, "
             "CAM_BACK, CAM_BACK_LEFT, CAM_BACK_RIGHT)";
    }
    if (!seen.insert(c).second) return "camera '" + c + "' listed twice";
  }
  if (num_scenes < 1 || num_scenes > 100000) {
    os << "num_scenes must be in [1, 100000] (got " << num_scenes << ")";
  } else if (image_width < 16 || image_height < 16 || image_width > 8192 ||
             image_height > 8192) {
    os << "image size must be within 16..8192 per side (got " << image_width
       << "x" << image_height << ")";
  } else if (!(scene_duration_s >= 1.0 && scene_duration_s <= 3600.0)) {
    os << "scene duration must be in [1, 3600] s (got " << scene_duration_s
       << ")";
  } else if (version.empty() || version.find('/') != std::string::npos ||
             version.find('\\') != std::string::npos || version == "." ||
             version == "..") {
    os << "version must be a plain folder name (got '" << version << "')";
  } else if (radars && !tables_only) {
    os << "radars are written in tables-only mode only";
  } else if (write_monst3r && tables_only) {
    os << "MonST3R outputs need images (drop tables-only)";
  } else if (write_monst3r && std::find(cameras.begin(), cameras.end(),
                                        "CAM_FRONT") == cameras.end()) {
    os << "MonST3R outputs need CAM_FRONT among the cameras";
  } else if (monst3r_clip_stride < 6 || monst3r_clip_stride % 6 != 0) {
    os << "monst3r_clip_stride must be a positive multiple of 6 (got "
       << monst3r_clip_stride << ")";
  } else if (!(monst3r_scale_min > 0 &&
               monst3r_scale_max >= monst3r_scale_min &&
               std::isfinite(monst3r_scale_max))) {
    os << "MonST3R scale range must satisfy 0 < min <= max";
  } else if (!(monst3r_depth_noise >= 0 && monst3r_depth_noise < 0.5)) {
    os << "MonST3R depth noise must be in [0, 0.5)";
  } else if (!(monst3r_pose_noise_deg >= 0 && monst3r_pose_noise_deg <= 30 &&
               monst3r_pose_noise_m >= 0 && monst3r_pose_noise_m <= 10)) {
    os << "MonST3R pose noise must be in [0, 30] deg and [0, 10] m";
  } else if (!(monst3r_outlier_fraction >= 0 &&
               monst3r_outlier_fraction <= 1)) {
    os << "MonST3R outlier fraction must be in [0, 1]";
  } else if (lidar_azimuth_steps < 1 || lidar_azimuth_steps > 100000) {
    os << "lidar_azimuth_steps must be in [1, 100000]";
  } else if (jpeg_quality < 1 || jpeg_quality > 100) {
    os << "jpeg_quality must be in [1, 100]";
  } else if (monst3r_max_clips_per_scene < 0) {
    os << "monst3r_max_clips_per_scene must be >= 0";
  }
  return os.str();
}

std::string SyntheticDatasetSummary::BriefReport() const {
  std::ostringstream os;
  os << "synthetic nuScenes dataset at " << root << " (" << version
     << "): " << num_scenes << " scenes, " << num_samples << " samples, "
     << num_sample_data << " sample_data, " << num_ego_poses << " ego_poses, "
     << num_instances << " instances, " << num_annotations << " annotations";
  if (num_images > 0 || num_lidar_sweeps > 0) {
    os << "; " << num_images << " camera images, " << num_lidar_sweeps
       << " lidar sweeps (" << num_lidar_points << " points)";
  }
  if (!monst3r_clip_ids.empty())
    os << "; " << monst3r_clip_ids.size() << " MonST3R clips";
  os << std::fixed << std::setprecision(1) << "; " << seconds << " s";
  return os.str();
}

// ---------------------------------------------------------------------------------------------
namespace {

struct Writers {
  std::map<std::string, std::unique_ptr<JsonTableWriter>> t;
  JsonTableWriter& operator[](const std::string& name) { return *t.at(name); }
};

// Visible fraction of a box from the written cameras at time t (27 points
// inside the box, each visible when a camera sees it in its image and the ray's
// first hit is the box itself).
double VisibleFraction(const SyntheticWorld& world,
                       const SyntheticDatasetOptions& o,
                       const VehicleBox& box,
                       double t) {
  const Rigid3d global_from_ego = world.GlobalFromEgo(t);
  std::vector<std::pair<PinholeCamera, Rigid3d>> cams;
  for (const auto& ch : o.cameras) {
    cams.emplace_back(
        SyntheticCameraIntrinsics(ch, o.image_width, o.image_height),
        global_from_ego * SyntheticEgoFromSensor(ch));
  }
  int visible = 0, total = 0;
  for (int i = -1; i <= 1; ++i) {
    for (int j = -1; j <= 1; ++j) {
      for (int k = -1; k <= 1; ++k) {
        const Eigen::Vector3d local(0.45 * i * box.size_wlh[1],
                                    0.45 * j * box.size_wlh[0],
                                    0.45 * k * box.size_wlh[2]);
        const Eigen::Vector3d p = box.center + box.rotation * local;
        ++total;
        for (const auto& [cam, pose] : cams) {
          const Eigen::Vector3d pc = pose.Inverse() * p;
          if (pc.z() < 0.5) continue;
          const Eigen::Vector2d px = cam.Project(pc);
          if (!(px.x() >= 0 && px.y() >= 0 && px.x() <= cam.width - 1 &&
                px.y() <= cam.height - 1)) {
            continue;
          }
          const RayHit hit =
              world.CastRay(pose.translation, p - pose.translation, t,
                            (p - pose.translation).norm() + 1.0);
          if (hit.instance == box.id + 1) {
            ++visible;
            break;
          }
        }
      }
    }
  }
  return static_cast<double>(visible) / total;
}

std::string VisibilityToken(double fraction) {
  if (fraction <= 0.4) return "1";
  if (fraction <= 0.6) return "2";
  if (fraction <= 0.8) return "3";
  return "4";
}

void WriteStaticTables(const SyntheticDatasetOptions& o,
                       const Tokens& tok,
                       Writers& w,
                       const std::vector<std::string>& channels) {
  const auto& cats = Categories();
  for (size_t i = 0; i < cats.size(); ++i) {
    auto& t = w["category"];
    t.Begin();
    t.Str("token", tok.Make(kTokCategory, i));
    t.Str("name", cats[i]);
    t.Str("description", "synthetic " + cats[i]);
    t.Int("index", static_cast<int64_t>(i) + 1);
    t.End();
  }
  const auto& atts = Attributes();
  for (size_t i = 0; i < atts.size(); ++i) {
    auto& t = w["attribute"];
    t.Begin();
    t.Str("token", tok.Make(kTokAttribute, i));
    t.Str("name", atts[i]);
    t.Str("description", "synthetic " + atts[i]);
    t.End();
  }
  const char* levels[] = {"v0-40", "v40-60", "v60-80", "v80-100"};
  const char* descr[] = {"visibility of whole object is between 0 and 40%",
                         "visibility of whole object is between 40 and 60%",
                         "visibility of whole object is between 60 and 80%",
                         "visibility of whole object is between 80 and 100%"};
  for (int i = 0; i < 4; ++i) {
    auto& t = w["visibility"];
    t.Begin();
    t.Str("description", descr[i]);
    t.Str("token", std::to_string(i + 1));
    t.Str("level", levels[i]);
    t.End();
  }
  for (const auto& ch : channels) {
    auto& t = w["sensor"];
    t.Begin();
    t.Str("token", tok.Make(kTokSensor, ChannelId(ch)));
    t.Str("channel", ch);
    t.Str("modality",
          IsCameraChannel(ch) ? "camera" : (IsRadar(ch) ? "radar" : "lidar"));
    t.End();
  }
  (void)o;
}

struct MonstClipContext {
  const SyntheticDatasetOptions* o;
  const SyntheticWorld* world;
  const SyntheticTimeline* tl;
  fs::path root;
  std::string scene_name, clip_id;
  int scene_index = 0, start = 0;
  std::vector<std::string>
      frame_files;  // CAM_FRONT image paths relative to root
  std::vector<std::string> frame_tokens;  // sample_data tokens
};

// What every frame of one MonST3R clip shares.
struct Monst3rClipSetup {
  fs::path dir, gt_dir;
  ImageResizeSpec spec;
  PinholeCamera cam;
  Rigid3d ego_from_cam;
  uint64_t clip_key = 0;
  double units_per_metre = 0;
  Rigid3d global_from_cam0, cam0_from_global;
  cv::Mat kernel;  // mask dilation
};

Monst3rClipSetup MakeMonst3rClipSetup(const MonstClipContext& c) {
  const SyntheticDatasetOptions& o = *c.o;
  Monst3rClipSetup setup;
  setup.dir = c.root / "monst3r" / c.clip_id;
  setup.gt_dir = c.root / "monst3r_gt" / c.clip_id;
  setup.spec = ComputeMonst3rResizeSpec(o.image_width, o.image_height);
  setup.cam = SyntheticMonst3rCamera(o.image_width, o.image_height);
  setup.ego_from_cam = SyntheticEgoFromSensor("CAM_FRONT");
  const auto& ts = c.tl->channel_us.at("CAM_FRONT");
  setup.clip_key =
      Mix64(o.seed ^ Mix64(static_cast<uint64_t>(c.scene_index) * 7919 +
                           static_cast<uint64_t>(c.start)));
  setup.units_per_metre =
      o.monst3r_scale_min +
      (o.monst3r_scale_max - o.monst3r_scale_min) * U01(setup.clip_key);
  setup.global_from_cam0 =
      c.world->GlobalFromEgo(c.tl->Seconds(ts[c.start])) * setup.ego_from_cam;
  setup.cam0_from_global = setup.global_from_cam0.Inverse();
  setup.kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3));
  return setup;
}

// MonST3R's predicted pose of frame i: the true pose with the configured noise
// (none on frame 0, the world origin).
Rigid3d Monst3rPredictedPose(const SyntheticDatasetOptions& o,
                             uint64_t clip_key,
                             int i,
                             const Rigid3d& world_from_cam) {
  Rigid3d pred = world_from_cam;
  if (i > 0) {
    const uint64_t k = clip_key ^ Mix64(1000 + i);
    pred.rotation = Perturb(pred.rotation, o.monst3r_pose_noise_deg, k);
    if (o.monst3r_pose_noise_m > 0) {
      pred.translation +=
          o.monst3r_pose_noise_m *
          Eigen::Vector3d(Normal(k + 11), Normal(k + 12), Normal(k + 13));
    }
  }
  return pred;
}

// Appends frame i's lines of pred_traj.txt and pred_intrinsics.txt.
void AppendMonst3rPredLines(int i,
                            const Rigid3d& pred,
                            double units_per_metre,
                            const PinholeCamera& cam,
                            std::string* traj,
                            std::string* intr) {
  *traj += PyFloat(static_cast<double>(i));
  const Eigen::Vector3d tp = pred.translation * units_per_metre;
  for (int a = 0; a < 3; ++a) *traj += " " + PyFloat(tp[a]);
  const Eigen::Quaterniond q = pred.rotation.normalized();
  *traj += " " + PyFloat(q.w()) + " " + PyFloat(q.x()) + " " + PyFloat(q.y()) +
           " " + PyFloat(q.z()) + "\n";
  *intr += Fmt6(cam.fx) + " " + Fmt6(0.0) + " " + Fmt6(cam.cx) + " " +
           Fmt6(0.0) + " " + Fmt6(cam.fy) + " " + Fmt6(cam.cy) + " " +
           Fmt6(0.0) + " " + Fmt6(0.0) + " " + Fmt6(1.0) + "\n";
}

// Per-frame images of a clip at the MonST3R resolution (reused across frames).
struct Monst3rFrameMaps {
  Monst3rFrameMaps(int width, int height)
      : depth_m(static_cast<size_t>(width) * height),
        conf(width * height),
        init_conf(width * height),
        mask(height, width, CV_8UC1) {}
  std::vector<float> depth_m, conf, init_conf;
  std::vector<float> depth_units;
  cv::Mat mask, enlarged;
};

// Depth, confidence, masks at the MonST3R resolution of frame i (at time t)
// from its rendered view; returns the number of outlier pixels.
int64_t ComputeMonst3rFrameMaps(const MonstClipContext& c,
                                const Monst3rClipSetup& setup,
                                int i,
                                double t,
                                const RenderedView& view,
                                Monst3rFrameMaps* maps) {
  const SyntheticDatasetOptions& o = *c.o;
  const int W = setup.cam.width, H = setup.cam.height;
  const uint64_t clip_key = setup.clip_key;
  const double units_per_metre = setup.units_per_metre;
  std::vector<float>& depth_m = maps->depth_m;
  std::vector<float>& conf = maps->conf;
  std::vector<float>& init_conf = maps->init_conf;
  cv::Mat& mask = maps->mask;
  int64_t num_outliers = 0;
  std::vector<bool> moving(c.world->NumVehicles() + 1, false);
  for (int v = 0; v < c.world->NumVehicles(); ++v)
    moving[v + 1] = c.world->Vehicle(v, t).moving;
  std::vector<float> depth_units(static_cast<size_t>(W) * H);
  for (int y = 0; y < H; ++y) {
    const float* dr = view.depth.ptr<float>(y);
    const uint16_t* ir = view.instance.ptr<uint16_t>(y);
    uint8_t* mr = mask.ptr<uint8_t>(y);
    for (int x = 0; x < W; ++x) {
      const size_t p = static_cast<size_t>(y) * W + x;
      const uint64_t key =
          clip_key ^ Mix64((static_cast<uint64_t>(i) << 40) ^ p);
      const uint16_t inst = ir[x];
      const bool sky = inst == kSkyInstance;
      const bool dyn = !sky && inst != kStaticInstance && moving[inst];
      mr[x] = dyn ? 255 : 0;
      depth_m[p] = dr[x];
      double d = sky ? 500.0 : dr[x];
      double raw = sky ? 1.02 : 1.0 + 30.0 * std::exp(-d / 40.0);
      if (dyn) raw = 1.0 + 0.5 * (raw - 1.0);
      if (o.monst3r_depth_noise > 0) {
        d *= std::max(0.05, 1.0 + o.monst3r_depth_noise * Normal(key));
      }
      bool outlier = false;
      if (o.monst3r_outlier_fraction > 0 &&
          U01(key ^ 0x0F0F0F0F0F0Full) < o.monst3r_outlier_fraction) {
        outlier = true;
        ++num_outliers;
        d *= 0.5 + 1.5 * U01(key ^ 0x1234567ull);
        raw = 1.0 + 0.3 * U01(key ^ 0x7654321ull) + 0.01;
      }
      depth_units[p] = static_cast<float>(d * units_per_metre);
      init_conf[p] = static_cast<float>(std::log(raw));
      conf[p] = outlier ? -std::numeric_limits<float>::infinity()
                        : static_cast<float>(std::log(1.0 + 0.8 * (raw - 1.0)));
    }
  }
  maps->depth_units = std::move(depth_units);
  return num_outliers;
}

// Writes frame i's MonST3R files (depth, confidences, masks, RGB) and, if
// asked, its true depth; returns the true depth's path relative to the root
// ("" when not written).
std::string WriteMonst3rFrameFiles(const MonstClipContext& c,
                                   const Monst3rClipSetup& setup,
                                   int i,
                                   Monst3rFrameMaps* maps) {
  const SyntheticDatasetOptions& o = *c.o;
  const fs::path& dir = setup.dir;
  const fs::path& gt_dir = setup.gt_dir;
  const ImageResizeSpec& spec = setup.spec;
  const int W = setup.cam.width, H = setup.cam.height;
  char name[64];
  std::snprintf(name, sizeof(name), "frame_%04d.npy", i);
  WriteNpy((dir / name).string(),
           NpyArray::Float32({H, W}, maps->depth_units.data()));
  WriteNpy((dir / ("conf_" + std::to_string(i) + ".npy")).string(),
           NpyArray::Float32({H, W}, maps->conf.data()));
  WriteNpy((dir / ("init_conf_" + std::to_string(i) + ".npy")).string(),
           NpyArray::Float32({H, W}, maps->init_conf.data()));
  WriteImageRgb((dir / ("dynamic_mask_" + std::to_string(i) + ".png")).string(),
                maps->mask);
  cv::dilate(maps->mask, maps->enlarged, setup.kernel);
  WriteImageRgb(
      (dir / ("enlarged_dynamic_mask_" + std::to_string(i) + ".png")).string(),
      maps->enlarged);
  // RGB: the camera JPEG as MonST3R loads it (resize, centre crop).
  {
    const cv::Mat rgb = ReadImageRgb((c.root / c.frame_files[i]).string());
    cv::Mat resized;
    const bool down = spec.resized_width < o.image_width;
    cv::resize(rgb, resized, cv::Size(spec.resized_width, spec.resized_height),
               0, 0, down ? cv::INTER_AREA : cv::INTER_CUBIC);
    const cv::Mat cropped = resized(cv::Rect(spec.crop_left, spec.crop_top,
                                             spec.width, spec.height))
                                .clone();
    std::snprintf(name, sizeof(name), "frame_%04d.png", i);
    WriteImageRgb((dir / name).string(), cropped);
  }
  std::string depth_rel;
  if (o.monst3r_write_true_depth) {
    std::snprintf(name, sizeof(name), "depth_%04d.npy", i);
    WriteNpy((gt_dir / name).string(),
             NpyArray::Float32({H, W}, maps->depth_m.data()));
    depth_rel = "monst3r_gt/" + c.clip_id + "/" + name;
  }
  return depth_rel;
}

// Frame i's entry of the ground-truth sidecar's "frames".
nlohmann::ordered_json Monst3rFrameTruth(const MonstClipContext& c,
                                         int i,
                                         int64_t timestamp,
                                         const Rigid3d& world_from_cam,
                                         const Rigid3d& global_from_cam,
                                         const std::string& depth_rel) {
  const int j = c.start + i;
  nlohmann::ordered_json f;
  f["index"] = i;
  f["cam_front_index"] = j;
  f["timestamp"] = timestamp;
  f["sample_data_token"] = c.frame_tokens[i];
  f["filename"] = c.frame_files[i];
  const Eigen::Vector4d qw =
      QuaternionToWxyz(world_from_cam.rotation.normalized());
  f["world_from_cam"] = {
      {"rotation_wxyz", {qw[0], qw[1], qw[2], qw[3]}},
      {"translation_m",
       {world_from_cam.translation.x(), world_from_cam.translation.y(),
        world_from_cam.translation.z()}}};
  const Eigen::Vector4d qg =
      QuaternionToWxyz(global_from_cam.rotation.normalized());
  f["global_from_cam"] = {
      {"rotation_wxyz", {qg[0], qg[1], qg[2], qg[3]}},
      {"translation_m",
       {global_from_cam.translation.x(), global_from_cam.translation.y(),
        global_from_cam.translation.z()}}};
  f["true_depth"] = depth_rel;
  return f;
}

// Writes the clip's ground-truth sidecar monst3r_gt/<clip_id>.json.
void WriteMonst3rClipTruth(const MonstClipContext& c,
                           const Monst3rClipSetup& setup,
                           const nlohmann::ordered_json& gt_frames,
                           int64_t num_outliers) {
  const SyntheticDatasetOptions& o = *c.o;
  const ImageResizeSpec& spec = setup.spec;
  const PinholeCamera& cam = setup.cam;
  const int W = setup.cam.width, H = setup.cam.height;
  const double units_per_metre = setup.units_per_metre;
  const Rigid3d& global_from_cam0 = setup.global_from_cam0;
  nlohmann::ordered_json gt;
  gt["clip_id"] = c.clip_id;
  gt["scene_name"] = c.scene_name;
  gt["start_index"] = c.start;
  gt["num_frames"] = kSyntheticClipLength;
  gt["monst3r_dir"] = "monst3r/" + c.clip_id;
  gt["units_per_metre"] = units_per_metre;
  gt["metres_per_unit"] = 1.0 / units_per_metre;
  gt["scale_note"] =
      "MonST3R depth and pred_traj translations are metres * units_per_metre; "
      "world = first "
      "camera (OpenCV axes); global_point = global_from_world * "
      "(metres_per_unit * monst3r_point)";
  const Eigen::Vector4d q0 =
      QuaternionToWxyz(global_from_cam0.rotation.normalized());
  gt["global_from_world"] = {
      {"rotation_wxyz", {q0[0], q0[1], q0[2], q0[3]}},
      {"translation_m",
       {global_from_cam0.translation.x(), global_from_cam0.translation.y(),
        global_from_cam0.translation.z()}}};
  gt["intrinsics"] = {{"fx", cam.fx},
                      {"fy", cam.fy},
                      {"cx", cam.cx},
                      {"cy", cam.cy},
                      {"width", W},
                      {"height", H},
                      {"pixel_convention", "integer-index"}};
  gt["source_intrinsics"] = {{"width", o.image_width},
                             {"height", o.image_height},
                             {"resize",
                              {{"resized_width", spec.resized_width},
                               {"resized_height", spec.resized_height},
                               {"crop_left", spec.crop_left},
                               {"crop_top", spec.crop_top}}}};
  gt["noise"] = {{"depth_fraction", o.monst3r_depth_noise},
                 {"pose_deg", o.monst3r_pose_noise_deg},
                 {"pose_m", o.monst3r_pose_noise_m},
                 {"outlier_fraction", o.monst3r_outlier_fraction},
                 {"num_outlier_pixels", num_outliers}};
  gt["sky_depth_m"] = 500.0;
  gt["frames"] = gt_frames;
  WriteText((c.root / "monst3r_gt" / (c.clip_id + ".json")).string(),
            gt.dump(1) + "\n");
}

void WriteMonst3rClip(const MonstClipContext& c) {
  const SyntheticDatasetOptions& o = *c.o;
  const Monst3rClipSetup setup = MakeMonst3rClipSetup(c);
  MakeDirs(setup.dir);
  if (o.monst3r_write_true_depth) MakeDirs(setup.gt_dir);
  const auto& ts = c.tl->channel_us.at("CAM_FRONT");
  std::string traj, intr;
  nlohmann::ordered_json gt_frames = nlohmann::ordered_json::array();
  Monst3rFrameMaps maps(setup.cam.width, setup.cam.height);
  int64_t num_outliers = 0;
  for (int i = 0; i < kSyntheticClipLength; ++i) {
    const int j = c.start + i;
    const double t = c.tl->Seconds(ts[j]);
    const Rigid3d global_from_cam =
        c.world->GlobalFromEgo(t) * setup.ego_from_cam;
    const Rigid3d world_from_cam =
        setup.cam0_from_global * global_from_cam;  // metres
    const Rigid3d pred =
        Monst3rPredictedPose(o, setup.clip_key, i, world_from_cam);
    AppendMonst3rPredLines(i, pred, setup.units_per_metre, setup.cam, &traj,
                           &intr);

    // Depth, confidence, masks at the MonST3R resolution.
    const RenderedView view =
        c.world->RenderCamera(setup.cam, global_from_cam, t);
    num_outliers += ComputeMonst3rFrameMaps(c, setup, i, t, view, &maps);
    const std::string depth_rel = WriteMonst3rFrameFiles(c, setup, i, &maps);
    gt_frames.push_back(Monst3rFrameTruth(c, i, ts[j], world_from_cam,
                                          global_from_cam, depth_rel));
  }
  WriteText((setup.dir / "pred_traj.txt").string(), traj);
  WriteText((setup.dir / "pred_intrinsics.txt").string(), intr);
  WriteMonst3rClipTruth(c, setup, gt_frames, num_outliers);
}

void WriteMapMask(const fs::path& path, int location) {
  cv::Mat mask(128, 128, CV_8UC1, cv::Scalar(0));
  // A schematic drivable area: a cross (the synthetic worlds' street and cross
  // street).
  cv::rectangle(mask, cv::Rect(0, 56 + location, 128, 16), cv::Scalar(255),
                cv::FILLED);
  cv::rectangle(mask, cv::Rect(56, 0, 16, 128), cv::Scalar(255), cv::FILLED);
  WriteImageRgb(path.string(), mask);
}

// Writes one dataset for WriteSyntheticDataset (options already validated):
// the static tables, then scene by scene its log, scene and sample records,
// sensor data, annotations and MonST3R clips, then the maps, the manifest.
class DatasetWriter {
 public:
  DatasetWriter(const SyntheticDatasetOptions& o, const std::string& out_dir)
      : o_(o), root_(out_dir), channels_(WrittenChannels(o)), tok_{o.seed} {
    summary_.root = out_dir;
    summary_.version = o.version;
    summary_.num_scenes = o.num_scenes;
    lidar_opts_.azimuth_steps = o.lidar_azimuth_steps;
  }

  // Writes everything; the summary's `seconds` is left to the caller.
  SyntheticDatasetSummary Write();

 private:
  // One scene being written.
  struct Scene {
    int index = 0;
    const SyntheticWorld* world = nullptr;
    const SyntheticTimeline* tl = nullptr;
    std::string name, log;
    // Keyframe lidar instance counts (sample x vehicle) feed num_lidar_pts.
    std::vector<std::vector<int>> lidar_counts;
    // CAM_FRONT sample_data filenames and tokens (for the MonST3R clips).
    std::vector<std::string> cam_front_files, cam_front_tokens;
  };

  void MakeDirectories() const;
  void OpenTables();
  void WriteScene(int s);
  void WriteSceneRecords(const Scene& scene);
  void WriteChannel(const std::string& ch, Scene* scene);
  void WriteCalibratedSensor(const std::string& ch,
                             int cid,
                             const std::string& calib,
                             const Rigid3d& ego_from_sensor);
  void WriteSensorFile(const std::string& ch,
                       const PinholeCamera& cam,
                       const Rigid3d& global_from_sensor,
                       double t,
                       const std::string& path,
                       bool is_key_frame,
                       int sample,
                       Scene* scene);
  void WriteAnnotations(const Scene& scene);
  nlohmann::ordered_json WriteMonst3rClips(const Scene& scene);
  void WriteMaps();
  void WriteManifest() const;
  void Progress(const std::string& line) const {
    if (o_.progress) o_.progress(line);
  }

  const SyntheticDatasetOptions& o_;
  const fs::path root_;
  const std::vector<std::string> channels_;
  const Tokens tok_;
  LidarOptions lidar_opts_;
  Writers w_;
  SyntheticDatasetSummary summary_;
  nlohmann::ordered_json manifest_scenes_ = nlohmann::ordered_json::array();
};

SyntheticDatasetSummary DatasetWriter::Write() {
  MakeDirectories();
  OpenTables();
  WriteStaticTables(o_, tok_, w_, channels_);
  for (int s = 0; s < o_.num_scenes; ++s) WriteScene(s);
  WriteMaps();
  for (auto& [name, writer] : w_.t) writer->Close();
  WriteManifest();
  return summary_;
}

void DatasetWriter::MakeDirectories() const {
  MakeDirs(root_ / o_.version);
  MakeDirs(root_ / "maps");
  if (!o_.tables_only) {
    for (const auto& ch : channels_) {
      MakeDirs(root_ / "samples" / ch);
      MakeDirs(root_ / "sweeps" / ch);
    }
  }
  if (o_.write_monst3r) {
    MakeDirs(root_ / "monst3r");
    MakeDirs(root_ / "monst3r_gt");
  }
}

void DatasetWriter::OpenTables() {
  for (const char* name :
       {"category", "attribute", "visibility", "instance", "sensor",
        "calibrated_sensor", "ego_pose", "log", "scene", "sample",
        "sample_data", "sample_annotation", "map"}) {
    w_.t[name] = std::make_unique<JsonTableWriter>(
        (root_ / o_.version / (std::string(name) + ".json")).string());
  }
}

void DatasetWriter::WriteScene(int s) {
  const SyntheticWorld world(SyntheticWorldOptionsFor(o_, s));
  const SyntheticTimeline tl = MakeSyntheticTimeline(o_, s);
  Scene scene;
  scene.index = s;
  scene.world = &world;
  scene.tl = &tl;
  scene.name = SyntheticSceneName(s);
  scene.log = LogName(o_.seed, s);
  const std::string& scene_name = scene.name;
  summary_.scene_maneuvers.push_back(ToString(world.maneuver()));
  WriteSceneRecords(scene);

  // Sensor data. Keyframe lidar instance counts feed num_lidar_pts.
  scene.lidar_counts.assign(tl.num_samples,
                            std::vector<int>(world.NumVehicles(), 0));
  for (const std::string& ch : channels_) WriteChannel(ch, &scene);

  // Annotations: every vehicle within 80 m of the ego at a keyframe.
  WriteAnnotations(scene);

  // MonST3R clips.
  const nlohmann::ordered_json clips = WriteMonst3rClips(scene);
  manifest_scenes_.push_back({{"name", scene_name},
                              {"token", tok_.Make(kTokScene, s)},
                              {"log", scene.log},
                              {"maneuver", ToString(world.maneuver())},
                              {"intersection_x_street", world.intersection_x()},
                              {"monst3r_clips", clips}});
  if (!o_.tables_only || (s + 1) % 50 == 0 || s + 1 == o_.num_scenes) {
    Progress("scene " + std::to_string(s + 1) + "/" +
             std::to_string(o_.num_scenes) + " (" + scene_name + ", " +
             ToString(world.maneuver()) + ") done");
  }
}

// The log, scene and sample records of a scene.
void DatasetWriter::WriteSceneRecords(const Scene& scene) {
  const int s = scene.index;
  const SyntheticWorld& world = *scene.world;
  const SyntheticTimeline& tl = *scene.tl;
  const int location = s % 2;
  const int N = tl.num_samples;
  auto& t = w_["log"];
  t.Begin();
  t.Str("token", tok_.Make(kTokLog, s));
  t.Str("logfile", scene.log);
  t.Str("vehicle", "n900");
  t.Str("date_captured", "2025-06-01");
  t.Str("location", kLocations[location]);
  t.End();
  auto& sc = w_["scene"];
  sc.Begin();
  sc.Str("token", tok_.Make(kTokScene, s));
  sc.Str("log_token", tok_.Make(kTokLog, s));
  sc.Int("nbr_samples", N);
  sc.Str("first_sample_token", tok_.Make(kTokSample, s, 0));
  sc.Str("last_sample_token", tok_.Make(kTokSample, s, N - 1));
  sc.Str("name", scene.name);
  sc.Str("description", "synthetic street, ego " + ToString(world.maneuver()) +
                            ", seed " + std::to_string(o_.seed));
  sc.End();
  for (int n = 0; n < N; ++n) {
    auto& sm = w_["sample"];
    sm.Begin();
    sm.Str("token", tok_.Make(kTokSample, s, n));
    sm.Int("timestamp", tl.sample_us[n]);
    sm.Str("prev", n > 0 ? tok_.Make(kTokSample, s, n - 1) : "");
    sm.Str("next", n + 1 < N ? tok_.Make(kTokSample, s, n + 1) : "");
    sm.Str("scene_token", tok_.Make(kTokScene, s));
    sm.End();
  }
  summary_.num_samples += N;
}

// One channel of a scene: its calibrated_sensor record, then per frame the
// ego_pose and sample_data records and (unless tables-only) the file.
void DatasetWriter::WriteChannel(const std::string& ch, Scene* scene) {
  const int s = scene->index;
  const SyntheticWorld& world = *scene->world;
  const SyntheticTimeline& tl = *scene->tl;
  const int cid = ChannelId(ch);
  const Rigid3d ego_from_sensor = SyntheticEgoFromSensor(ch);
  const std::string calib = tok_.Make(kTokCalib, s, cid);
  WriteCalibratedSensor(ch, cid, calib, ego_from_sensor);
  const auto& ts = tl.channel_us.at(ch);
  const auto& key = tl.channel_key.at(ch);
  const auto& smp = tl.channel_sample.at(ch);
  const PinholeCamera cam =
      IsCameraChannel(ch)
          ? SyntheticCameraIntrinsics(ch, o_.image_width, o_.image_height)
          : PinholeCamera();
  const int M = static_cast<int>(ts.size());
  for (int m = 0; m < M; ++m) {
    const double t = tl.Seconds(ts[m]);
    const Rigid3d global_from_ego = world.GlobalFromEgo(t);
    const std::string sd_token = tok_.Make(kTokSampleData, s, cid, m);
    const std::string ep_token = tok_.Make(kTokEgoPose, s, cid, m);
    const std::string filename = SweepFilename(scene->log, ch, ts[m], key[m]);
    {
      auto& e = w_["ego_pose"];
      e.Begin();
      e.Str("token", ep_token);
      e.Int("timestamp", ts[m]);
      double q[4];
      Quat(global_from_ego.rotation, q);
      e.Nums("rotation", q, 4);
      e.Nums("translation", global_from_ego.translation.data(), 3);
      e.End();
      auto& d = w_["sample_data"];
      d.Begin();
      d.Str("token", sd_token);
      d.Str("sample_token", tok_.Make(kTokSample, s, smp[m]));
      d.Str("ego_pose_token", ep_token);
      d.Str("calibrated_sensor_token", calib);
      d.Int("timestamp", ts[m]);
      d.Str("fileformat", IsCameraChannel(ch) ? "jpg" : "pcd");
      d.Bool("is_key_frame", key[m]);
      d.Int("height", IsCameraChannel(ch) ? o_.image_height : 0);
      d.Int("width", IsCameraChannel(ch) ? o_.image_width : 0);
      d.Str("filename", filename);
      d.Str("prev", m > 0 ? tok_.Make(kTokSampleData, s, cid, m - 1) : "");
      d.Str("next", m + 1 < M ? tok_.Make(kTokSampleData, s, cid, m + 1) : "");
      d.End();
    }
    if (ch == "CAM_FRONT") {
      scene->cam_front_files.push_back(filename);
      scene->cam_front_tokens.push_back(sd_token);
    }
    if (o_.tables_only) continue;
    const Rigid3d global_from_sensor = global_from_ego * ego_from_sensor;
    const std::string path = (root_ / filename).string();
    WriteSensorFile(ch, cam, global_from_sensor, t, path, key[m], smp[m],
                    scene);
  }
  summary_.num_sample_data += M;
  summary_.num_ego_poses += M;
  if (!o_.tables_only) {
    Progress(scene->name + " " + ch + ": " + std::to_string(M) + " files");
  }
}

void DatasetWriter::WriteCalibratedSensor(const std::string& ch,
                                          int cid,
                                          const std::string& calib,
                                          const Rigid3d& ego_from_sensor) {
  auto& t = w_["calibrated_sensor"];
  t.Begin();
  t.Str("token", calib);
  t.Str("sensor_token", tok_.Make(kTokSensor, cid));
  double q[4];
  Quat(ego_from_sensor.rotation, q);
  t.Nums("translation", ego_from_sensor.translation.data(), 3);
  t.Nums("rotation", q, 4);
  if (IsCameraChannel(ch)) {
    const PinholeCamera cam =
        SyntheticCameraIntrinsics(ch, o_.image_width, o_.image_height);
    std::ostringstream k;
    k.precision(17);
    auto num = [](double v) {
      char b[64];
      return std::string(b, std::to_chars(b, b + sizeof(b), v).ptr);
    };
    t.Raw("camera_intrinsic", "[[" + num(cam.fx) + ", 0.0, " + num(cam.cx) +
                                  "], [0.0, " + num(cam.fy) + ", " +
                                  num(cam.cy) + "], [0.0, 0.0, 1.0]]");
  } else {
    t.Raw("camera_intrinsic", "[]");
  }
  t.End();
}

// The file of one sample_data: a camera JPEG or a LIDAR_TOP .pcd.bin (whose
// keyframe instance counts go to scene->lidar_counts[sample]).
void DatasetWriter::WriteSensorFile(const std::string& ch,
                                    const PinholeCamera& cam,
                                    const Rigid3d& global_from_sensor,
                                    double t,
                                    const std::string& path,
                                    bool is_key_frame,
                                    int sample,
                                    Scene* scene) {
  const SyntheticWorld& world = *scene->world;
  if (IsCameraChannel(ch)) {
    const RenderedView view = world.RenderCamera(cam, global_from_sensor, t);
    // TurboJPEG with cv::imencode's settings: the same bytes as before.
    const std::vector<uint8_t> jpeg =
        EncodeJpegRgb(view.rgb, o_.jpeg_quality, path);
    WriteBytes(path, jpeg.data(), jpeg.size());
    ++summary_.num_images;
  } else if (ch == "LIDAR_TOP") {
    const LidarSweep sweep =
        world.CastLidar(global_from_sensor, t, lidar_opts_);
    std::vector<float> data(sweep.points.size() * 5);
    for (size_t k = 0; k < sweep.points.size(); ++k) {
      data[5 * k + 0] = sweep.points[k].x();
      data[5 * k + 1] = sweep.points[k].y();
      data[5 * k + 2] = sweep.points[k].z();
      data[5 * k + 3] = sweep.intensity[k];
      data[5 * k + 4] = sweep.ring[k];
    }
    WriteBytes(path, data.data(), data.size() * sizeof(float));
    ++summary_.num_lidar_sweeps;
    summary_.num_lidar_points += static_cast<int64_t>(sweep.points.size());
    if (is_key_frame) {
      for (uint16_t inst : sweep.instance) {
        if (inst != kStaticInstance && inst != kSkyInstance)
          ++scene->lidar_counts[sample][inst - 1];
      }
    }
  }
}

// Annotations: every vehicle within 80 m of the ego at a keyframe (an instance
// record per annotated vehicle and its sample_annotation records).
void DatasetWriter::WriteAnnotations(const Scene& scene) {
  const int s = scene.index;
  const SyntheticWorld& world = *scene.world;
  const SyntheticTimeline& tl = *scene.tl;
  const int N = tl.num_samples;
  for (int v = 0; v < world.NumVehicles(); ++v) {
    std::vector<int> annotated;
    for (int n = 0; n < N; ++n) {
      const double t = tl.Seconds(tl.sample_us[n]);
      const Eigen::Vector3d d =
          world.Vehicle(v, t).center - world.GlobalFromEgo(t).translation;
      if (d.head<2>().norm() <= 80.0) annotated.push_back(n);
    }
    if (annotated.empty()) continue;
    const std::string inst_token = tok_.Make(kTokInstance, s, v);
    auto ann_token = [&](int n) { return tok_.Make(kTokAnnotation, s, v, n); };
    const VehicleBox first = world.Vehicle(v, 0.0);
    {
      auto& t = w_["instance"];
      t.Begin();
      t.Str("token", inst_token);
      t.Str("category_token",
            tok_.Make(kTokCategory, IndexOf(Categories(), first.category)));
      t.Int("nbr_annotations", static_cast<int64_t>(annotated.size()));
      t.Str("first_annotation_token", ann_token(annotated.front()));
      t.Str("last_annotation_token", ann_token(annotated.back()));
      t.End();
      ++summary_.num_instances;
    }
    for (size_t a = 0; a < annotated.size(); ++a) {
      const int n = annotated[a];
      const double t = tl.Seconds(tl.sample_us[n]);
      const VehicleBox box = world.Vehicle(v, t);
      int num_pts;
      std::string vis;
      if (o_.tables_only) {
        // Analytic estimate (no ray casting in tables-only mode).
        const double dist =
            (box.center - world.GlobalFromEgo(t).translation).head<2>().norm();
        num_pts = static_cast<int>(std::min(
            3000.0,
            2.0e4 * box.size_wlh[0] * box.size_wlh[2] / (dist * dist + 1.0)));
        vis = dist < 30 ? "4" : (dist < 50 ? "3" : (dist < 65 ? "2" : "1"));
      } else {
        num_pts = scene.lidar_counts[n][v];
        vis = VisibilityToken(VisibleFraction(world, o_, box, t));
      }
      auto& r = w_["sample_annotation"];
      r.Begin();
      r.Str("token", ann_token(n));
      r.Str("sample_token", tok_.Make(kTokSample, s, n));
      r.Str("instance_token", inst_token);
      r.Str("visibility_token", vis);
      r.Strs("attribute_tokens",
             {tok_.Make(kTokAttribute, IndexOf(Attributes(), box.attribute))});
      r.Nums("translation", box.center.data(), 3);
      r.Nums("size", box.size_wlh.data(), 3);
      double q[4];
      Quat(box.rotation, q);
      r.Nums("rotation", q, 4);
      r.Str("prev", a > 0 ? ann_token(annotated[a - 1]) : "");
      r.Str("next",
            a + 1 < annotated.size() ? ann_token(annotated[a + 1]) : "");
      r.Int("num_lidar_pts", num_pts);
      r.Int("num_radar_pts", 0);
      r.End();
      ++summary_.num_annotations;
    }
  }
}

// Writes the scene's MonST3R clips (if asked); returns their ids.
nlohmann::ordered_json DatasetWriter::WriteMonst3rClips(const Scene& scene) {
  const std::string& scene_name = scene.name;
  nlohmann::ordered_json clips = nlohmann::ordered_json::array();
  if (!o_.write_monst3r) return clips;
  for (int start : SyntheticMonst3rClipStarts(
           o_, static_cast<int>(scene.cam_front_files.size()))) {
    MonstClipContext c;
    c.o = &o_;
    c.world = scene.world;
    c.tl = scene.tl;
    c.root = root_;
    c.scene_name = scene_name;
    c.scene_index = scene.index;
    c.start = start;
    c.clip_id = MakeClipId(scene_name, start);
    c.frame_files.assign(
        scene.cam_front_files.begin() + start,
        scene.cam_front_files.begin() + start + kSyntheticClipLength);
    c.frame_tokens.assign(
        scene.cam_front_tokens.begin() + start,
        scene.cam_front_tokens.begin() + start + kSyntheticClipLength);
    WriteMonst3rClip(c);
    summary_.monst3r_clip_ids.push_back(c.clip_id);
    clips.push_back(c.clip_id);
    Progress(scene_name + " MonST3R clip " + c.clip_id);
  }
  return clips;
}

// Maps: one per location used, covering its logs.
void DatasetWriter::WriteMaps() {
  for (int loc = 0; loc < std::min(2, o_.num_scenes); ++loc) {
    std::vector<std::string> logs;
    for (int s = loc; s < o_.num_scenes; s += 2)
      logs.push_back(tok_.Make(kTokLog, s));
    const std::string map_token = tok_.Make(kTokMap, loc);
    const std::string filename = "maps/" + map_token + ".png";
    auto& t = w_["map"];
    t.Begin();
    t.Str("category", "semantic_prior");
    t.Str("token", map_token);
    t.Str("filename", filename);
    t.Strs("log_tokens", logs);
    t.End();
    WriteMapMask(root_ / filename, loc);
  }
}

void DatasetWriter::WriteManifest() const {
  nlohmann::ordered_json manifest;
  manifest["generator"] = "geodrive synth";
  manifest["version"] = o_.version;
  manifest["seed"] = o_.seed;
  manifest["num_scenes"] = o_.num_scenes;
  manifest["image_size"] = {o_.image_width, o_.image_height};
  manifest["cameras"] = o_.cameras;
  manifest["scene_duration_s"] = o_.scene_duration_s;
  manifest["tables_only"] = o_.tables_only;
  manifest["monst3r"] = o_.write_monst3r;
  manifest["monst3r_clip_stride"] = o_.monst3r_clip_stride;
  manifest["scenes"] = manifest_scenes_;
  WriteText((root_ / "synthetic_manifest.json").string(),
            manifest.dump(1) + "\n");
}

}  // namespace

SyntheticDatasetSummary WriteSyntheticDataset(const SyntheticDatasetOptions& o,
                                              const std::string& out_dir) {
  const std::string err = o.Validate();
  GEODRIVE_CHECK_INPUT(err.empty(), "synth options: ", err);
  GEODRIVE_CHECK_INPUT(!out_dir.empty(), "synth: empty output directory");
  const auto t_begin = std::chrono::steady_clock::now();
  SyntheticDatasetSummary summary = DatasetWriter(o, out_dir).Write();
  summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_begin)
          .count();
  return summary;
}

}  // namespace geodrive

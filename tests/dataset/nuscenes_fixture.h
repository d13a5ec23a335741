#pragma once
// A tiny nuScenes-format dataset with known closed-form truth, for the reader's
// tests.
//
// Per scene: CAM_FRONT at 12 Hz (frame period 83,333 us), LIDAR_TOP at 20 Hz,
// samples at 2 Hz (every 10th lidar frame; the camera keyframe is every 6th
// camera frame). Every sample_data has its own ego pose: the ego drives x =
// kSpeed * t with yaw = kYawRate * t (t in s since the scene start). Instance 0
// (a car) is annotated at every sample with a centre moving linearly and a yaw
// growing linearly; instance 1 appears from sample 3 on. Tables are nlohmann
// JSON so tests can corrupt them before writing.

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

namespace geodrive {
namespace test {

struct NuscenesFixture {
  using json = nlohmann::json;
  static constexpr double kSpeed = 10.0;   // m/s
  static constexpr double kYawRate = 0.1;  // rad/s
  static constexpr int64_t kCamPeriod = 83333;
  static constexpr int64_t kLidarPeriod = 50000;
  static constexpr int kWidth = 160, kHeight = 90;

  int scenes = 2;
  int samples_per_scene = 10;
  std::map<std::string, json> tables;
  uint64_t counter = 1;

  std::string Token() {
    uint64_t a = counter++ * 0x9E3779B97F4A7C15ull;
    uint64_t b = (a ^ (a >> 29)) * 0xBF58476D1CE4E5B9ull;
    char buf[40];
    std::snprintf(buf, sizeof(buf), "%016llx%016llx",
                  static_cast<unsigned long long>(a),
                  static_cast<unsigned long long>(b));
    return buf;
  }

  static json Quat(double yaw) {
    return {std::cos(yaw / 2), 0.0, 0.0, std::sin(yaw / 2)};
  }
  // Truth of instance `k` in scene-relative time t (s).
  static Eigen::Vector3d CarCenter(int k, double t) {
    return k == 0 ? Eigen::Vector3d(20 + 5 * t, 2 + t, 0.8)
                  : Eigen::Vector3d(30 - 3 * t, -3, 0.9);
  }
  static double CarYaw(int k, double t) {
    return k == 0 ? 0.2 * t : 3.0 + 0.05 * t;
  }

  NuscenesFixture() { Build(); }

  void Build() {
    for (const char* t :
         {"category", "attribute", "visibility", "instance", "sensor",
          "calibrated_sensor", "ego_pose", "log", "scene", "sample",
          "sample_data", "sample_annotation", "map"}) {
      tables[t] = json::array();
    }
    const std::string car = Token(), ped = Token();
    tables["category"].push_back(
        {{"token", car}, {"name", "vehicle.car"}, {"description", ""}});
    tables["category"].push_back({{"token", ped},
                                  {"name", "human.pedestrian.adult"},
                                  {"description", ""}});
    const std::string moving = Token();
    tables["attribute"].push_back(
        {{"token", moving}, {"name", "vehicle.moving"}, {"description", ""}});
    for (int v = 1; v <= 4; ++v) {
      tables["visibility"].push_back({{"token", std::to_string(v)},
                                      {"level", "v" + std::to_string(20 * v)},
                                      {"description", ""}});
    }
    const std::string cam_sensor = Token(), lidar_sensor = Token();
    tables["sensor"].push_back({{"token", cam_sensor},
                                {"channel", "CAM_FRONT"},
                                {"modality", "camera"}});
    tables["sensor"].push_back({{"token", lidar_sensor},
                                {"channel", "LIDAR_TOP"},
                                {"modality", "lidar"}});
    const std::string cam_cs = Token(), lidar_cs = Token();
    const double qn = std::sqrt(0.4998 * 0.4998 + 0.5030 * 0.5030 +
                                0.4998 * 0.4998 + 0.4974 * 0.4974);
    tables["calibrated_sensor"].push_back(
        {{"token", cam_cs},
         {"sensor_token", cam_sensor},
         {"translation", {1.7, 0.016, 1.51}},
         {"rotation", {0.4998 / qn, -0.5030 / qn, 0.4998 / qn, -0.4974 / qn}},
         {"camera_intrinsic",
          {{126.0, 0.0, 80.0}, {0.0, 126.0, 45.0}, {0.0, 0.0, 1.0}}}});
    tables["calibrated_sensor"].push_back(
        {{"token", lidar_cs},
         {"sensor_token", lidar_sensor},
         {"translation", {0.944, 0.0, 1.84}},
         {"rotation", Quat(-M_PI / 2)},
         {"camera_intrinsic", json::array()}});
    const std::string log = Token();
    tables["log"].push_back({{"token", log},
                             {"logfile", "n000-fixture"},
                             {"vehicle", "n000"},
                             {"date_captured", "2018-01-01"},
                             {"location", "singapore-onenorth"}});
    tables["map"].push_back({{"token", Token()},
                             {"log_tokens", {log}},
                             {"category", "semantic_prior"},
                             {"filename", "maps/fixture.png"}});
    for (int s = 0; s < scenes; ++s)
      BuildScene(s, log, cam_cs, lidar_cs, car, moving);
  }

  void BuildScene(int s,
                  const std::string& log,
                  const std::string& cam_cs,
                  const std::string& lidar_cs,
                  const std::string& car,
                  const std::string& moving) {
    const int64_t t0 = 1532402927000000 + s * 100000000LL;
    const std::string scene = Token();
    std::vector<std::string> samples;
    for (int k = 0; k < samples_per_scene; ++k) samples.push_back(Token());
    for (int k = 0; k < samples_per_scene; ++k) {
      tables["sample"].push_back(
          {{"token", samples[k]},
           {"timestamp", t0 + 10 * kLidarPeriod * k},
           {"scene_token", scene},
           {"prev", k > 0 ? samples[k - 1] : ""},
           {"next", k + 1 < samples_per_scene ? samples[k + 1] : ""}});
    }
    tables["scene"].push_back(
        {{"token", scene},
         {"name", "scene-" +
                      std::string(4 - std::to_string(s + 1).size(), '0') +
                      std::to_string(s + 1)},
         {"description", "fixture"},
         {"log_token", log},
         {"nbr_samples", samples_per_scene},
         {"first_sample_token", samples.front()},
         {"last_sample_token", samples.back()}});
    auto add_chain = [&](const std::string& channel, const std::string& cs,
                         int64_t period, int per_sample, const char* ext, int w,
                         int h) {
      const int frames = (samples_per_scene - 1) * per_sample + 1;
      std::vector<std::string> tokens;
      for (int i = 0; i < frames; ++i) tokens.push_back(Token());
      for (int i = 0; i < frames; ++i) {
        const int64_t ts = t0 + period * i;
        const double t = (ts - t0) * 1e-6;
        const bool key = i % per_sample == 0;
        const int sample =
            (i + per_sample - 1) / per_sample;  // keyframe: itself; sweep: next
        const std::string ego = Token();
        tables["ego_pose"].push_back({{"token", ego},
                                      {"timestamp", ts},
                                      {"rotation", Quat(kYawRate * t)},
                                      {"translation", {kSpeed * t, 0.0, 0.0}}});
        const std::string name =
            "n000-fixture__" + channel + "__" + std::to_string(ts) + ext;
        tables["sample_data"].push_back(
            {{"token", tokens[i]},
             {"sample_token", samples[sample]},
             {"ego_pose_token", ego},
             {"calibrated_sensor_token", cs},
             {"timestamp", ts},
             {"fileformat", std::string(ext).substr(1, 3)},
             {"is_key_frame", key},
             {"height", h},
             {"width", w},
             {"filename",
              std::string(key ? "samples/" : "sweeps/") + channel + "/" + name},
             {"prev", i > 0 ? tokens[i - 1] : ""},
             {"next", i + 1 < frames ? tokens[i + 1] : ""}});
      }
    };
    add_chain("CAM_FRONT", cam_cs, kCamPeriod, 6, ".jpg", kWidth, kHeight);
    add_chain("LIDAR_TOP", lidar_cs, kLidarPeriod, 10, ".pcd.bin", 0, 0);
    for (int k = 0; k < 2; ++k) {
      const std::string inst = Token();
      const int first = k == 0 ? 0 : 3;
      std::vector<std::string> anns;
      for (int i = first; i < samples_per_scene; ++i) anns.push_back(Token());
      for (int i = first; i < samples_per_scene; ++i) {
        const double t = 0.5 * i;
        const Eigen::Vector3d c = CarCenter(k, t);
        const int a = i - first;
        tables["sample_annotation"].push_back(
            {{"token", anns[a]},
             {"sample_token", samples[i]},
             {"instance_token", inst},
             {"visibility_token", "4"},
             {"attribute_tokens", {moving}},
             {"translation", {c.x(), c.y(), c.z()}},
             {"size", {1.9, 4.5, 1.6}},
             {"rotation", Quat(CarYaw(k, t))},
             {"prev", a > 0 ? anns[a - 1] : ""},
             {"next", a + 1 < static_cast<int>(anns.size()) ? anns[a + 1] : ""},
             {"num_lidar_pts", 10},
             {"num_radar_pts", 0}});
      }
      tables["instance"].push_back({{"token", inst},
                                    {"category_token", car},
                                    {"nbr_annotations", anns.size()},
                                    {"first_annotation_token", anns.front()},
                                    {"last_annotation_token", anns.back()}});
    }
  }

  // Writes <root>/v1.0-mini/*.json (nuScenes' indent-0 layout); returns root.
  std::string Write(const std::string& root) const {
    std::filesystem::create_directories(root + "/v1.0-mini");
    for (const auto& [name, table] : tables) {
      std::ofstream(root + "/v1.0-mini/" + name + ".json") << table.dump(0);
    }
    return root;
  }
};

}  // namespace test
}  // namespace geodrive

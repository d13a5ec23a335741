// Acceptance tests of the synthetic nuScenes + MonST3R dataset against its
// ground truth. Tables are parsed with nlohmann directly (independent of the
// nuScenes reader).

#include "dataset/synthetic/synthetic_dataset.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "dataset/clip_id.h"
#include "geometry/image_io.h"
#include "geometry/npy.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

SyntheticDatasetOptions SmallOptions() {
  SyntheticDatasetOptions o;
  o.num_scenes = 2;
  o.seed = 5;
  o.image_width = 320;
  o.image_height = 180;
  o.scene_duration_s = 3.0;  // 6 samples, 31 CAM_FRONT frames, 51 lidar sweeps
  o.cameras = {"CAM_FRONT", "CAM_BACK"};
  o.write_monst3r = true;
  o.lidar_azimuth_steps = 360;
  return o;
}

// One dataset for the whole suite, generated once per build of this test binary
// (ctest runs every test in its own process): the folder name carries the
// binary's modification time, and a new dataset is written to a private folder
// and renamed into place (safe under ctest -j).
class SyntheticDatasetTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const fs::path base = fs::path(GEODRIVE_BINARY_DIR) / "test_tmp";
    const std::string stamp = std::to_string(
        fs::last_write_time("/proc/self/exe").time_since_epoch().count());
    const fs::path dir = base / ("synthetic_dataset_" + stamp);
    if (!fs::exists(dir / "synthetic_manifest.json")) {
      const fs::path tmp =
          base / ("synthetic_dataset_tmp_" + std::to_string(::getpid()));
      fs::remove_all(tmp);
      const SyntheticDatasetSummary s =
          WriteSyntheticDataset(SmallOptions(), tmp.string());
      std::cout << s.BriefReport() << "\n";
      std::error_code ec;
      fs::rename(tmp, dir, ec);
      if (ec)
        fs::remove_all(
            tmp);  // another process won the race; its dataset is identical
      for (const auto& e :
           fs::directory_iterator(base)) {  // datasets of older builds
        const std::string name = e.path().filename().string();
        if (name.rfind("synthetic_dataset_", 0) == 0 &&
            name.rfind("synthetic_dataset_tmp_", 0) != 0) {
          if (e.path() != dir) fs::remove_all(e.path(), ec);
        }
      }
    }
    root_ = new std::string(dir.string());
    std::ifstream in(dir / "synthetic_manifest.json");
    const json manifest = json::parse(in);
    clip_ids_ = new std::vector<std::string>();
    for (const auto& sc : manifest["scenes"])
      for (const auto& c : sc["monst3r_clips"])
        clip_ids_->push_back(c.get<std::string>());
  }
  static void TearDownTestSuite() {
    delete root_;
    delete clip_ids_;
  }
  static json Table(const std::string& name) {
    std::ifstream in(*root_ + "/v1.0-mini/" + name + ".json");
    EXPECT_TRUE(in.good()) << name;
    return json::parse(in);
  }
  static std::map<std::string, json> ByToken(const json& table) {
    std::map<std::string, json> m;
    for (const auto& r : table) m[r["token"].get<std::string>()] = r;
    return m;
  }
  static Rigid3d Pose(const json& r) {
    const auto& q = r["rotation"];
    const auto& t = r["translation"];
    return Rigid3d(QuaternionFromWxyz(q[0], q[1], q[2], q[3]).normalized(),
                   Eigen::Vector3d(t[0], t[1], t[2]));
  }
  static std::string* root_;
  static std::vector<std::string>* clip_ids_;
};
std::string* SyntheticDatasetTest::root_ = nullptr;
std::vector<std::string>* SyntheticDatasetTest::clip_ids_ = nullptr;

TEST_F(SyntheticDatasetTest, TablesAreConsistent) {
  std::map<std::string, json> t;
  for (const char* name :
       {"category", "attribute", "visibility", "instance", "sensor",
        "calibrated_sensor", "ego_pose", "log", "scene", "sample",
        "sample_data", "sample_annotation", "map"}) {
    t[name] = Table(name);
    ASSERT_TRUE(t[name].is_array()) << name;
    ASSERT_FALSE(t[name].empty()) << name;
  }
  std::map<std::string, std::map<std::string, json>> idx;
  for (auto& [name, table] : t) {
    idx[name] = ByToken(table);
    EXPECT_EQ(idx[name].size(), table.size()) << "duplicate tokens in " << name;
    if (name == "visibility") continue;
    for (const auto& [tok, r] : idx[name]) {
      ASSERT_EQ(tok.size(), 32u) << name;
      ASSERT_EQ(tok.find_first_not_of("0123456789abcdef"), std::string::npos)
          << name;
    }
  }
  auto resolves = [&](const std::string& table, const json& tok,
                      bool allow_empty) {
    const std::string s = tok.get<std::string>();
    if (s.empty()) return allow_empty;
    return idx[table].count(s) > 0;
  };
  EXPECT_EQ(t["scene"].size(), 2u);
  EXPECT_EQ(idx["ego_pose"].size(), idx["sample_data"].size());
  // scene / sample chains.
  for (const auto& sc : t["scene"]) {
    ASSERT_TRUE(resolves("log", sc["log_token"], false));
    std::string tok = sc["first_sample_token"];
    int n = 0;
    int64_t prev_ts = -1;
    std::string prev = "";
    while (!tok.empty()) {
      const json& s = idx["sample"].at(tok);
      EXPECT_EQ(s["scene_token"], sc["token"]);
      EXPECT_EQ(s["prev"].get<std::string>(), prev);
      const int64_t ts = s["timestamp"];
      if (prev_ts >= 0) {  // 2 Hz within 1 ms
        EXPECT_NEAR(ts - prev_ts, 500000, 1000);
      }
      prev_ts = ts;
      prev = tok;
      tok = s["next"].get<std::string>();
      ++n;
    }
    EXPECT_EQ(prev, sc["last_sample_token"].get<std::string>());
    EXPECT_EQ(n, sc["nbr_samples"].get<int>());
  }
  // sample_data: references, files, per-channel chains and rates.
  std::map<std::string, std::string> channel_of_calib;
  for (const auto& cs : t["calibrated_sensor"]) {
    ASSERT_TRUE(resolves("sensor", cs["sensor_token"], false));
    channel_of_calib[cs["token"]] =
        idx["sensor"].at(cs["sensor_token"])["channel"];
  }
  std::map<std::string, int> keyframes_per_sample_channel;
  for (const auto& sd : t["sample_data"]) {
    ASSERT_TRUE(resolves("sample", sd["sample_token"], false));
    ASSERT_TRUE(resolves("ego_pose", sd["ego_pose_token"], false));
    ASSERT_TRUE(
        resolves("calibrated_sensor", sd["calibrated_sensor_token"], false));
    ASSERT_TRUE(resolves("sample_data", sd["prev"], true));
    ASSERT_TRUE(resolves("sample_data", sd["next"], true));
    EXPECT_EQ(idx["ego_pose"].at(sd["ego_pose_token"])["timestamp"],
              sd["timestamp"]);
    EXPECT_EQ(idx["ego_pose"]
                  .at(sd["ego_pose_token"])["translation"][2]
                  .get<double>(),
              0.0);
    const std::string ch = channel_of_calib.at(sd["calibrated_sensor_token"]);
    const std::string fn = sd["filename"];
    const bool key = sd["is_key_frame"];
    EXPECT_EQ(fn.rfind(key ? "samples/" + ch + "/" : "sweeps/" + ch + "/", 0),
              0u)
        << fn;
    EXPECT_TRUE(fs::exists(*root_ + "/" + fn)) << fn;
    const int64_t ts = sd["timestamp"];
    const int64_t sample_ts = idx["sample"].at(sd["sample_token"])["timestamp"];
    if (key) {
      ++keyframes_per_sample_channel[sd["sample_token"].get<std::string>() +
                                     ch];
      EXPECT_LT(std::abs(ts - sample_ts), 50000)
          << "keyframe far from its sample";
    } else {
      // A sweep points at the NEXT keyframe: its sample is the first one at or
      // after it.
      EXPECT_GT(sample_ts + 50000, ts);
      const std::string prev_sample =
          idx["sample"].at(sd["sample_token"])["prev"];
      ASSERT_FALSE(prev_sample.empty());
      EXPECT_LT(idx["sample"].at(prev_sample)["timestamp"].get<int64_t>(), ts);
    }
    if (ch.rfind("CAM_", 0) == 0) {
      EXPECT_EQ(sd["width"], 320);
      EXPECT_EQ(sd["height"], 180);
      EXPECT_EQ(sd["fileformat"], "jpg");
    } else {
      EXPECT_EQ(sd["width"], 0);
      EXPECT_EQ(sd["fileformat"], "pcd");
      EXPECT_EQ(fs::file_size(*root_ + "/" + fn) % 20, 0u);
    }
    if (sd["prev"]
            .get<std::string>()
            .empty()) {  // walk the chain from its head
      const double rate = ch == "LIDAR_TOP" ? 20.0 : 12.0;
      std::string tok = sd["token"];
      int64_t prev_ts = -1;
      while (!tok.empty()) {
        const json& r = idx["sample_data"].at(tok);
        EXPECT_EQ(channel_of_calib.at(r["calibrated_sensor_token"]), ch);
        const int64_t cur = r["timestamp"];
        if (prev_ts >= 0) {
          EXPECT_NEAR(cur - prev_ts, 1e6 / rate, 1000) << ch;
        }
        if (!r["next"].get<std::string>().empty()) {
          EXPECT_EQ(idx["sample_data"].at(r["next"])["prev"], r["token"]);
        }
        prev_ts = cur;
        tok = r["next"].get<std::string>();
      }
    }
  }
  // Every sample has exactly one keyframe per channel (CAM_FRONT, CAM_BACK,
  // LIDAR_TOP).
  for (const auto& s : t["sample"]) {
    for (const char* ch : {"CAM_FRONT", "CAM_BACK", "LIDAR_TOP"}) {
      EXPECT_EQ(
          keyframes_per_sample_channel[s["token"].get<std::string>() + ch], 1)
          << ch;
    }
  }
  // Annotations and instances.
  for (const auto& a : t["sample_annotation"]) {
    ASSERT_TRUE(resolves("sample", a["sample_token"], false));
    ASSERT_TRUE(resolves("instance", a["instance_token"], false));
    ASSERT_TRUE(resolves("visibility", a["visibility_token"], false));
    ASSERT_TRUE(resolves("sample_annotation", a["prev"], true));
    ASSERT_TRUE(resolves("sample_annotation", a["next"], true));
    for (const auto& at : a["attribute_tokens"])
      ASSERT_TRUE(resolves("attribute", at, false));
    ASSERT_EQ(a["size"].size(), 3u);
    ASSERT_EQ(a["rotation"].size(), 4u);
    if (!a["next"].get<std::string>().empty()) {
      EXPECT_LT(idx["sample"].at(a["sample_token"])["timestamp"].get<int64_t>(),
                idx["sample"]
                    .at(idx["sample_annotation"].at(
                        a["next"])["sample_token"])["timestamp"]
                    .get<int64_t>());
    }
  }
  int64_t lidar_pts = 0;
  for (const auto& a : t["sample_annotation"])
    lidar_pts += a["num_lidar_pts"].get<int64_t>();
  EXPECT_GT(lidar_pts, 100);
  for (const auto& in : t["instance"]) {
    ASSERT_TRUE(resolves("category", in["category_token"], false));
    std::string tok = in["first_annotation_token"];
    int n = 0;
    std::string last;
    while (!tok.empty()) {
      EXPECT_EQ(idx["sample_annotation"].at(tok)["instance_token"],
                in["token"]);
      last = tok;
      tok = idx["sample_annotation"].at(tok)["next"].get<std::string>();
      ++n;
    }
    EXPECT_EQ(n, in["nbr_annotations"].get<int>());
    EXPECT_EQ(last, in["last_annotation_token"].get<std::string>());
  }
  // Maps cover every log and their masks exist.
  std::set<std::string> covered;
  for (const auto& m : t["map"]) {
    for (const auto& l : m["log_tokens"]) covered.insert(l.get<std::string>());
    EXPECT_TRUE(fs::exists(*root_ + "/" + m["filename"].get<std::string>()));
  }
  for (const auto& l : t["log"])
    EXPECT_TRUE(covered.count(l["token"].get<std::string>()));
}

// LiDAR points through the nuScenes chain (sensor -> ego(lidar t) -> global ->
// ego(cam t) -> camera) land on pixels whose ray-cast true depth equals the
// LiDAR depth.
TEST_F(SyntheticDatasetTest, LidarProjectsOntoTrueCameraDepth) {
  const json sd_table = Table("sample_data");
  const auto sd = ByToken(sd_table);
  const auto ep = ByToken(Table("ego_pose"));
  const auto cs = ByToken(Table("calibrated_sensor"));
  const auto sensors = ByToken(Table("sensor"));
  const auto samples = ByToken(Table("sample"));
  const auto scenes = ByToken(Table("scene"));
  auto channel = [&](const json& r) {
    return sensors
        .at(cs.at(r["calibrated_sensor_token"])["sensor_token"])["channel"]
        .get<std::string>();
  };
  const SyntheticDatasetOptions o = SmallOptions();
  std::vector<double> errors;
  for (int scene = 0; scene < 2; ++scene) {
    const SyntheticWorld world(SyntheticWorldOptionsFor(o, scene));
    const SyntheticTimeline tl = MakeSyntheticTimeline(o, scene);
    // Pair every keyframe lidar with the keyframe CAM_FRONT image of the same
    // sample.
    std::map<std::string, std::pair<std::string, std::string>> by_sample;
    for (const auto& r : sd_table) {
      if (!r["is_key_frame"].get<bool>()) continue;
      const std::string scene_tok =
          samples.at(r["sample_token"])["scene_token"];
      if (scenes.at(scene_tok)["name"] != SyntheticSceneName(scene)) continue;
      if (channel(r) == "LIDAR_TOP")
        by_sample[r["sample_token"]].first = r["token"];
      if (channel(r) == "CAM_FRONT")
        by_sample[r["sample_token"]].second = r["token"];
    }
    ASSERT_EQ(by_sample.size(), 6u);
    for (const auto& [sample, pair] : by_sample) {
      const json& lidar = sd.at(pair.first);
      const json& camera = sd.at(pair.second);
      const Rigid3d ego_from_lidar =
          Pose(cs.at(lidar["calibrated_sensor_token"]));
      const Rigid3d global_from_ego_l = Pose(ep.at(lidar["ego_pose_token"]));
      const Rigid3d global_from_ego_c = Pose(ep.at(camera["ego_pose_token"]));
      const json& ccs = cs.at(camera["calibrated_sensor_token"]);
      const Rigid3d ego_from_cam = Pose(ccs);
      const auto& K = ccs["camera_intrinsic"];
      const PinholeCamera cam(K[0][0], K[1][1], K[0][2], K[1][2], 320, 180);
      const Rigid3d cam_from_lidar =
          (global_from_ego_c * ego_from_cam).Inverse() * global_from_ego_l *
          ego_from_lidar;
      const std::string path =
          *root_ + "/" + lidar["filename"].get<std::string>();
      std::ifstream in(path, std::ios::binary);
      std::vector<float> data(fs::file_size(path) / 4);
      in.read(reinterpret_cast<char*>(data.data()), data.size() * 4);
      const double t_cam = tl.Seconds(camera["timestamp"].get<int64_t>());
      for (size_t k = 0; k < data.size(); k += 5 * 3) {
        const Eigen::Vector3d p_cam =
            cam_from_lidar * Eigen::Vector3d(data[k], data[k + 1], data[k + 2]);
        if (p_cam.z() <= 1.0) continue;
        const Eigen::Vector2d uv = cam.Project(p_cam);
        if (!(uv.x() > 1 && uv.x() < cam.width - 1 && uv.y() > 1 &&
              uv.y() < cam.height - 1)) {
          continue;
        }
        const double true_depth = world.CameraDepthAt(
            cam, global_from_ego_c * ego_from_cam, t_cam, uv);
        errors.push_back(std::abs(true_depth - p_cam.z()));
      }
    }
  }
  ASSERT_GT(errors.size(), 500u);
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2,
                   errors.end());
  const double median = errors[errors.size() / 2];
  const double within = std::count_if(errors.begin(), errors.end(),
                                      [](double e) { return e < 0.01; }) /
                        static_cast<double>(errors.size());
  std::cout << "LiDAR->CAM_FRONT: " << errors.size()
            << " points, median |depth error| " << median * 1000 << " mm, "
            << within * 100 << "% within 1 cm\n";
  EXPECT_LT(median, 0.01);
  EXPECT_GT(within, 0.8);
}

// MonST3R depth unprojected with pred_intrinsics and pred_traj, times the true
// scale, gives the true world points (true = ray cast through the camera pose
// from the nuScenes tables).
TEST_F(SyntheticDatasetTest, Monst3rDepthUnprojectsToTrueWorldPoints) {
  const std::string clip = MakeClipId("scene-0001", 0);
  ASSERT_EQ(clip_ids_->size(), 2u);
  EXPECT_EQ((*clip_ids_)[0], clip);
  const std::string dir = *root_ + "/monst3r/" + clip;
  std::ifstream gt_in(*root_ + "/monst3r_gt/" + clip + ".json");
  const json gt = json::parse(gt_in);
  const double metres_per_unit = gt["metres_per_unit"];
  const Rigid3d global_from_world(
      QuaternionFromWxyz(gt["global_from_world"]["rotation_wxyz"][0],
                         gt["global_from_world"]["rotation_wxyz"][1],
                         gt["global_from_world"]["rotation_wxyz"][2],
                         gt["global_from_world"]["rotation_wxyz"][3]),
      Eigen::Vector3d(gt["global_from_world"]["translation_m"][0],
                      gt["global_from_world"]["translation_m"][1],
                      gt["global_from_world"]["translation_m"][2]));
  // Parse pred_traj.txt (t x y z qw qx qy qz, camera-to-world) and
  // pred_intrinsics.txt.
  std::ifstream traj_in(dir + "/pred_traj.txt"),
      intr_in(dir + "/pred_intrinsics.txt");
  std::vector<Rigid3d> world_from_cam;
  std::vector<Eigen::Matrix3d> Ks;
  std::string line;
  while (std::getline(traj_in, line)) {
    std::istringstream ls(line);
    double t, x, y, z, qw, qx, qy, qz;
    ASSERT_TRUE(
        static_cast<bool>(ls >> t >> x >> y >> z >> qw >> qx >> qy >> qz));
    EXPECT_EQ(t, static_cast<double>(world_from_cam.size()));
    world_from_cam.emplace_back(QuaternionFromWxyz(qw, qx, qy, qz),
                                Eigen::Vector3d(x, y, z));
  }
  while (std::getline(intr_in, line)) {
    std::istringstream ls(line);
    Eigen::Matrix3d K;
    for (int k = 0; k < 9; ++k) ls >> K(k / 3, k % 3);
    Ks.push_back(K);
  }
  ASSERT_EQ(world_from_cam.size(), 25u);
  ASSERT_EQ(Ks.size(), 25u);
  EXPECT_EQ(Ks[0](0, 2), 256.0);  // cx = W/2 exactly, as MonST3R writes it
  EXPECT_EQ(Ks[0](1, 2), 144.0);
  EXPECT_EQ(Ks[0](0, 0), Ks[0](1, 1));

  // Ground truth from the nuScenes tables + the world.
  const auto sd = ByToken(Table("sample_data"));
  const auto ep = ByToken(Table("ego_pose"));
  const auto cs = ByToken(Table("calibrated_sensor"));
  const SyntheticDatasetOptions o = SmallOptions();
  const SyntheticWorld world(SyntheticWorldOptionsFor(o, 0));
  const SyntheticTimeline tl = MakeSyntheticTimeline(o, 0);
  const PinholeCamera mcam = SyntheticMonst3rCamera(320, 180);
  double sum_sq = 0;
  int64_t n = 0, dynamic_pixels = 0;
  for (int i = 0; i < 25; i += 6) {
    char name[32];
    std::snprintf(name, sizeof(name), "/frame_%04d.npy", i);
    const NpyArray depth = ReadNpy(dir + name);
    ASSERT_EQ(depth.shape, (std::vector<int64_t>{288, 512}));
    const float* d = depth.Data<float>();
    const json& r =
        sd.at(gt["frames"][i]["sample_data_token"].get<std::string>());
    const Rigid3d global_from_cam = Pose(ep.at(r["ego_pose_token"])) *
                                    Pose(cs.at(r["calibrated_sensor_token"]));
    const double t = tl.Seconds(r["timestamp"].get<int64_t>());
    const Eigen::Matrix3d Kinv = Ks[i].inverse();
    for (int v = 0; v < 288; v += 9) {
      for (int u = 0; u < 512; u += 9) {
        uint16_t inst;
        const double true_z = world.CameraDepthAt(mcam, global_from_cam, t,
                                                  Eigen::Vector2d(u, v), &inst);
        if (true_z <= 0) continue;  // sky
        const Eigen::Vector3d x_cam =
            Kinv * Eigen::Vector3d(u, v, 1.0) * d[v * 512 + u];
        const Eigen::Vector3d x_world =
            world_from_cam[i].rotation * x_cam + world_from_cam[i].translation;
        const Eigen::Vector3d pred =
            global_from_world * (metres_per_unit * x_world);
        const Eigen::Vector3d truth =
            global_from_cam * (mcam.Unproject(Eigen::Vector2d(u, v), true_z));
        sum_sq += (pred - truth).squaredNorm();
        ++n;
      }
    }
    const cv::Mat mask =
        ReadImageGray(dir + "/dynamic_mask_" + std::to_string(i) + ".png");
    const cv::Mat big = ReadImageGray(dir + "/enlarged_dynamic_mask_" +
                                      std::to_string(i) + ".png");
    ASSERT_EQ(mask.cols, 512);
    for (int v = 0; v < mask.rows; ++v) {
      for (int u = 0; u < mask.cols; ++u) {
        const uint8_t m = mask.at<uint8_t>(v, u);
        ASSERT_TRUE(m == 0 || m == 255);
        if (m) {
          ASSERT_EQ(big.at<uint8_t>(v, u), 255);
        }
        dynamic_pixels += m ? 1 : 0;
      }
    }
    const cv::Mat rgb =
        ReadImageRgb(dir + "/frame_" + std::string(name + 7, 4) + ".png");
    EXPECT_EQ(rgb.cols, 512);
    EXPECT_EQ(rgb.rows, 288);
  }
  ASSERT_GT(n, 5000);
  const double rms = std::sqrt(sum_sq / n);
  std::cout << "MonST3R unprojection x true scale vs true world points: RMS "
            << rms * 1000 << " mm over " << n << " pixels; " << dynamic_pixels
            << " dynamic-mask pixels\n";
  EXPECT_LT(rms, 1e-3);
  EXPECT_GT(dynamic_pixels, 0);
  // Confidence maps: log confidence, finite and > 0 without noise.
  const NpyArray conf = ReadNpy(dir + "/conf_3.npy");
  const NpyArray init = ReadNpy(dir + "/init_conf_3.npy");
  for (int64_t k = 0; k < conf.NumElements(); ++k) {
    ASSERT_TRUE(std::isfinite(conf.Data<float>()[k]) &&
                conf.Data<float>()[k] > 0);
    ASSERT_TRUE(init.Data<float>()[k] > 0);
  }
}

TEST(SyntheticDatasetNoise, OutliersGetMinusInfConfidenceAndWrongDepth) {
  SyntheticDatasetOptions o = SmallOptions();
  o.num_scenes = 1;
  o.cameras = {"CAM_FRONT"};
  o.scene_duration_s = 2.5;  // exactly one 25-frame clip
  o.monst3r_outlier_fraction = 0.05;
  o.monst3r_pose_noise_deg = 0.5;
  const std::string root = test::MakeTempDir("synthetic_noise");
  const SyntheticDatasetSummary s = WriteSyntheticDataset(o, root);
  ASSERT_EQ(s.monst3r_clip_ids.size(), 1u);
  const std::string dir = root + "/monst3r/" + s.monst3r_clip_ids[0];
  const NpyArray conf = ReadNpy(dir + "/conf_10.npy");
  const NpyArray depth = ReadNpy(dir + "/frame_0010.npy");
  const NpyArray truth = ReadNpy(root + "/monst3r_gt/" + s.monst3r_clip_ids[0] +
                                 "/depth_0010.npy");
  std::ifstream gt_in(root + "/monst3r_gt/" + s.monst3r_clip_ids[0] + ".json");
  const double upm = json::parse(gt_in)["units_per_metre"];
  int64_t inf = 0, wrong_at_inf = 0;
  for (int64_t k = 0; k < conf.NumElements(); ++k) {
    const float c = conf.Data<float>()[k];
    const double z = truth.Data<float>()[k];
    if (std::isinf(c) && c < 0) {
      ++inf;
      if (z > 0 && std::abs(depth.Data<float>()[k] / upm - z) > 1e-3 * z)
        ++wrong_at_inf;
    } else if (z > 0) {
      ASSERT_NEAR(depth.Data<float>()[k] / upm, z,
                  1e-4 * z);  // no depth noise asked
    }
  }
  const double frac = static_cast<double>(inf) / conf.NumElements();
  std::cout << "outlier fraction " << frac
            << " (asked 0.05), wrong depth at -inf: " << wrong_at_inf << "/"
            << inf << "\n";
  EXPECT_NEAR(frac, 0.05, 0.005);
  EXPECT_GT(wrong_at_inf, inf / 2);
}

// Devkit conventions: Debian python (json + numpy) recomputes the camera's
// global pose and the boxes' projected corners from the JSON files; they match
// the C++ ground truth to 1e-6.
TEST_F(SyntheticDatasetTest, DevkitConventionsMatchGroundTruth) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("numpy");
  const int sample_index = 3;
  std::string out;
  const std::string cmd =
      std::string(test::kDebianPython) + " " + GEODRIVE_SOURCE_DIR +
      "/tests/dataset/devkit_check.py " + *root_ + " v1.0-mini scene-0002 " +
      std::to_string(sample_index) + " CAM_FRONT";
  ASSERT_EQ(test::RunCommand(cmd, &out), 0) << out;
  const json r = json::parse(out);
  const SyntheticDatasetOptions o = SmallOptions();
  const SyntheticWorld world(SyntheticWorldOptionsFor(o, 1));
  const SyntheticTimeline tl = MakeSyntheticTimeline(o, 1);
  const double t_cam = tl.Seconds(r["camera"]["timestamp"].get<int64_t>());
  const double t_sample = tl.Seconds(r["sample_timestamp"].get<int64_t>());
  const Rigid3d global_from_cam =
      world.GlobalFromEgo(t_cam) * SyntheticEgoFromSensor("CAM_FRONT");
  const Eigen::Matrix4d expected = global_from_cam.ToMatrix();
  double pose_err = 0;
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b)
      pose_err =
          std::max(pose_err,
                   std::abs(r["camera"]["global_from_cam"][a][b].get<double>() -
                            expected(a, b)));
  const PinholeCamera cam = SyntheticCameraIntrinsics("CAM_FRONT", 320, 180);
  double corner_err = 0;
  int boxes = 0;
  for (const auto& b : r["boxes"]) {
    const Eigen::Vector3d c(b["translation"][0], b["translation"][1],
                            b["translation"][2]);
    int id = -1;
    for (int v = 0; v < world.NumVehicles(); ++v)
      if ((world.Vehicle(v, t_sample).center - c).norm() < 1e-9) id = v;
    ASSERT_GE(id, 0) << "annotation matches no true vehicle";
    const VehicleBox box = world.Vehicle(id, t_sample);
    EXPECT_EQ(b["category_name"], box.category);
    const double l = box.size_wlh[1] / 2, w = box.size_wlh[0] / 2,
                 h = box.size_wlh[2] / 2;
    const double xs[8] = {l, l, l, l, -l, -l, -l, -l},
                 ys[8] = {w, -w, -w, w, w, -w, -w, w};
    const double zs[8] = {h, h, -h, -h, h, h, -h, -h};
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3d pc =
          global_from_cam.Inverse() *
          (box.center + box.rotation * Eigen::Vector3d(xs[k], ys[k], zs[k]));
      corner_err = std::max(
          corner_err, std::abs(pc.z() - b["corners_depth"][k].get<double>()));
      if (std::abs(pc.z()) < 0.1)
        continue;  // projection ill-conditioned at the camera plane
      const Eigen::Vector2d uv(cam.fx * pc.x() / pc.z() + cam.cx,
                               cam.fy * pc.y() / pc.z() + cam.cy);
      corner_err = std::max(
          corner_err, std::abs(uv.x() - b["corners_uv"][k][0].get<double>()));
      corner_err = std::max(
          corner_err, std::abs(uv.y() - b["corners_uv"][k][1].get<double>()));
    }
    ++boxes;
  }
  std::cout << "devkit recomputation: camera pose max error " << pose_err
            << ", " << boxes << " boxes, max corner error " << corner_err
            << " (px or m)\n";
  EXPECT_GT(boxes, 2);
  EXPECT_LT(pose_err, 1e-6);
  EXPECT_LT(corner_err, 1e-6);
}

TEST(SyntheticDatasetDeterminism, SameSeedGivesIdenticalBytes) {
  SyntheticDatasetOptions o = SmallOptions();
  o.num_scenes = 1;
  o.cameras = {"CAM_FRONT"};
  o.scene_duration_s = 2.5;
  o.image_width = 160;
  o.image_height = 90;
  o.monst3r_depth_noise = 0.01;
  o.monst3r_outlier_fraction = 0.01;
  const std::string a = test::MakeTempDir("synthetic_det_a"),
                    b = test::MakeTempDir("synthetic_det_b");
  WriteSyntheticDataset(o, a);
  WriteSyntheticDataset(o, b);
  int files = 0;
  for (const auto& e : fs::recursive_directory_iterator(a)) {
    if (!e.is_regular_file()) continue;
    const std::string rel = fs::relative(e.path(), a).string();
    std::ifstream fa(e.path(), std::ios::binary),
        fb(b + "/" + rel, std::ios::binary);
    ASSERT_TRUE(fb.good()) << rel;
    const std::string ca((std::istreambuf_iterator<char>(fa)), {});
    const std::string cb((std::istreambuf_iterator<char>(fb)), {});
    ASSERT_EQ(ca, cb) << rel << " differs";
    ++files;
  }
  EXPECT_GT(files, 200);
  // A different seed changes the data (tables suffice to see it).
  o.seed = 6;
  o.tables_only = true;
  o.write_monst3r = false;
  const std::string c = test::MakeTempDir("synthetic_det_c");
  WriteSyntheticDataset(o, c);
  std::ifstream fa(a + "/v1.0-mini/ego_pose.json"),
      fc(c + "/v1.0-mini/ego_pose.json");
  EXPECT_NE(std::string((std::istreambuf_iterator<char>(fa)), {}),
            std::string((std::istreambuf_iterator<char>(fc)), {}));
}

TEST(SyntheticDatasetOptionsTest, RejectsBadOptions) {
  SyntheticDatasetOptions o;
  EXPECT_TRUE(o.Check());
  o.cameras = {"CAM_TOP"};
  EXPECT_FALSE(o.Check());
  o = SyntheticDatasetOptions();
  o.version = "../x";
  EXPECT_FALSE(o.Check());
  o = SyntheticDatasetOptions();
  o.monst3r_clip_stride = 5;
  EXPECT_FALSE(o.Check());
  o = SyntheticDatasetOptions();
  o.write_monst3r = true;
  o.tables_only = true;
  EXPECT_THROW(WriteSyntheticDataset(o, test::MakeTempDir("synthetic_bad")),
               InputError);
}

TEST(SyntheticDatasetTablesOnly, WritesRowsWithoutFiles) {
  SyntheticDatasetOptions o;
  o.num_scenes = 3;
  o.tables_only = true;
  o.radars = true;
  o.cameras = {"CAM_FRONT", "CAM_FRONT_LEFT", "CAM_FRONT_RIGHT",
               "CAM_BACK",  "CAM_BACK_LEFT",  "CAM_BACK_RIGHT"};
  const std::string root = test::MakeTempDir("synthetic_tables_only");
  const SyntheticDatasetSummary s = WriteSyntheticDataset(o, root);
  // 20 s scenes: 40 samples; per scene 6 x 235 camera + 391 lidar + 5 x 254
  // radar rows.
  EXPECT_EQ(s.num_samples, 3 * 40);
  EXPECT_EQ(s.num_sample_data, 3 * (6 * 235 + 391 + 5 * 254));
  EXPECT_EQ(s.num_images, 0);
  EXPECT_FALSE(fs::exists(root + "/samples"));
  std::ifstream in(root + "/v1.0-mini/sample_data.json");
  EXPECT_EQ(json::parse(in).size(), static_cast<size_t>(s.num_sample_data));
}

}  // namespace
}  // namespace geodrive

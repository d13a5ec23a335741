// The rds-hq export read back as Cosmos-Drive-Dreams' render_from_rds_hq.py
// reads it (docs/reference/trainer-formats.md §3): one webdataset tar per
// field and clip, members <clip>.<key>, poses %06d.pose.<cam>.npy float64
// (4,4) for frames 0..N-1, intrinsics (6,) at 1280x720, LiDAR npz at every
// multiple of 3, an object JSON per frame, empty HD-map tars, the -cj lists;
// and its numbers against our pair and the synthetic world's exact ray
// casting: the poses are the pair's, the intrinsics ours at 1280x720, and a
// LiDAR return placed with lidar_to_world and projected with the exported
// camera lands on a pixel whose true depth is its camera z (unless something
// nearer hides it).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>

#include "dataset/build_dataset.h"
#include "dataset/drive_dataset.h"
#include "dataset/exporter.h"
#include "dataset/pairs.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "dataset/synthetic/synthetic_world.h"
#include "geometry/npy.h"
#include "geometry/npz.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace export_rds_hq_test {

namespace fs = std::filesystem;

constexpr int kFrames = 121, kWidth = 1280, kHeight = 720;
constexpr char kCamera[] = "camera_front_wide_120fov";

// One scene at the full 12 Hz camera rate, 10.5 s (one 121-frame clip),
// small images: the export writes no pixels, and the pair is built small.
const SyntheticDatasetOptions& WorldOptions() {
  static const SyntheticDatasetOptions o = [] {
    SyntheticDatasetOptions w;
    w.num_scenes = 1;
    w.seed = 7;
    w.image_width = 320;
    w.image_height = 180;
    w.scene_duration_s = 10.5;
    return w;
  }();
  return o;
}

const std::string& World() {
  static const std::string root =
      test::SharedFixtureDir("export_rds_hq_world", [](const std::string& dir) {
        WriteSyntheticDataset(WorldOptions(), dir);
      });
  return root;
}

constexpr char kClip[] = "scene-0001_0000";

BuildDatasetOptions Options(const std::string& out) {
  BuildDatasetOptions o;
  o.dataroot = World();
  o.geometry = "lidar";
  o.out = out;
  o.quiet = true;
  o.clip_frames = kFrames;
  o.clips = {kClip};
  o.width = 256;  // the pair's own size: rds-hq takes no pixels from it
  o.height = 144;
  o.exports = {ExportFormat::kRdsHq};
  return o;
}

const std::string& Export() {
  static const std::string out =
      test::SharedFixtureDir("export_rds_hq_out", [](const std::string& dir) {
        const BuildDatasetSummary s = BuildDataset(Options(dir));
        std::printf("rds-hq export: %s\n", s.BriefReport().c_str());
        EXPECT_EQ(s.built, 1) << test::ReadFile(dir + "/failures.jsonl");
      });
  return out;
}

DriveClip LoadClip() {
  DriveDatasetOptions dopt;
  dopt.root = World();
  dopt.clip_frames = kFrames;
  DriveClip clip = OpenDriveDataset(dopt)->LoadClip(kClip);
  EXPECT_EQ(clip.num_frames(), kFrames);
  return clip;
}

// The members of a tar (ustar, pax "path" records honoured), name -> bytes.
std::map<std::string, std::string> ReadTar(const std::string& path) {
  const std::string bytes = test::ReadFile(path);
  EXPECT_FALSE(bytes.empty()) << path;
  std::map<std::string, std::string> members;
  std::string pax_path;
  size_t at = 0;
  while (at + 512 <= bytes.size()) {
    const char* h = bytes.data() + at;
    if (std::all_of(h, h + 512, [](char c) { return c == 0; })) break;
    EXPECT_EQ(std::string(h + 257, 5), "ustar") << path;
    const size_t size = std::stoull(std::string(h + 124, 11), nullptr, 8);
    std::string name(h, strnlen(h, 100));
    const std::string data = bytes.substr(at + 512, size);
    at += 512 + (size + 511) / 512 * 512;
    if (h[156] == 'x') {
      const size_t p = data.find(" path=");
      pax_path = data.substr(p + 6, data.find('\n', p) - p - 6);
      continue;
    }
    if (!pax_path.empty()) name = pax_path, pax_path.clear();
    members[name] = data;
  }
  return members;
}

NpyArray MemberNpy(const std::map<std::string, std::string>& tar,
                   const std::string& name) {
  const auto it = tar.find(name);
  EXPECT_NE(it, tar.end()) << name;
  if (it == tar.end()) return {};
  return ParseNpy(name, reinterpret_cast<const uint8_t*>(it->second.data()),
                  it->second.size());
}

std::string Tar(const std::string& field) {
  return Export() + "/rds_hq/" + field + "/" + kClip + ".tar";
}

std::string Key(int frame) {
  char key[8];
  std::snprintf(key, sizeof(key), "%06d", frame);
  return key;
}

Eigen::Matrix4d Matrix(const double* rows) {
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i) m(i / 4, i % 4) = rows[i];
  return m;
}

// A short clip is refused with the 30 Hz requirement, per clip and up front;
// a clip id with a dot (webdataset's key separator) is refused.
TEST(ExportRdsHq, ShortClipsAndDottedIdsAreRefusedNamingTheRequirement) {
  EXPECT_EQ(ParseExportFormat("rds-hq"), ExportFormat::kRdsHq);
  EXPECT_EQ(ToString(ExportFormat::kRdsHq), "rds-hq");
  const auto exporter = CreateExporter(ExportFormat::kRdsHq);
  EXPECT_NO_THROW(exporter->CheckClip("c", 121));
  EXPECT_NO_THROW(exporter->CheckClip("c", 150));
  try {
    exporter->CheckClip("scene-0001_0000", 120);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(),
                 "scene-0001_0000: rds-hq needs 121 frames at 30 Hz; this "
                 "clip has 120");
  }
  try {
    exporter->CheckClip("clip.v2", 121);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "clip.v2: rds-hq needs a clip id without '.'"),
              std::string::npos)
        << e.what();
  }
  BuildDatasetOptions o = Options("/tmp/unused");
  o.clip_frames = 25;
  try {
    o.Check();
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "--export rds-hq needs 121 frames per clip; --clip-frames "
                  "is 25"),
              std::string::npos)
        << e.what();
  }
}

// The Python mirror of the renderer's reading (tarfile grouped as
// webdataset, tests/dataset/rds_hq_loader_check.py): member names, keys,
// dtypes and shapes, the LiDAR and object keys every render frame reaches,
// the HD-map tars, the -cj lists.
TEST(ExportRdsHq, PythonMirrorOfTheRendererAcceptsIt) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("numpy");
  std::string log;
  EXPECT_EQ(
      test::RunCommand(
          std::string(test::kDebianPython) +
              " " GEODRIVE_SOURCE_DIR "/tests/dataset/rds_hq_loader_check.py " +
              Export() + "/rds_hq " + kClip + " " + std::to_string(kFrames),
          &log),
      0)
      << log;
  std::printf("%s", log.c_str());
}

// pose[t] = the pair's world_from_cam[t] (float64: to 1e-12), intrinsics =
// the source camera centre-cropped and scaled to 1280x720.
TEST(ExportRdsHq, PosesAreOursAndIntrinsicsAtTheExportSize) {
  const auto poses = ReadTar(Tar("pose"));
  ASSERT_EQ(poses.size(), static_cast<size_t>(kFrames));
  const PairMeta meta = ReadPairMeta(Export() + "/pairs/" + kClip);
  ASSERT_EQ(meta.world_from_cam.size(), static_cast<size_t>(kFrames));
  double worst = 0;
  for (int t = 0; t < kFrames; ++t) {
    const NpyArray a = MemberNpy(
        poses, std::string(kClip) + "." + Key(t) + ".pose." + kCamera + ".npy");
    ASSERT_EQ(a.dtype, NpyDtype::kFloat64);
    ASSERT_EQ(a.shape, (std::vector<int64_t>{4, 4}));
    const Eigen::Matrix4d got = Matrix(a.Data<double>());
    worst = std::max(
        worst, (got - meta.world_from_cam[t].ToMatrix()).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(worst, 1e-12);
  const auto intr = ReadTar(Tar("pinhole_intrinsic"));
  ASSERT_EQ(intr.size(), 1u);
  const NpyArray k = MemberNpy(
      intr, std::string(kClip) + ".pinhole_intrinsic." + kCamera + ".npy");
  ASSERT_EQ(k.dtype, NpyDtype::kFloat64);
  ASSERT_EQ(k.shape, (std::vector<int64_t>{6}));
  const DriveClip clip = LoadClip();
  const PinholeCamera& full = clip.frames.front().camera;
  const PinholeCamera want = ApplyResizeSpec(
      full, ComputeResizeSpec(full.width, full.height, kWidth, kHeight,
                              ResizeMode::kCenterCrop));
  const double* v = k.Data<double>();
  EXPECT_NEAR(v[0], want.fx, 1e-9);
  EXPECT_NEAR(v[1], want.fy, 1e-9);
  EXPECT_NEAR(v[2], want.cx, 1e-9);
  EXPECT_NEAR(v[3], want.cy, 1e-9);
  EXPECT_EQ(v[4], kWidth);
  EXPECT_EQ(v[5], kHeight);
}

// LiDAR returns of the sweeps at frames 0, 60, 120 (lidar_to_world @ xyz,
// the renderer's 3 m cut) projected with the exported pose and intrinsics:
// the true depth through that pixel at the sweep's time (the synthetic
// world's ray cast) equals the point's camera z (1e-3 relative) for most of
// them, and is never beyond it (a nearer surface may hide a return, nothing
// shows through it).
TEST(ExportRdsHq, LidarReturnsProjectWhereTheWorldSays) {
  const auto lidar = ReadTar(Tar("lidar_raw"));
  const auto poses = ReadTar(Tar("pose"));
  const auto intr = ReadTar(Tar("pinhole_intrinsic"));
  for (int f = 0; f < kFrames; f += 3)
    EXPECT_TRUE(
        lidar.count(std::string(kClip) + "." + Key(f) + ".lidar_raw.npz"))
        << f;
  const DriveClip clip = LoadClip();
  const SyntheticWorld world(SyntheticWorldOptionsFor(WorldOptions(), 0));
  const SyntheticTimeline tl = MakeSyntheticTimeline(WorldOptions(), 0);
  const Rigid3d world_from_export = clip.frames.front().world_from_cam;
  const NpyArray k = MemberNpy(
      intr, std::string(kClip) + ".pinhole_intrinsic." + kCamera + ".npy");
  const double* kv = k.Data<double>();
  PinholeCamera cam;
  cam.fx = kv[0], cam.fy = kv[1], cam.cx = kv[2], cam.cy = kv[3];
  cam.width = kWidth, cam.height = kHeight;
  const std::string scratch = test::MakeTempDir("rds_hq_npz") + "/x.npz";
  int seen = 0, exact = 0, through = 0;
  for (const int t : {0, 60, 120}) {
    test::WriteFile(scratch, lidar.at(std::string(kClip) + "." + Key(t) +
                                      ".lidar_raw.npz"));
    const NpzReader npz(scratch);
    EXPECT_EQ(npz.Keys(), (std::vector<std::string>{"xyz", "lidar_to_world"}));
    const NpyArray xyz = npz.Read("xyz");
    const NpyArray l2w = npz.Read("lidar_to_world");
    ASSERT_EQ(xyz.dtype, NpyDtype::kFloat32);
    ASSERT_EQ(l2w.dtype, NpyDtype::kFloat64);
    ASSERT_EQ(xyz.shape.size(), 2u);
    ASSERT_EQ(xyz.shape[1], 3);
    const Eigen::Matrix4d lidar_to_world = Matrix(l2w.Data<double>());
    const Eigen::Matrix4d w2c =
        Matrix(MemberNpy(poses, std::string(kClip) + "." + Key(t) + ".pose." +
                                    kCamera + ".npy")
                   .Data<double>())
            .inverse();
    const Rigid3d global_from_cam =
        world_from_export * Rigid3d::FromMatrix(w2c.inverse(), /*tol=*/1e-9);
    // The export's sweep: the keyframe's own, else the nearest.
    const size_t sweep = clip.frames[t].keyframe_sweep.value_or(
        *clip.lidar->Nearest(clip.frames[t].timestamp_us));
    const double time = tl.Seconds(clip.lidar->Sweeps()[sweep].timestamp_us);
    const float* p = xyz.Data<float>();
    for (int64_t i = 0; i < xyz.shape[0]; i += 3) {
      const Eigen::Vector3d s(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
      if (s.norm() < 3.0) continue;  // render_from_rds_hq.py:336-341
      const Eigen::Vector3d c =
          (w2c * (lidar_to_world * s.homogeneous())).head<3>();
      if (c.z() < 1.0) continue;
      const Eigen::Vector2d px(cam.fx * c.x() / c.z() + cam.cx,
                               cam.fy * c.y() / c.z() + cam.cy);
      if (px.x() < 0 || px.y() < 0 || px.x() > kWidth - 1 ||
          px.y() > kHeight - 1)
        continue;
      const double z = world.CameraDepthAt(cam, global_from_cam, time, px);
      ++seen;
      if (std::abs(z - c.z()) < 1e-3 * c.z()) ++exact;
      if (z > c.z() * (1 + 1e-3) || z == 0) ++through;
    }
  }
  std::printf(
      "%d LiDAR returns in view: %.1f %% at the true depth, %.2f %% seen "
      "through\n",
      seen, 100.0 * exact / std::max(1, seen),
      100.0 * through / std::max(1, seen));
  ASSERT_GT(seen, 1500);
  EXPECT_GT(exact, 0.8 * seen);
  EXPECT_LT(through, 0.01 * seen);
}

// Every frame has an object JSON whose tracks are the clip's boxes of the
// four renderer types, with the dataset's instance ids, lwh = the box's
// (l, w, h) and object_to_world = the box moved into the export's world.
TEST(ExportRdsHq, ObjectsAreTheClipsBoxesInTheExportWorld) {
  const auto tar = ReadTar(Tar("all_object_info"));
  ASSERT_EQ(tar.size(), static_cast<size_t>(kFrames));
  const DriveClip clip = LoadClip();
  const Rigid3d export_from_world =
      clip.frames.front().world_from_cam.Inverse();
  int boxes = 0, moving = 0;
  for (int t = 0; t < kFrames; ++t) {
    const nlohmann::json j = nlohmann::json::parse(
        tar.at(std::string(kClip) + "." + Key(t) + ".all_object_info.json"));
    int expected = 0;
    for (const ClipBox& b : clip.frames[t].boxes) {
      if (b.category.rfind("vehicle.", 0) != 0 &&
          b.category.rfind("human.pedestrian.", 0) != 0)
        continue;
      ++expected;
      ASSERT_TRUE(j.contains(b.instance_id)) << t << " " << b.instance_id;
      const nlohmann::json& o = j[b.instance_id];
      EXPECT_EQ(o["object_lwh"][0].get<double>(), b.box.size.y());
      EXPECT_EQ(o["object_lwh"][1].get<double>(), b.box.size.x());
      EXPECT_EQ(o["object_lwh"][2].get<double>(), b.box.size.z());
      Eigen::Matrix4d m;
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) m(r, c) = o["object_to_world"][r][c];
      const Eigen::Matrix4d want =
          (export_from_world * b.box.WorldFromBox()).ToMatrix();
      EXPECT_LT((m - want).cwiseAbs().maxCoeff(), 1e-9) << t;
      const std::string type = o["object_type"];
      EXPECT_TRUE(type == "Car" || type == "Truck" || type == "Pedestrian" ||
                  type == "Cyclist")
          << type;
      moving += o["object_is_moving"].get<bool>();
      ++boxes;
    }
    EXPECT_EQ(static_cast<int>(j.size()), expected) << t;
  }
  std::printf("%d boxes over %d frames, %d moving\n", boxes, kFrames, moving);
  EXPECT_GT(boxes, kFrames);
  EXPECT_GT(moving, 0);
}

// `geodrive export --format rds-hq` on a pair built without --export writes
// the same bytes as build-dataset --export rds-hq.
TEST(ExportRdsHq, ExportingBuiltPairsGivesTheSameFiles) {
  const std::string out = test::MakeTempDir("export_rds_hq_later");
  BuildDatasetOptions o = Options(out);
  o.exports.clear();
  ASSERT_EQ(BuildDataset(o).built, 1);
  EXPECT_EQ(ExportPairs(out, {ExportFormat::kRdsHq}, o.export_options,
                        /*quiet=*/true),
            1);
  int fields = 0;
  for (const auto& e : fs::directory_iterator(Export() + "/rds_hq")) {
    if (!e.is_directory()) continue;
    const std::string field = e.path().filename().string();
    const std::string got =
        test::ReadFile(out + "/rds_hq/" + field + "/" + kClip + ".tar");
    EXPECT_GT(got.size(), 0u) << field;
    EXPECT_TRUE(got == test::ReadFile(Tar(field))) << field;
    ++fields;
  }
  EXPECT_EQ(fields, 12);
  EXPECT_EQ(test::ReadFile(out + "/rds_hq/clips_train.json"),
            test::ReadFile(Export() + "/rds_hq/clips_train.json"));
  EXPECT_EQ(ReadPairMeta(out + "/pairs/" + kClip).files.at("rds_hq"), "rds_hq");
}

// The real scene-0916 as keyframes (41 frames, the whole scene) is refused
// with the 30 Hz requirement: up front for --clip-frames 41, and per clip.
TEST(ExportRdsHq, RealScene0916KeyframeClipIsRefused) {
  const std::string root = test::RealDataPath("nuscenes_scene0916");
  ASSERT_TRUE(fs::is_directory(root)) << "real data missing: " << root;
  BuildDatasetOptions o;
  o.dataroot = root;
  o.version = "v1.0-mini-extract";
  o.frames = ClipFrameSource::kKeyframes;
  o.geometry = "lidar";
  o.out = test::MakeTempDir("export_rds_hq_real");
  o.quiet = true;
  o.clip_frames = 41;
  o.exports = {ExportFormat::kRdsHq};
  try {
    o.Check();
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "--export rds-hq needs 121 frames per clip; --clip-frames "
                  "is 41"),
              std::string::npos)
        << e.what();
  }
  DriveDatasetOptions dopt;
  dopt.root = root;
  dopt.version = o.version;
  dopt.frames = ClipFrameSource::kKeyframes;
  dopt.clip_frames = 41;
  const std::unique_ptr<DriveDataset> dataset = OpenDriveDataset(dopt);
  ASSERT_EQ(dataset->ClipIds().size(), 1u);
  const DriveClip clip = dataset->LoadClip(dataset->ClipIds().front());
  ASSERT_EQ(clip.num_frames(), 41);
  try {
    CreateExporter(ExportFormat::kRdsHq)->CheckClip(clip.id, clip.num_frames());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              clip.id + ": rds-hq needs 121 frames at 30 Hz; this clip has 41");
  }
}

// The six-camera layout: a synthetic six-camera rig (built with --cameras
// all) exports as rds_hq_mv's six cameras, each camera's 121 poses the rig
// view's (to 1e-12) and its intrinsics the view's camera at 1280x720; the
// renderer's mirror reads it with the rds_hq_mv config and finds LiDAR
// returns in view of every camera.
TEST(ExportRdsHqRig, SixCamerasAsRdsHqMv) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("numpy");
  const std::string out =
      test::SharedFixtureDir("export_rds_hq_rig", [](const std::string& dir) {
        SyntheticDatasetOptions w = WorldOptions();
        w.image_width = 160;
        w.image_height = 90;
        w.cameras = {"CAM_FRONT",     "CAM_FRONT_LEFT", "CAM_FRONT_RIGHT",
                     "CAM_BACK_LEFT", "CAM_BACK_RIGHT", "CAM_BACK"};
        WriteSyntheticDataset(w, dir + "/world");
        BuildDatasetOptions o = Options(dir + "/out");
        o.dataroot = dir + "/world";
        o.cameras = {"all"};
        o.width = 128;
        o.height = 72;
        const BuildDatasetSummary s = BuildDataset(o);
        EXPECT_EQ(s.built, 1) << test::ReadFile(dir + "/out/failures.jsonl");
      });
  const std::string root = out + "/out/rds_hq";
  const std::map<std::string, std::string> name_of = {
      {"CAM_FRONT", "camera_front_wide_120fov"},
      {"CAM_FRONT_LEFT", "camera_cross_left_120fov"},
      {"CAM_FRONT_RIGHT", "camera_cross_right_120fov"},
      {"CAM_BACK_LEFT", "camera_rear_left_70fov"},
      {"CAM_BACK_RIGHT", "camera_rear_right_70fov"},
      {"CAM_BACK", "camera_rear_tele_30fov"}};
  const PairMeta meta = ReadPairMeta(out + "/out/pairs/" + kClip);
  ASSERT_EQ(meta.views.size(), 6u);
  DriveDatasetOptions dopt;
  dopt.root = out + "/world";
  dopt.clip_frames = kFrames;
  dopt.cameras = {"all"};
  const DriveClip clip = OpenDriveDataset(dopt)->LoadClip(kClip);
  ASSERT_EQ(clip.num_views(), 6);
  const auto poses = ReadTar(root + "/pose/" + kClip + ".tar");
  const auto intr = ReadTar(root + "/pinhole_intrinsic/" + kClip + ".tar");
  EXPECT_EQ(poses.size(), 6u * kFrames);
  EXPECT_EQ(intr.size(), 6u);
  double worst_pose = 0, worst_k = 0;
  for (size_t v = 0; v < meta.views.size(); ++v) {
    const PairView& view = meta.views[v];
    ASSERT_EQ(clip.View(static_cast<int>(v)).channel, view.channel);
    const std::string cam = name_of.at(view.channel);
    ASSERT_EQ(view.world_from_cam.size(), static_cast<size_t>(kFrames));
    for (int t = 0; t < kFrames; ++t) {
      const NpyArray a = MemberNpy(
          poses, std::string(kClip) + "." + Key(t) + ".pose." + cam + ".npy");
      ASSERT_EQ(a.shape, (std::vector<int64_t>{4, 4})) << cam;
      worst_pose = std::max(worst_pose, (Matrix(a.Data<double>()) -
                                         view.world_from_cam[t].ToMatrix())
                                            .cwiseAbs()
                                            .maxCoeff());
    }
    const PinholeCamera full =
        clip.View(static_cast<int>(v)).frames.front().camera;
    const PinholeCamera want = ApplyResizeSpec(
        full, ComputeResizeSpec(full.width, full.height, kWidth, kHeight,
                                ResizeMode::kCenterCrop));
    const NpyArray k = MemberNpy(
        intr, std::string(kClip) + ".pinhole_intrinsic." + cam + ".npy");
    ASSERT_EQ(k.shape, (std::vector<int64_t>{6})) << cam;
    const double* kv = k.Data<double>();
    worst_k = std::max({worst_k, std::abs(kv[0] - want.fx),
                        std::abs(kv[1] - want.fy), std::abs(kv[2] - want.cx),
                        std::abs(kv[3] - want.cy)});
    EXPECT_EQ(kv[4], kWidth);
    EXPECT_EQ(kv[5], kHeight);
  }
  std::printf(
      "six cameras: poses within %.2g of the views', intrinsics within "
      "%.2g px\n",
      worst_pose, worst_k);
  EXPECT_LT(worst_pose, 1e-12);
  EXPECT_LT(worst_k, 1e-9);
  std::string log;
  EXPECT_EQ(
      test::RunCommand(
          std::string(test::kDebianPython) +
              " " GEODRIVE_SOURCE_DIR "/tests/dataset/rds_hq_loader_check.py " +
              root + " " + kClip + " " + std::to_string(kFrames) +
              " rds_hq_mv",
          &log),
      0)
      << log;
  std::printf("%s", log.c_str());
}

// A rig without the six nuScenes cameras (here two of them) has no
// rds_hq_mv layout: the clip is refused naming the six.
TEST(ExportRdsHqRig, OtherRigsAreRefusedNamingTheSixCameras) {
  const std::unique_ptr<Exporter> e = CreateExporter(ExportFormat::kRdsHq);
  EXPECT_TRUE(e->WritesRigs());
  std::vector<ExportClip> views(2);
  views[0].clip_id = views[1].clip_id = kClip;
  views[0].channel = "CAM_FRONT";
  views[1].channel = "CAM_BACK";
  PairMeta meta;
  try {
    e->WriteRig(views, test::MakeTempDir("rds_hq_two_cameras"), &meta);
    ADD_FAILURE() << "a two-camera rig was accepted";
  } catch (const InputError& err) {
    EXPECT_EQ(std::string(err.what()),
              std::string(kClip) +
                  ": rds-hq's six-camera layout (the rds_hq_mv config) needs "
                  "the six nuScenes cameras CAM_FRONT,CAM_FRONT_LEFT,"
                  "CAM_FRONT_RIGHT,CAM_BACK_LEFT,CAM_BACK_RIGHT,CAM_BACK; "
                  "this rig has CAM_FRONT,CAM_BACK");
  }
}

}  // namespace export_rds_hq_test
}  // namespace geodrive

// The drivestudio export read back as drivestudio's nuScenes loader reads it
// (docs/reference/trainer-formats.md §4): per frame the image, the sky and
// dynamic masks, the extrinsics, the LiDAR and its pose; the intrinsics at
// 1600x900; the instances; and its numbers against our pair and the
// synthetic world's exact ray casting: the extrinsics are the pair's poses,
// the intrinsics ours at 1600x900, a LiDAR return placed with lidar_pose and
// projected with the exported camera lands on a pixel whose true depth is its
// camera z, the sky mask covers only true sky, the vehicle mask covers the
// pixels of every vehicle wholly in view. The real scene-0916 (41 keyframes)
// exports and reads back too.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "dataset/build_dataset.h"
#include "dataset/drive_dataset.h"
#include "dataset/exporter.h"
#include "dataset/pairs.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "dataset/synthetic/synthetic_world.h"
#include "geometry/image_io.h"
#include "geometry/util/status.h"
#include "render/boxes.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace export_drivestudio_test {

namespace fs = std::filesystem;

constexpr int kFrames = 13, kWidth = 1600, kHeight = 900;

// One scene at the full 12 Hz camera rate, 3 s (a 13-frame clip), small
// images (the export writes its images at 1600x900 whatever the source).
const SyntheticDatasetOptions& WorldOptions() {
  static const SyntheticDatasetOptions o = [] {
    SyntheticDatasetOptions w;
    w.num_scenes = 1;
    w.seed = 7;
    w.image_width = 320;
    w.image_height = 180;
    w.scene_duration_s = 3;
    return w;
  }();
  return o;
}

const std::string& World() {
  static const std::string root = test::SharedFixtureDir(
      "export_drivestudio_world", [](const std::string& dir) {
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
  o.width = 256;  // the pair's own size; the export writes 1600x900
  o.height = 144;
  o.exports = {ExportFormat::kDrivestudio};
  return o;
}

const std::string& Export() {
  static const std::string out = test::SharedFixtureDir(
      "export_drivestudio_out", [](const std::string& dir) {
        const BuildDatasetSummary s = BuildDataset(Options(dir));
        std::printf("drivestudio export: %s\n", s.BriefReport().c_str());
        EXPECT_EQ(s.built, 1) << test::ReadFile(dir + "/failures.jsonl");
      });
  return out;
}

// A drivestudio export of the real scene-0916's keyframes, clips of
// `frames`, into `dir`.
BuildDatasetOptions RealOptions(const std::string& dir, int frames) {
  BuildDatasetOptions o;
  o.dataroot = test::RealDataPath("nuscenes_scene0916");
  o.version = "v1.0-mini-extract";
  o.frames = ClipFrameSource::kKeyframes;
  o.geometry = "lidar";
  o.out = dir;
  o.quiet = true;
  o.clip_frames = frames;
  o.width = 256;
  o.height = 144;
  o.exports = {ExportFormat::kDrivestudio};
  return o;
}

// The real scene-0916, its 41 keyframes as one clip.
const std::string& RealExport() {
  static const std::string out = test::SharedFixtureDir(
      "export_drivestudio_real", [](const std::string& dir) {
        const BuildDatasetOptions o = RealOptions(dir, 41);
        const BuildDatasetSummary s = BuildDataset(o);
        std::printf("drivestudio export of scene-0916: %s\n",
                    s.BriefReport().c_str());
        EXPECT_EQ(s.built, 1) << test::ReadFile(dir + "/failures.jsonl");
      });
  return out;
}

std::string SceneDir() { return Export() + "/drivestudio/000"; }

DriveClip LoadClip() {
  DriveDatasetOptions dopt;
  dopt.root = World();
  dopt.clip_frames = kFrames;
  DriveClip clip = OpenDriveDataset(dopt)->LoadClip(kClip);
  EXPECT_EQ(clip.num_frames(), kFrames);
  return clip;
}

std::vector<double> ReadNumbers(const std::string& path) {
  std::istringstream in(test::ReadFile(path));
  std::vector<double> v;
  double x;
  while (in >> x) v.push_back(x);
  return v;
}

Eigen::Matrix4d ReadMatrix(const std::string& path) {
  const std::vector<double> v = ReadNumbers(path);
  EXPECT_EQ(v.size(), 16u) << path;
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  for (size_t i = 0; i < std::min<size_t>(16, v.size()); ++i)
    m(i / 4, i % 4) = v[i];
  return m;
}

std::string Name(int t) {
  char name[16];
  std::snprintf(name, sizeof(name), "%03d", t);
  return name;
}

PinholeCamera ExportedCamera(const std::string& dir) {
  const std::vector<double> k = ReadNumbers(dir + "/intrinsics/0.txt");
  EXPECT_EQ(k.size(), 9u);
  return PinholeCamera(k[0], k[1], k[2], k[3], kWidth, kHeight);
}

TEST(ExportDrivestudio, FormatNameParses) {
  EXPECT_EQ(ParseExportFormat("drivestudio"), ExportFormat::kDrivestudio);
  EXPECT_EQ(ToString(ExportFormat::kDrivestudio), "drivestudio");
  const ExportRequirements req =
      CreateExporter(ExportFormat::kDrivestudio)->Requirements();
  EXPECT_EQ(req.width, kWidth);
  EXPECT_EQ(req.height, kHeight);
}

// The Python mirror of the loader (NumPy and cv2,
// tests/dataset/drivestudio_loader_check.py) on the synthetic clip and on
// the real scene-0916 (41 keyframes; its pedestrians fill the human masks).
TEST(ExportDrivestudio, PythonMirrorOfTheLoaderAcceptsIt) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("cv2");
  GEODRIVE_REQUIRE_PYTHON_MODULE("numpy");
  const std::string script = std::string(test::kDebianPython) +
                             " " GEODRIVE_SOURCE_DIR
                             "/tests/dataset/drivestudio_loader_check.py ";
  std::string log;
  EXPECT_EQ(test::RunCommand(
                script + SceneDir() + " 0 " + std::to_string(kFrames), &log),
            0)
      << log;
  std::printf("synthetic: %s", log.c_str());
  EXPECT_EQ(
      test::RunCommand(script + RealExport() + "/drivestudio/000 0 41", &log),
      0)
      << log;
  std::printf("scene-0916: %s", log.c_str());
  const nlohmann::json scenes = nlohmann::json::parse(
      test::ReadFile(RealExport() + "/drivestudio/scenes.json"));
  EXPECT_EQ(scenes.size(), 1u);
  EXPECT_TRUE(fs::is_directory(RealExport() + "/drivestudio/000/images"));
}

// extrinsics[t] = the pair's world_from_cam[t]; intrinsics = the source
// camera centre-cropped and scaled to 1600x900 (the real scene's own
// 1600x900 camera unchanged).
TEST(ExportDrivestudio, CamerasAreOursAtTheExportSize) {
  const PairMeta meta = ReadPairMeta(Export() + "/pairs/" + kClip);
  double worst = 0;
  for (int t = 0; t < kFrames; ++t) {
    const Eigen::Matrix4d got =
        ReadMatrix(SceneDir() + "/extrinsics/" + Name(t) + "_0.txt");
    worst = std::max(
        worst, (got - meta.world_from_cam[t].ToMatrix()).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(worst, 1e-12);
  const DriveClip clip = LoadClip();
  const PinholeCamera& full = clip.frames.front().camera;
  const PinholeCamera want = ApplyResizeSpec(
      full, ComputeResizeSpec(full.width, full.height, kWidth, kHeight,
                              ResizeMode::kCenterCrop));
  const PinholeCamera got = ExportedCamera(SceneDir());
  EXPECT_NEAR(got.fx, want.fx, 1e-9);
  EXPECT_NEAR(got.fy, want.fy, 1e-9);
  EXPECT_NEAR(got.cx, want.cx, 1e-9);
  EXPECT_NEAR(got.cy, want.cy, 1e-9);
  const std::string real = RealExport() + "/drivestudio/000";
  const PairMeta real_meta =
      ReadPairMeta(RealExport() + "/pairs/" +
                   nlohmann::json::parse(test::ReadFile(
                       RealExport() + "/drivestudio/scenes.json"))["000"]
                       .get<std::string>());
  DriveDatasetOptions dopt;
  dopt.root = test::RealDataPath("nuscenes_scene0916");
  dopt.version = "v1.0-mini-extract";
  dopt.frames = ClipFrameSource::kKeyframes;
  dopt.clip_frames = 41;
  const DriveClip real_clip =
      OpenDriveDataset(dopt)->LoadClip(real_meta.clip_id);
  const PinholeCamera& nusc = real_clip.frames.front().camera;
  ASSERT_EQ(nusc.width, kWidth);
  const PinholeCamera real_got = ExportedCamera(real);
  EXPECT_NEAR(real_got.fx, nusc.fx, 1e-9);
  EXPECT_NEAR(real_got.cx, nusc.cx, 1e-9);
  EXPECT_NEAR(real_got.cy, nusc.cy, 1e-9);
  const cv::Mat image = ReadImageRgb(real + "/images/040_0.jpg");
  EXPECT_EQ(image.cols, kWidth);
  EXPECT_EQ(image.rows, kHeight);
  // The real cameras are 1600x900: every image is the source JPEG's bytes.
  // The synthetic ones (320x180) are decoded, scaled up and encoded.
  ASSERT_EQ(real_clip.num_frames(), 41);
  for (int t = 0; t < 41; ++t) {
    EXPECT_EQ(test::ReadFile(real + "/images/" + Name(t) + "_0.jpg"),
              test::ReadFile(real_clip.frames[t].image_path))
        << "frame " << t;
  }
  const cv::Mat synthetic = ReadImageRgb(SceneDir() + "/images/000_0.jpg");
  EXPECT_EQ(synthetic.size(), cv::Size(kWidth, kHeight));
}

// A six-camera rig (build-dataset --cameras all): one scene folder, each
// camera under drivestudio's index of its channel (CAM_FRONT 0,
// CAM_FRONT_LEFT 1, CAM_FRONT_RIGHT 2, CAM_BACK_LEFT 3, CAM_BACK_RIGHT 4,
// CAM_BACK 5), its extrinsics the pair view's poses in the rig's frame, its
// intrinsics the view's camera at 1600x900; the Python mirror reads all six
// (every LiDAR return in view of any camera off its sky mask).
constexpr int kRigFrames = 5;  // six cameras' frames at 1600x900 each
TEST(ExportDrivestudio, RigWritesEveryCameraUnderItsIndex) {
  const std::string out = test::SharedFixtureDir(
      "export_drivestudio_rig", [](const std::string& dir) {
        SyntheticDatasetOptions w = WorldOptions();
        w.cameras = {"CAM_FRONT",     "CAM_FRONT_LEFT", "CAM_FRONT_RIGHT",
                     "CAM_BACK_LEFT", "CAM_BACK_RIGHT", "CAM_BACK"};
        WriteSyntheticDataset(w, dir + "/world");
        BuildDatasetOptions o = Options(dir + "/out");
        o.dataroot = dir + "/world";
        o.cameras = {"all"};
        o.clip_frames = kRigFrames;
        const BuildDatasetSummary s = BuildDataset(o);
        EXPECT_EQ(s.built, 1) << test::ReadFile(dir + "/out/failures.jsonl");
      });
  const std::string scene = out + "/out/drivestudio/000";
  const PairMeta meta = ReadPairMeta(out + "/out/pairs/" + kClip);
  ASSERT_EQ(meta.views.size(), 6u);
  const char* const order[] = {"CAM_FRONT",       "CAM_FRONT_LEFT",
                               "CAM_FRONT_RIGHT", "CAM_BACK_LEFT",
                               "CAM_BACK_RIGHT",  "CAM_BACK"};
  DriveDatasetOptions dopt;
  dopt.root = out + "/world";
  dopt.clip_frames = kRigFrames;
  dopt.cameras = {"all"};
  const DriveClip clip = OpenDriveDataset(dopt)->LoadClip(kClip);
  ASSERT_EQ(clip.num_views(), 6);
  double worst_pose = 0, worst_k = 0;
  for (size_t v = 0; v < meta.views.size(); ++v) {
    const PairView& view = meta.views[v];
    const int index = static_cast<int>(
        std::find(std::begin(order), std::end(order), view.channel) -
        std::begin(order));
    ASSERT_LT(index, 6) << view.channel;
    for (int t = 0; t < kRigFrames; ++t) {
      const Eigen::Matrix4d got =
          ReadMatrix(scene + "/extrinsics/" + Name(t) + "_" +
                     std::to_string(index) + ".txt");
      worst_pose = std::max(
          worst_pose,
          (got - view.world_from_cam[t].ToMatrix()).cwiseAbs().maxCoeff());
    }
    const PinholeCamera full =
        clip.View(static_cast<int>(v)).frames.front().camera;
    const PinholeCamera want = ApplyResizeSpec(
        full, ComputeResizeSpec(full.width, full.height, kWidth, kHeight,
                                ResizeMode::kCenterCrop));
    const std::vector<double> k =
        ReadNumbers(scene + "/intrinsics/" + std::to_string(index) + ".txt");
    ASSERT_EQ(k.size(), 9u);
    worst_k =
        std::max({worst_k, std::abs(k[0] - want.fx), std::abs(k[1] - want.fy),
                  std::abs(k[2] - want.cx), std::abs(k[3] - want.cy)});
  }
  std::printf(
      "six cameras: extrinsics within %.2g of the views' poses, "
      "intrinsics within %.2g px\n",
      worst_pose, worst_k);
  EXPECT_LT(worst_pose, 1e-12);
  EXPECT_LT(worst_k, 1e-9);
  EXPECT_TRUE(ReadMatrix(scene + "/extrinsics/000_0.txt")
                  .isApprox(Eigen::Matrix4d::Identity(), 1e-12));
  GEODRIVE_REQUIRE_PYTHON_MODULE("cv2");
  std::string log;
  EXPECT_EQ(
      test::RunCommand(std::string(test::kDebianPython) +
                           " " GEODRIVE_SOURCE_DIR
                           "/tests/dataset/drivestudio_loader_check.py " +
                           scene + " 0,1,2,3,4,5 " + std::to_string(kRigFrames),
                       &log),
      0)
      << log;
  std::printf("synthetic rig: %s", log.c_str());
}

// The single-camera formats (all but drivestudio and rds-hq): with
// --cameras the options are refused before anything is built, naming the
// format.
TEST(ExportDrivestudio, SingleCameraFormatsRefuseARig) {
  BuildDatasetOptions o = Options("unused");
  o.cameras = {"all"};
  EXPECT_NO_THROW(o.Check());
  o.exports = {ExportFormat::kDrivestudio, ExportFormat::kStreetCrafter};
  try {
    o.Check();
    ADD_FAILURE() << "streetcrafter with --cameras was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--export streetcrafter is "
                                         "single-camera"),
              std::string::npos)
        << e.what();
  }
}

// The real scene-0916's six cameras, its first 9 keyframes: the Python
// mirror reads every camera; every image is its source JPEG.
TEST(ExportDrivestudio, RealScene0916RigReadsBackInSixCameras) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("cv2");
  const std::string out = test::SharedFixtureDir(
      "export_drivestudio_real_rig", [](const std::string& dir) {
        BuildDatasetOptions o = RealOptions(dir, 9);
        o.max_clips = 1;
        o.cameras = {"all"};
        const BuildDatasetSummary s = BuildDataset(o);
        EXPECT_EQ(s.built, 1) << test::ReadFile(dir + "/failures.jsonl");
      });
  const std::string scene = out + "/drivestudio/000";
  std::string log;
  EXPECT_EQ(test::RunCommand(std::string(test::kDebianPython) +
                                 " " GEODRIVE_SOURCE_DIR
                                 "/tests/dataset/drivestudio_loader_check.py " +
                                 scene + " 0,1,2,3,4,5 9",
                             &log),
            0)
      << log;
  std::printf("scene-0916 rig: %s", log.c_str());
  const PairMeta meta =
      ReadPairMeta(out + "/pairs/" +
                   nlohmann::json::parse(
                       test::ReadFile(out + "/drivestudio/scenes.json"))["000"]
                       .get<std::string>());
  ASSERT_EQ(meta.views.size(), 6u);
  // CAM_BACK is drivestudio's camera 5: its images are its own JPEGs.
  for (const PairView& v : meta.views) {
    if (v.channel != "CAM_BACK") continue;
    EXPECT_EQ(test::ReadFile(scene + "/images/000_5.jpg"),
              test::ReadFile(test::RealDataPath("nuscenes_scene0916") + "/" +
                             v.frames.front().filename));
  }
}

// LiDAR returns of frames 0, 6, 12 (lidar_pose @ [x, y, z, 1]) projected
// with inv(extrinsics) and K: the true depth through that pixel at the
// sweep's time equals the point's camera z (1e-3 relative) for most, and is
// never beyond it. The sky mask at those frames against the true depth:
// little within the LiDAR's range (100 m from it) is called sky (under 5 %
// of the masked pixels, none measured: surfaces between returns; what is
// beyond the range, far buildings down the street, can be);
// the mask covers part of the true sky (the band within the LiDAR's vertical
// field of view).
constexpr double kLidarRangeM = 100;  // LidarOptions::max_range_m
TEST(ExportDrivestudio, LidarAndSkyAgreeWithTheWorld) {
  const DriveClip clip = LoadClip();
  const SyntheticWorld world(SyntheticWorldOptionsFor(WorldOptions(), 0));
  const SyntheticTimeline tl = MakeSyntheticTimeline(WorldOptions(), 0);
  const Rigid3d world_from_export = clip.frames.front().world_from_cam;
  const PinholeCamera cam = ExportedCamera(SceneDir());
  int seen = 0, exact = 0, through = 0, sky = 0, sky_wrong = 0, sky_near = 0,
      true_sky = 0, true_sky_found = 0;
  for (const int t : {0, 6, 12}) {
    const Eigen::Matrix4d l2w =
        ReadMatrix(SceneDir() + "/lidar_pose/" + Name(t) + ".txt");
    const Eigen::Matrix4d c2w =
        ReadMatrix(SceneDir() + "/extrinsics/" + Name(t) + "_0.txt");
    const Eigen::Matrix4d w2c = c2w.inverse();
    const Rigid3d global_from_cam =
        world_from_export * Rigid3d::FromMatrix(c2w, 1e-9);
    const size_t sweep = clip.frames[t].keyframe_sweep.value_or(
        *clip.lidar->Nearest(clip.frames[t].timestamp_us));
    const double time = tl.Seconds(clip.lidar->Sweeps()[sweep].timestamp_us);
    const std::string bin =
        test::ReadFile(SceneDir() + "/lidar/" + Name(t) + ".bin");
    ASSERT_EQ(bin.size() % 16, 0u);
    const float* p = reinterpret_cast<const float*>(bin.data());
    for (size_t i = 0; i < bin.size() / 16; i += 3) {
      const Eigen::Vector3d s(p[4 * i], p[4 * i + 1], p[4 * i + 2]);
      const Eigen::Vector3d c = (w2c * (l2w * s.homogeneous())).head<3>();
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
    // The sky mask against the true sky at the frame's time.
    const cv::Mat mask =
        ReadImageGray(SceneDir() + "/sky_masks/" + Name(t) + "_0.png");
    ASSERT_EQ(mask.size(), cv::Size(kWidth, kHeight));
    const double frame_time = tl.Seconds(clip.frames[t].timestamp_us);
    for (int y = 2; y < kHeight; y += 17) {
      for (int x = 3; x < kWidth; x += 19) {
        const double z = world.CameraDepthAt(cam, global_from_cam, frame_time,
                                             Eigen::Vector2d(x, y));
        const bool marked = mask.at<uint8_t>(y, x) > 0;
        sky += marked;
        sky_wrong += marked && z > 0;
        // The surface's range from the LiDAR (export frame).
        const Eigen::Vector3d surface =
            (c2w * (z * Eigen::Vector3d((x - cam.cx) / cam.fx,
                                        (y - cam.cy) / cam.fy, 1))
                       .homogeneous())
                .head<3>();
        const double range = (surface - l2w.block<3, 1>(0, 3)).norm();
        sky_near += marked && z > 0 && range < kLidarRangeM;
        true_sky += z == 0;
        true_sky_found += marked && z == 0;
      }
    }
  }
  std::printf(
      "%d LiDAR returns in view: %.1f %% at the true depth, %.2f %% seen "
      "through; sky mask: %d pixels, %.2f %% not sky (%.2f %% within "
      "100 m of the LiDAR), %.1f %% of the true sky\n",
      seen, 100.0 * exact / std::max(1, seen),
      100.0 * through / std::max(1, seen), sky,
      100.0 * sky_wrong / std::max(1, sky), 100.0 * sky_near / std::max(1, sky),
      100.0 * true_sky_found / std::max(1, true_sky));
  ASSERT_GT(seen, 1500);
  EXPECT_GT(exact, 0.8 * seen);
  EXPECT_LT(through, 0.01 * seen);
  ASSERT_GT(sky, 100);
  EXPECT_LT(sky_near, 0.05 * sky);
  EXPECT_GT(true_sky_found, 0.1 * true_sky);
}

// Pixels of a vehicle (the world's instance seen through them) whose box is
// wholly in view lie inside the vehicle mask; instances_info holds the
// clip's vehicles with the box sizes l, w, h.
TEST(ExportDrivestudio, VehicleMasksCoverTheVehiclesInView) {
  const DriveClip clip = LoadClip();
  const SyntheticWorld world(SyntheticWorldOptionsFor(WorldOptions(), 0));
  const SyntheticTimeline tl = MakeSyntheticTimeline(WorldOptions(), 0);
  const Rigid3d world_from_export = clip.frames.front().world_from_cam;
  const PinholeCamera cam = ExportedCamera(SceneDir());
  const nlohmann::json info = nlohmann::json::parse(
      test::ReadFile(SceneDir() + "/instances/instances_info.json"));
  ASSERT_GT(info.size(), 0u);
  int covered = 0, vehicle_pixels = 0;
  for (const int t : {0, 6, 12}) {
    const Eigen::Matrix4d c2w =
        ReadMatrix(SceneDir() + "/extrinsics/" + Name(t) + "_0.txt");
    const Rigid3d cam_from_export = Rigid3d::FromMatrix(c2w, 1e-9).Inverse();
    const Rigid3d global_from_cam =
        world_from_export * Rigid3d::FromMatrix(c2w, 1e-9);
    // Boxes of frame t wholly in front and inside the image.
    std::vector<Box2d> whole;
    for (const auto& [id, inst] : info.items()) {
      const auto& fa = inst["frame_annotations"];
      for (size_t k = 0; k < fa["frame_idx"].size(); ++k) {
        if (fa["frame_idx"][k].get<int>() != t) continue;
        Eigen::Matrix4d o2w;
        for (int r = 0; r < 4; ++r)
          for (int c = 0; c < 4; ++c) o2w(r, c) = fa["obj_to_world"][k][r][c];
        const Eigen::Vector3d lwh(fa["box_size"][k][0], fa["box_size"][k][1],
                                  fa["box_size"][k][2]);
        Box2d b{1e9, 1e9, -1e9, -1e9};
        bool ok = true;
        for (int corner = 0; corner < 8; ++corner) {
          const Eigen::Vector3d local(((corner & 1) ? 0.5 : -0.5) * lwh.x(),
                                      ((corner & 2) ? 0.5 : -0.5) * lwh.y(),
                                      ((corner & 4) ? 0.5 : -0.5) * lwh.z());
          const Eigen::Vector3d c =
              cam_from_export * (o2w * local.homogeneous()).head<3>();
          if (c.z() <= 0.1) ok = false;
          const Eigen::Vector2d px = cam.Project(c);
          b.xmin = std::min(b.xmin, px.x()), b.xmax = std::max(b.xmax, px.x());
          b.ymin = std::min(b.ymin, px.y()), b.ymax = std::max(b.ymax, px.y());
        }
        if (ok && b.xmin >= 0 && b.ymin >= 0 && b.xmax < kWidth &&
            b.ymax < kHeight)
          whole.push_back(b);
      }
    }
    const cv::Mat mask = ReadImageGray(SceneDir() + "/dynamic_masks/vehicle/" +
                                       Name(t) + "_0.png");
    const double time = tl.Seconds(clip.frames[t].timestamp_us);
    for (const Box2d& b : whole) {
      for (int y = static_cast<int>(b.ymin) + 1; y < b.ymax - 1; y += 3) {
        for (int x = static_cast<int>(b.xmin) + 1; x < b.xmax - 1; x += 3) {
          uint16_t instance = 0;
          world.CameraDepthAt(cam, global_from_cam, time, Eigen::Vector2d(x, y),
                              &instance);
          if (instance == kStaticInstance || instance == kSkyInstance) continue;
          ++vehicle_pixels;
          covered += mask.at<uint8_t>(y, x) > 0;
        }
      }
    }
  }
  std::printf("%d vehicle pixels of boxes wholly in view, %.1f %% masked\n",
              vehicle_pixels, 100.0 * covered / std::max(1, vehicle_pixels));
  ASSERT_GT(vehicle_pixels, 50);
  EXPECT_GT(covered, 0.99 * vehicle_pixels);
}

}  // namespace export_drivestudio_test
}  // namespace geodrive

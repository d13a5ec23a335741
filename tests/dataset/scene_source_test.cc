// The clip -> scene seam (dataset/scene_source.h): the registry, and the
// worked-example source "depth-folder" (docs/ARCHITECTURE.md) against exact
// unprojection and pose composition.

#include "dataset/scene_source.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "dataset/scene_folders.h"
#include "geometry/npy.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

constexpr int kW = 32, kH = 24;
constexpr double kFx = 20, kFy = 25, kCx = 15.5, kCy = 11.5;

// world_from_cam of frame i: a yawed, shifted camera 0, then i metres forward.
Rigid3d WorldFromCam(int i) {
  const Rigid3d world_from_cam0(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY())),
      Eigen::Vector3d(5, -1, 2));
  return world_from_cam0 *
         Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, i));
}

std::string PoseJson(const Rigid3d& pose) {
  const Eigen::Matrix3d r = pose.rotation.toRotationMatrix();
  std::ostringstream os;
  os.precision(17);
  os << "[";
  for (int row = 0; row < 4; ++row) {
    for (int col = 0; col < 4; ++col) {
      const double v = row == 3   ? (col == 3 ? 1.0 : 0.0)
                       : col == 3 ? pose.translation[row]
                                  : r(row, col);
      os << v << (row == 3 && col == 3 ? "]" : ", ");
    }
  }
  return os.str();
}

// A depth folder: depth 8 + 0.1 u (metres) at pixel (u, v), 3 frames.
std::string MakeDepthFolder(const std::string& name) {
  const std::string dir = test::MakeTempDir(name);
  fs::create_directories(dir + "/depth");
  std::vector<float> depth(kW * kH);
  for (int v = 0; v < kH; ++v)
    for (int u = 0; u < kW; ++u) depth[v * kW + u] = 8.0f + 0.1f * u;
  WriteNpy(dir + "/depth/000000.npy",
           NpyArray::Float32({kH, kW}, depth.data()));
  std::ofstream json(dir + "/cameras.json");
  json << "{\"units\": \"metres\", \"frames\": [";
  for (int i = 0; i < 3; ++i) {
    json << (i ? ", " : "") << "{\"fx\": " << kFx << ", \"fy\": " << kFy
         << ", \"cx\": " << kCx << ", \"cy\": " << kCy << ", \"width\": " << kW
         << ", \"height\": " << kH
         << ", \"world_from_cam\": " << PoseJson(WorldFromCam(i)) << "}";
  }
  json << "]}\n";
  return dir;
}

SceneInputs Inputs(const std::string& dir) {
  SceneInputs in;
  in.path = dir;
  in.image = cv::Mat(kH, kW, CV_8UC3, cv::Scalar(10, 20, 30));
  return in;
}

TEST(SceneSource, RegistryListsEverySourceAndRejectsUnknownNames) {
  EXPECT_THAT(
      SceneSourceNames(),
      ::testing::ElementsAre("monst3r", "lidar", "lidar-dense", "image-depth",
                             "cloud", "depth-folder", "vggt", "da3", "cut3r",
                             "megasam", "moge", "npz"));
  for (const std::string& name : SceneSourceNames())
    EXPECT_NE(CreateSceneSource(name), nullptr) << name;
  try {
    CreateSceneSource("vggt-typo");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("unknown scene source 'vggt-typo'"));
    EXPECT_THAT(e.what(), HasSubstr("depth-folder"));
  }
  // The LiDAR source needs a clip; path-based sources need a path.
  EXPECT_THROW(BuildConditionScene("lidar", SceneInputs(), {}), InputError);
  EXPECT_THROW(BuildConditionScene("lidar-dense", SceneInputs(), {}),
               InputError);
  EXPECT_THROW(BuildConditionScene("depth-folder", SceneInputs(), {}),
               InputError);
}

// Every pixel unprojects exactly (integer-index pixels: x = (u - cx) z / fx),
// and the trajectory is cam0_from_cam = inverse(world_from_cam0) *
// world_from_cam_i: i metres forward of camera 0.
TEST(SceneSource, DepthFolderUnprojectsFrameZeroAndComposesPoses) {
  const std::string dir = MakeDepthFolder("scene_depth_folder");
  const ConditionScene scene =
      BuildConditionScene("depth-folder", Inputs(dir), {});
  ASSERT_EQ(scene.cloud.size(), static_cast<size_t>(kW * kH));
  ASSERT_TRUE(scene.cloud.HasColors());
  double worst = 0;
  for (size_t k = 0; k < scene.cloud.size(); ++k) {
    const int u = static_cast<int>(k % kW), v = static_cast<int>(k / kW);
    const double z = 8.0f + 0.1f * u;
    const Eigen::Vector3d truth((u - kCx) * z / kFx, (v - kCy) * z / kFy, z);
    worst = std::max(worst,
                     (scene.cloud.positions[k].cast<double>() - truth).norm());
    EXPECT_EQ(scene.cloud.colors[k], Color3u8(10, 20, 30));
  }
  EXPECT_LT(worst, 1e-5);  // float32 positions of metre-scale points
  ASSERT_EQ(scene.trajectory.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    const Rigid3d& p = scene.trajectory.world_from_cam[i];
    EXPECT_NEAR((p.translation - Eigen::Vector3d(0, 0, i)).norm(), 0, 1e-9);
    EXPECT_NEAR(p.rotation.angularDistance(Eigen::Quaterniond::Identity()), 0,
                1e-9);
  }
  EXPECT_TRUE(scene.metric());
  EXPECT_EQ(scene.scale.source, "given");
  EXPECT_EQ(scene.camera.width, kW);
  EXPECT_DOUBLE_EQ(scene.camera.fy, kFy);
  // The render camera at twice the size: focal lengths double.
  EXPECT_DOUBLE_EQ(scene.CameraAt(2 * kW, 2 * kH, ResizeMode::kResize).fx,
                   2 * kFx);
}

// kPaper keeps depths within [min, max] metres: 8 + 0.1 u <= 9 keeps u <= 10.
TEST(SceneSource, DepthFolderPaperFilterKeepsTheDepthRange) {
  const std::string dir = MakeDepthFolder("scene_depth_folder_range");
  SceneSourceOptions o;
  o.max_depth_m = 9.0;
  const ConditionScene scene =
      BuildConditionScene("depth-folder", Inputs(dir), o);
  EXPECT_EQ(scene.cloud.size(), static_cast<size_t>(11 * kH));
  o.max_depth_m = 7.0;  // nothing left: an error naming the depth file
  try {
    BuildConditionScene("depth-folder", Inputs(dir), o);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("depth/000000.npy: no pixel"));
  }
  o.filter = PointmapFilter::kReleased;  // the released scripts keep all
  EXPECT_EQ(BuildConditionScene("depth-folder", Inputs(dir), o).cloud.size(),
            static_cast<size_t>(kW * kH));
}

TEST(SceneSource, DepthFolderBadInputNamesTheFile) {
  const std::string dir = MakeDepthFolder("scene_depth_folder_bad");
  std::ofstream(dir + "/cameras.json") << "{\"frames\": [{\"fx\": 1}]}";
  try {
    BuildConditionScene("depth-folder", Inputs(dir), {});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("cameras.json: frames[0].fy"));
  }
  fs::remove(dir + "/cameras.json");
  EXPECT_THROW(BuildConditionScene("depth-folder", Inputs(dir), {}),
               InputError);
}

// A user trajectory is placed by the scene's anchor: relative to its first
// pose and started at scene_from_cam0.
TEST(SceneSource, PlaceTrajectoryAnchorsAtFrameZero) {
  ConditionScene scene;
  scene.anchor = TrajectoryAnchor::kFirstFrame;
  scene.scene_from_cam0 = WorldFromCam(0);
  Trajectory user;
  user.Add(0,
           Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(7, 7, 7)));
  user.Add(1,
           Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(7, 7, 9)));
  const Trajectory placed = scene.PlaceTrajectory(user);
  const Rigid3d expect = WorldFromCam(2);  // 2 m forward of camera 0
  EXPECT_NEAR(
      (placed.world_from_cam[1].translation - expect.translation).norm(), 0,
      1e-12);
  scene.anchor = TrajectoryAnchor::kAbsolute;
  EXPECT_EQ(scene.PlaceTrajectory(user).world_from_cam[1].translation,
            Eigen::Vector3d(7, 7, 9));
}

// Per-clip folders in the layouts users have (dataset/scene_folders.h).
TEST(SceneFolders, FindsClipFoldersInEveryLayout) {
  const std::string root = test::MakeTempDir("scene_folders");
  auto make = [&](const std::string& rel, bool marker) {
    fs::create_directories(root + "/" + rel);
    if (marker) std::ofstream(root + "/" + rel + "/pred_traj.txt") << "\n";
  };
  make("a_0000", true);                        // ROOT/<clip_id>/
  make("b_0000/reconstruction", true);         // ROOT/<clip_id>/reconstruction/
  make("sample_000007/reconstruction", true);  // upstream numbering
  make("broken_0000", false);  // exists: the clip's (fails later)
  make("lady-running", true);  // any name, mapped
  const std::string map = root + "/map.txt";
  std::ofstream(map) << "# folder clip\nlady-running c_0000\n"
                        "{\"clip_id\":\"d_0000\",\"index\":7}\n";
  const SceneFolders f(root, map, "pred_traj.txt");
  EXPECT_EQ(f.Find("a_0000").value(), root + "/a_0000");
  EXPECT_EQ(f.Find("b_0000").value(), root + "/b_0000/reconstruction");
  EXPECT_EQ(f.Find("c_0000").value(), root + "/lady-running");
  EXPECT_EQ(f.Find("d_0000").value(), root + "/sample_000007/reconstruction");
  EXPECT_EQ(f.Find("broken_0000").value(), root + "/broken_0000");
  EXPECT_FALSE(f.Find("e_0000").has_value());
  std::ofstream(map) << "lady-running\n";
  try {
    SceneFolders bad(root, map, "pred_traj.txt");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(),
                HasSubstr("map.txt:1: expected '<folder name> <clip id>'"));
  }
  std::ofstream(map) << "../etc c_0000\n";
  EXPECT_THROW(SceneFolders(root, map, "pred_traj.txt"), InputError);
}

}  // namespace
}  // namespace geodrive

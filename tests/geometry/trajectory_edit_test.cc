#include "geometry/trajectory_edit.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "geometry/util/status.h"
#include "geometry/trajectory_json.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

// A car-like trajectory: first camera rotated (yaw 30° about world y, small
// pitch), driving forward along its own z at 5 units/s, 10 fps, with a gentle
// turn.
Trajectory MakeTrajectory(int n = 25) {
  Trajectory t;
  const Eigen::Quaterniond first =
      QuaternionFromAngleAxis(Eigen::Vector3d(0.05, 0.52, 0.0));
  Eigen::Vector3d position(10, -1.5, 3);
  for (int k = 0; k < n; ++k) {
    const Eigen::Quaterniond q =
        first * QuaternionFromAngleAxis(Eigen::Vector3d(0, 0.01 * k, 0));
    t.Add(0.1 * k, Rigid3d(q, position));
    position += q * Eigen::Vector3d(0, 0, 0.5);
  }
  return t;
}

// A straight constant-velocity trajectory along world +z (camera facing +z).
Trajectory Straight(int n, double step) {
  Trajectory t;
  for (int k = 0; k < n; ++k)
    t.Add(0.1 * k, Rigid3d(Eigen::Quaterniond::Identity(),
                           Eigen::Vector3d(0, 0, step * k)));
  return t;
}

TEST(TrajectoryEdit, ShiftLeftMovesAlongFirstCameraMinusX) {
  const Trajectory t = MakeTrajectory();
  const Trajectory left = ShiftLeft(t, 3.0);
  const Eigen::Vector3d minus_x_world =
      t.world_from_cam[0].rotation * Eigen::Vector3d(-1, 0, 0);
  for (size_t k = 0; k < t.size(); ++k) {
    EXPECT_THAT(
        left.world_from_cam[k].translation,
        test::EigenNear(t.world_from_cam[k].translation + 3.0 * minus_x_world,
                        1e-12));
    EXPECT_LT(RotationDistanceDeg(left.world_from_cam[k].rotation,
                                  t.world_from_cam[k].rotation),
              1e-9);
  }
  // In the first camera's frame, the shifted first camera sits at x = -3.
  const Eigen::Vector3d in_first =
      t.world_from_cam[0].Inverse() * left.world_from_cam[0].translation;
  EXPECT_THAT(in_first, test::EigenNear(Eigen::Vector3d(-3, 0, 0), 1e-12));
  const Trajectory right = ShiftRight(t, 2.0);
  EXPECT_THAT(
      Eigen::Vector3d(
          t.world_from_cam[0].Inverse() * right.world_from_cam[5].translation -
          t.world_from_cam[0].Inverse() * t.world_from_cam[5].translation),
      test::EigenNear(Eigen::Vector3d(2, 0, 0), 1e-12));
  const Trajectory up = ShiftUp(t, 1.5);  // up = -y (y points down)
  EXPECT_THAT(
      Eigen::Vector3d(
          t.world_from_cam[0].Inverse() * up.world_from_cam[3].translation -
          t.world_from_cam[0].Inverse() * t.world_from_cam[3].translation),
      test::EigenNear(Eigen::Vector3d(0, -1.5, 0), 1e-12));
}

TEST(TrajectoryEdit, ForwardThenBackReturnsToStart) {
  const Trajectory t = MakeTrajectory(25);
  const Trajectory fb = ForwardThenBack(t);
  ASSERT_EQ(fb.size(), 25u);
  EXPECT_EQ(fb.timestamps, t.timestamps);
  for (int k = 0; k <= 12; ++k) {
    EXPECT_THAT(fb.world_from_cam[k].translation,
                test::EigenNear(t.world_from_cam[k].translation, 0));
  }
  for (int k = 13; k < 25; ++k) {
    EXPECT_THAT(fb.world_from_cam[k].translation,
                test::EigenNear(t.world_from_cam[24 - k].translation, 0));
  }
  EXPECT_THAT(fb.world_from_cam[24].translation,
              test::EigenNear(t.world_from_cam[0].translation, 0));
  const Trajectory rev = ReverseOrder(t);
  EXPECT_THAT(rev.world_from_cam[0].translation,
              test::EigenNear(t.world_from_cam[24].translation, 0));
}

TEST(TrajectoryEdit, SpeedScalingOnAStraightLineIsExactIncludingExtrapolation) {
  const Trajectory t = Straight(25, 0.5);  // 5 units/s
  for (double factor : {0.5, 1.0, 2.0, 3.0}) {
    const Trajectory s = ScaleSpeed(t, factor);
    ASSERT_EQ(s.size(), t.size());
    for (size_t k = 0; k < t.size(); ++k) {
      EXPECT_NEAR(s.world_from_cam[k].translation.z(), 0.5 * factor * k, 1e-9)
          << factor << " " << k;
    }
    EXPECT_NEAR(s.MeanSpeed(), 5.0 * factor, 1e-9);
  }
  EXPECT_THROW(ScaleSpeed(t, 0.0), InputError);
  EXPECT_THROW(ScaleSpeed(t, -1.0), InputError);
}

TEST(TrajectoryEdit, ExtrapolationContinuesAConstantTurn) {
  // Constant yaw rate and forward speed: extrapolating the last segment
  // reproduces the next poses.
  const Trajectory full = MakeTrajectory(30);
  Trajectory head;
  for (int k = 0; k < 20; ++k)
    head.Add(full.timestamps[k], full.world_from_cam[k]);
  for (int k = 20; k < 30; ++k) {
    const Rigid3d p = PoseAtExtrapolated(head, full.timestamps[k]);
    EXPECT_LT(RotationDistanceDeg(p.rotation, full.world_from_cam[k].rotation),
              1e-6);
    // The extrapolation is the SE(3) power of the last motion: exact at integer
    // steps.
    EXPECT_LT((p.translation - full.world_from_cam[k].translation).norm(), 1e-9)
        << k;
  }
}

TEST(TrajectoryEdit, ResamplingInterpolatesAndKeepsEnds) {
  const Trajectory t = Straight(25, 0.5);
  const Trajectory r = ResampleUniform(t, 49);
  ASSERT_EQ(r.size(), 49u);
  EXPECT_DOUBLE_EQ(r.timestamps.front(), 0.0);
  EXPECT_NEAR(r.timestamps.back(), 2.4, 1e-12);
  for (int k = 0; k < 49; ++k)
    EXPECT_NEAR(r.world_from_cam[k].translation.z(), 0.25 * k, 1e-9);
  const Trajectory f = ResampleFps(t, 5.0);  // 2.4 s at 5 fps: 13 frames
  ASSERT_EQ(f.size(), 13u);
  EXPECT_NEAR(f.world_from_cam[12].translation.z(), 12.0, 1e-9);
  EXPECT_THROW(ResampleUniform(t, 0), InputError);
  EXPECT_THROW(ResampleFps(t, 0), InputError);
}

TEST(TrajectoryEdit, PositiveYawTurnsLeft) {
  const Trajectory t = Straight(3, 1.0);
  const Trajectory y = ApplyYawOffset(t, 90.0);
  // Forward axis after a 90° left turn points to the old -x (left).
  const Eigen::Vector3d forward =
      y.world_from_cam[1].rotation * Eigen::Vector3d::UnitZ();
  EXPECT_THAT(forward, test::EigenNear(Eigen::Vector3d(-1, 0, 0), 1e-12));
  // Down stays down, positions unchanged.
  EXPECT_THAT(
      Eigen::Vector3d(y.world_from_cam[1].rotation * Eigen::Vector3d::UnitY()),
      test::EigenNear(Eigen::Vector3d(0, 1, 0), 1e-12));
  EXPECT_THAT(y.world_from_cam[2].translation,
              test::EigenNear(t.world_from_cam[2].translation, 0));
  EXPECT_THROW(ApplyYawOffsets(t, {1.0, 2.0}), InputError);
}

TEST(TrajectoryEdit, ClipFromPosesIsRelativeToFirstFrame) {
  const Trajectory t = MakeTrajectory(10);
  const Trajectory clip =
      ClipTrajectoryFromPoses(t.timestamps, t.world_from_cam);
  EXPECT_THAT(clip.world_from_cam[0].ToMatrix(),
              test::EigenNear(Eigen::Matrix4d::Identity(), 1e-12));
  for (size_t k = 0; k < t.size(); ++k) {
    const Rigid3d expected =
        t.world_from_cam[0].Inverse() * t.world_from_cam[k];
    EXPECT_THAT(clip.world_from_cam[k].ToMatrix(),
                test::EigenNear(expected.ToMatrix(), 1e-12));
  }
  // From ego poses + extrinsics: equal to composing them first.
  const Rigid3d ego_from_cam(
      QuaternionFromAngleAxis(Eigen::Vector3d(-M_PI / 2, 0, 0)),
      Eigen::Vector3d(1.7, 0.0, 1.5));
  std::vector<Rigid3d> world_from_ego;
  for (const auto& p : t.world_from_cam)
    world_from_ego.push_back(p * ego_from_cam.Inverse());
  const Trajectory from_ego =
      ClipTrajectoryFromEgoPoses(t.timestamps, world_from_ego, ego_from_cam);
  for (size_t k = 0; k < t.size(); ++k) {
    EXPECT_THAT(from_ego.world_from_cam[k].ToMatrix(),
                test::EigenNear(clip.world_from_cam[k].ToMatrix(), 1e-9));
  }
  // Bad input.
  std::vector<Rigid3d> bad = t.world_from_cam;
  bad[3].translation.x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(ClipTrajectoryFromPoses(t.timestamps, bad), InputError);
  bad = t.world_from_cam;
  bad[2].rotation.coeffs() *= 1.5;  // not a rotation
  EXPECT_THROW(ClipTrajectoryFromPoses(t.timestamps, bad), InputError);
  std::vector<double> ts = t.timestamps;
  ts[4] = ts[3];
  EXPECT_THROW(ClipTrajectoryFromPoses(ts, t.world_from_cam), InputError);
  EXPECT_THROW(ClipTrajectoryFromPoses({}, {}), InputError);
}

TEST(TrajectoryEdit, ApplyEditsComposesInDocumentedOrder) {
  const Trajectory t = Straight(25, 0.5);
  TrajectoryEditOptions o;
  EXPECT_EQ(o.Describe(), "none");
  o.shift_left = 3;
  o.speed_scale = 2;
  const Trajectory e = ApplyTrajectoryEdits(t, o);
  EXPECT_EQ(o.Describe(), "speed_scale=2 shift_left=3");
  EXPECT_NEAR(e.world_from_cam[10].translation.x(), -3.0, 1e-12);
  EXPECT_NEAR(e.world_from_cam[10].translation.z(), 10.0, 1e-9);
  o.speed_scale = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(ApplyTrajectoryEdits(t, o), InputError);
}

// ---- Trajectory JSON ----

std::string WriteText(const std::string& dir,
                      const std::string& name,
                      const std::string& text) {
  const std::string path = dir + "/" + name;
  std::ofstream(path) << text;
  return path;
}

TEST(TrajectoryJson, RoundTripWithCamera) {
  const std::string dir = test::MakeTempDir("trajectory_json_roundtrip");
  const Trajectory t = MakeTrajectory(7);
  TrajectoryFileInfo info;
  info.units = "metres";
  info.camera = PinholeCamera(1266.4, 1266.4, 816.3, 491.5, 1600, 900);
  const std::string path = dir + "/traj.json";
  WriteTrajectoryJson(path, t, info);
  TrajectoryFileInfo back_info;
  const Trajectory back = ReadTrajectoryJson(path, &back_info);
  ASSERT_EQ(back.size(), t.size());
  for (size_t k = 0; k < t.size(); ++k) {
    EXPECT_EQ(back.timestamps[k], t.timestamps[k]);
    EXPECT_THAT(back.world_from_cam[k].ToMatrix(),
                test::EigenNear(t.world_from_cam[k].ToMatrix(), 1e-15));
  }
  ASSERT_TRUE(back_info.camera.has_value());
  EXPECT_EQ(back_info.camera->fx, 1266.4);
  EXPECT_EQ(back_info.camera->width, 1600);
  EXPECT_EQ(back_info.units, "metres");
  // Auto-detection by extension.
  EXPECT_EQ(ReadTrajectoryAny(path).size(), t.size());

  // The written file validates against data_schema/trajectory.schema.json.
  GEODRIVE_REQUIRE_PYTHON_MODULE("jsonschema");
  const std::string schema =
      std::string(GEODRIVE_SOURCE_DIR) + "/data_schema/trajectory.schema.json";
  const std::string cmd =
      std::string(test::kDebianPython) +
      " -c 'import json,sys,jsonschema; s=json.load(open(sys.argv[1])); "
      "jsonschema.Draft202012Validator.check_schema(s); "
      "jsonschema.validate(json.load(open(sys.argv[2])), s, "
      "cls=jsonschema.Draft202012Validator)' " +
      schema + " " + path;
  std::string out;
  EXPECT_EQ(test::RunCommand(cmd, &out), 0) << out;
  // And a file with a rotation matrix instead of a quaternion validates too.
  const std::string rot = WriteText(
      dir, "rot.json", R"({"format": "geodrive-trajectory", "version": 1,
    "frames": [{"t": 0, "position": [0, 0, 0], "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}]})");
  EXPECT_EQ(
      test::RunCommand(std::string(test::kDebianPython) +
                           " -c 'import json,sys,jsonschema; "
                           "jsonschema.validate(json.load(open(sys.argv[2])), "
                           "json.load(open(sys.argv[1])))' " +
                           schema + " " + rot,
                       &out),
      0)
      << out;
}

TEST(TrajectoryJson, RotationMatrixFramesAndDefaults) {
  const std::string dir = test::MakeTempDir("trajectory_json_rotation");
  const std::string path = WriteText(dir, "t.json", R"({
    "format": "geodrive-trajectory", "version": 1,
    "frames": [
      {"position": [0, 0, 0], "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]},
      {"position": [0, 0, 1], "rotation": [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]}
    ]})");
  TrajectoryFileInfo info;
  const Trajectory t = ReadTrajectoryJson(path, &info);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t.timestamps[1], 1.0);  // default t = frame index
  EXPECT_FALSE(info.camera.has_value());
  const Eigen::Matrix3d r = t.world_from_cam[1].rotation.toRotationMatrix();
  EXPECT_THAT(
      r,
      test::EigenNear(
          (Eigen::Matrix3d() << 0, 0, 1, 0, 1, 0, -1, 0, 0).finished(), 1e-12));
}

TEST(TrajectoryJson, BadFilesGiveOneLineErrorsNamingTheFile) {
  const std::string dir = test::MakeTempDir("trajectory_json_bad");
  const std::string head =
      R"({"format": "geodrive-trajectory", "version": 1, "frames": [)";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"malformed.json", "{\"format\": "},
      {"format.json", R"({"format": "other", "version": 1, "frames": []})"},
      // Found by fuzz_trajectory_json: a non-string "format" escaped as
      // nlohmann's type_error (exit 1, "internal error").
      {"format_object.json",
       R"({"format": {}, "version": 1, "frames": []})"},
      {"empty.json", head + "]}"},
      {"nonunit.json",
       head + R"({"position": [0,0,0], "quaternion_wxyz": [1, 0.3, 0, 0]}]})"},
      {"skew.json",
       head +
           R"({"position": [0,0,0], "rotation": [[1,0.2,0],[0,1,0],[0,0,1]]}]})"},
      {"reflection.json",
       head +
           R"({"position": [0,0,0], "rotation": [[-1,0,0],[0,1,0],[0,0,1]]}]})"},
      {"nan.json",
       head + R"({"position": [0,NaN,0], "quaternion_wxyz": [1,0,0,0]}]})"},
      {"short.json",
       head + R"({"position": [0,0], "quaternion_wxyz": [1,0,0,0]}]})"},
      {"both.json",
       head +
           R"({"position": [0,0,0], "quaternion_wxyz": [1,0,0,0], "rotation": [[1,0,0],[0,1,0],[0,0,1]]}]})"},
      {"time.json",
       head + R"({"t": 1, "position": [0,0,0], "quaternion_wxyz": [1,0,0,0]},
                             {"t": 1, "position": [0,0,0], "quaternion_wxyz": [1,0,0,0]}]})"},
      {"camera.json",
       R"({"format": "geodrive-trajectory", "version": 1, "camera": {"fx": -5, "fy": 5, "cx": 1, "cy": 1, "width": 4, "height": 4},
                        "frames": [{"position": [0,0,0], "quaternion_wxyz": [1,0,0,0]}]})"},
  };
  for (const auto& [name, text] : cases) {
    const std::string path = WriteText(dir, name, text);
    try {
      ReadTrajectoryJson(path);
      ADD_FAILURE() << name << ": no error";
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(path), std::string::npos) << name << ": " << msg;
      EXPECT_EQ(msg.find('\n'), std::string::npos) << name << ": " << msg;
    }
  }
  EXPECT_THROW(ReadTrajectoryJson(dir + "/missing.json"), InputError);
  EXPECT_THROW(ParseTrajectoryFormat("xml"), InputError);
}

}  // namespace
}  // namespace geodrive

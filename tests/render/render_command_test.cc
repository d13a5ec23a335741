// End-to-end tests of `geodrive render`.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "geometry/image_io.h"
#include "geometry/npy.h"
#include "geometry/trajectory_json.h"
#include "tests/common/test_util.h"
#include "tests/render/render_test_util.h"

namespace geodrive {
namespace {

namespace fs = std::filesystem;

struct Inputs {
  std::string image, depth, intrinsics, trajectory;
  test::RayCastScene scene;
};

Inputs WriteInputs(const std::string& dir) {
  Inputs in;
  const PinholeCamera camera(250, 250, 127.5, 79.5, 256, 160);
  in.scene = test::RayCast(camera, Rigid3d());
  in.image = dir + "/frame0.png";
  WriteImageRgb(in.image, in.scene.rgb);
  in.depth = dir + "/frame0.npy";
  WriteNpy(in.depth, NpyArray::Float32({camera.height, camera.width},
                                       in.scene.depth.ptr<float>()));
  in.intrinsics = dir + "/K.txt";
  std::ofstream(in.intrinsics) << "250 0 127.5 0 250 79.5 0 0 1\n";
  Trajectory t;
  for (int k = 0; k < 6; ++k) {
    t.Add(0.1 * k, Rigid3d(Eigen::Quaterniond::Identity(),
                           Eigen::Vector3d(0, 0, 0.5 * k)));
  }
  in.trajectory = dir + "/traj.json";
  WriteTrajectoryJson(in.trajectory, t);
  return in;
}

TEST(RenderCommand, ImageDepthToVideoFramesAndReport) {
  const std::string dir = test::MakeTempDir("render_cmd_image");
  const Inputs in = WriteInputs(dir);
  const std::string out = dir + "/out";
  std::string log;
  const std::string cmd = test::GeodriveBinary() + " render --image " +
                          in.image + " --depth " + in.depth + " --intrinsics " +
                          in.intrinsics + " --trajectory " + in.trajectory +
                          " --size 160x256 --frames --out " + out;
  ASSERT_EQ(test::RunCommand(cmd, &log), 0) << log;
  EXPECT_TRUE(fs::exists(out + "/render.mp4"));
  EXPECT_TRUE(fs::exists(out + "/contact_sheet.png"));
  ASSERT_TRUE(fs::exists(out + "/frames/render_0005.png"));
  // Frame 0 (PNG, lossless) reproduces the input image at every rendered pixel.
  const cv::Mat f0 = ReadImageRgb(out + "/frames/render_0000.png");
  const cv::Mat has_depth = in.scene.depth > 0;
  EXPECT_GE(test::MaskedPsnr(f0, in.scene.rgb, has_depth), 60.0);
  std::ifstream rj(out + "/render.json");
  const nlohmann::json report = nlohmann::json::parse(rj);
  EXPECT_EQ(report["options"]["mode"], "zbuffer");
  EXPECT_EQ(report["video"]["fourcc"], "avc1");
  ASSERT_EQ(report["frames"].size(), 6u);
  const double c0 = report["frames"][0]["coverage"];
  const double c5 = report["frames"][5]["coverage"];
  EXPECT_GT(c0, 0.95 * cv::countNonZero(has_depth) / double(has_depth.total()));
  EXPECT_LT(c5, c0);  // driving forward opens holes
}

// Render streams chunks of frames to the video, the PNG sequence and
// the contact sheet (chunks of max(8, 2 x threads) frames). Different chunkings
// must give the same bytes: over 40 frames, 1 thread renders chunks of 8 and
// 16 threads chunks of 32 and 8.
TEST(RenderCommand, StreamedChunksGiveTheSameBytesForAnyChunking) {
  const std::string dir = test::MakeTempDir("render_cmd_chunks");
  const Inputs in = WriteInputs(dir);
  const std::string base =
      test::GeodriveBinary() + " render --image " + in.image + " --depth " +
      in.depth + " --intrinsics " + in.intrinsics + " --trajectory " +
      in.trajectory + " --size 160x256 --num-frames 40 --frames";
  std::string log;
  ASSERT_EQ(test::RunCommand(base + " --threads 1 --out " + dir + "/a", &log),
            0)
      << log;
  ASSERT_EQ(test::RunCommand(base + " --threads 16 --out " + dir + "/b", &log),
            0)
      << log;
  auto bytes = [](const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(f)), {});
  };
  for (int i = 0; i < 40; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "/frames/render_%04d.png", i);
    ASSERT_TRUE(fs::exists(dir + "/a" + name)) << name;
    EXPECT_EQ(bytes(dir + "/a" + name), bytes(dir + "/b" + name)) << name;
  }
  EXPECT_EQ(bytes(dir + "/a/render.mp4"), bytes(dir + "/b/render.mp4"));
  EXPECT_EQ(bytes(dir + "/a/contact_sheet.png"),
            bytes(dir + "/b/contact_sheet.png"));
  std::ifstream rj(dir + "/a/render.json");
  const nlohmann::json report = nlohmann::json::parse(rj);
  ASSERT_EQ(report["frames"].size(), 40u);
  double sum = 0;
  for (const auto& f : report["frames"]) sum += f["coverage"].get<double>();
  EXPECT_NEAR(report["summary"]["mean_coverage"].get<double>(), sum / 40,
              1e-12);
}

// A render.json that cannot be written is an error, not a run that exits 0
// with a truncated report.
// Here a file-size limit (ulimit -f 150 KiB, SIGXFSZ ignored, so writes fail
// with EFBIG as on a full disk) lets the contact sheet through but not the
// report of 2000 frames (about 300 KB): the run must say so and exit 2.
TEST(RenderCommand, ReportWriteFailureIsAnError) {
  const std::string dir = test::MakeTempDir("render_cmd_report_fail");
  const Inputs in = WriteInputs(dir);
  std::string log;
  const int rc = test::RunCommand(
      "bash -c \"trap '' XFSZ; ulimit -f 150; exec " +
          test::GeodriveBinary() + " render --image " + in.image +
          " --depth " + in.depth + " --intrinsics " + in.intrinsics +
          " --trajectory " + in.trajectory +
          " --size 16x16 --num-frames 2000 --no-video --out " + dir +
          "/out\"",
      &log);
  EXPECT_EQ(rc, 2) << log;
  EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;
  EXPECT_NE(log.find(dir + "/out/render.json: write failed"),
            std::string::npos)
      << log;
  EXPECT_FALSE(fs::exists(dir + "/out/render.json"));  // no partial report
}

TEST(RenderCommand, ShiftAndCompatPreset) {
  const std::string dir = test::MakeTempDir("render_cmd_compat");
  const Inputs in = WriteInputs(dir);
  const std::string out = dir + "/out";
  std::string log;
  const std::string cmd =
      test::GeodriveBinary() + " render --image " + in.image + " --depth " +
      in.depth + " --intrinsics " + in.intrinsics + " --trajectory " +
      in.trajectory + " --preset geodrive-compat --shift-left 1 --reverse " +
      "--frames --no-video --out " + out;
  ASSERT_EQ(test::RunCommand(cmd, &log), 0) << log;
  std::ifstream rj(out + "/render.json");
  const nlohmann::json report = nlohmann::json::parse(rj);
  EXPECT_EQ(report["options"]["mode"], "soft");
  EXPECT_EQ(report["output_size"]["width"], 1024);
  EXPECT_EQ(report["output_size"]["height"], 576);
  EXPECT_EQ(report["edits"], "shift_left=1 forward_then_back");
  EXPECT_EQ(report["options"]["frame0_replaced"], true);
  const cv::Mat f0 = ReadImageRgb(out + "/frames/render_0000.png");
  EXPECT_EQ(f0.cols, 1024);
}

// The footprint preset: driving forward into the image + depth scene keeps
// it closed where the paper preset opens holes, frame 0 is the same, and the
// options that contradict it are one-line errors.
TEST(RenderCommand, FootprintPresetKeepsTheApproachedSceneClosed) {
  const std::string dir = test::MakeTempDir("render_cmd_footprint");
  const Inputs in = WriteInputs(dir);
  const std::string base =
      test::GeodriveBinary() + " render --image " + in.image + " --depth " +
      in.depth + " --intrinsics " + in.intrinsics + " --trajectory " +
      in.trajectory + " --size 160x256 --no-video --frames";
  std::string log;
  nlohmann::json reports[2];
  for (int k = 0; k < 2; ++k) {
    const std::string out = dir + (k ? "/footprint" : "/paper");
    ASSERT_EQ(
        test::RunCommand(
            base + (k ? " --preset footprint" : "") + " --out " + out, &log),
        0)
        << log;
    std::ifstream rj(out + "/render.json");
    reports[k] = nlohmann::json::parse(rj);
  }
  EXPECT_EQ(reports[1]["preset"], "footprint");
  EXPECT_EQ(reports[1]["options"]["splat_size"], "footprint");
  EXPECT_EQ(reports[1]["options"]["max_footprint_magnification"], 8.0);
  EXPECT_EQ(reports[0]["options"]["splat_size"], "fixed");
  const double paper0 = reports[0]["frames"][0]["coverage"];
  const double foot0 = reports[1]["frames"][0]["coverage"];
  const double paper5 = reports[0]["frames"][5]["coverage"];
  const double foot5 = reports[1]["frames"][5]["coverage"];
  EXPECT_EQ(paper0, foot0);  // seen as captured: one pixel per point
  EXPECT_GT(foot5, paper5 + 0.1) << paper5 << " " << foot5;
  const cv::Mat p0 = ReadImageRgb(dir + "/paper/frames/render_0000.png");
  const cv::Mat f0 = ReadImageRgb(dir + "/footprint/frames/render_0000.png");
  EXPECT_EQ(cv::norm(p0, f0, cv::NORM_INF), 0.0);
  // Contradicting options: one line, exit 2.
  for (const std::string bad :
       {" --preset footprint --mode soft", " --preset footprint --radius 2",
        " --preset footprint --max-magnification 0.5"}) {
    EXPECT_EQ(test::RunCommand(base + bad + " --out " + dir + "/bad", &log), 2)
        << bad << ": " << log;
    EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;
  }
}

TEST(RenderCommand, BadInputExitsTwoWithOneLine) {
  const std::string dir = test::MakeTempDir("render_cmd_bad");
  const Inputs in = WriteInputs(dir);
  const std::string base = test::GeodriveBinary() + " render --image " +
                           in.image + " --intrinsics " + in.intrinsics +
                           " --trajectory " + in.trajectory + " --out " + dir +
                           "/out";
  std::string log;
  EXPECT_EQ(test::RunCommand(base + " --depth " + dir + "/missing.npy", &log),
            2)
      << log;
  EXPECT_NE(log.find("missing.npy"), std::string::npos) << log;
  EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;
  EXPECT_EQ(
      test::RunCommand(base + " --depth " + in.depth + " --size 0x100", &log),
      2)
      << log;
  EXPECT_EQ(test::RunCommand(
                base + " --depth " + in.depth + " --size 20000x100", &log),
            2)
      << log;
  // A trajectory with a non-orthonormal rotation.
  const std::string bad_traj = dir + "/bad.json";
  std::ofstream(bad_traj)
      << R"({"format": "geodrive-trajectory", "version": 1, "frames": [
      {"position": [0,0,0], "rotation": [[1,0.3,0],[0,1,0],[0,0,1]]}]})";
  EXPECT_EQ(test::RunCommand(
                test::GeodriveBinary() + " render --image " + in.image +
                    " --depth " + in.depth + " --intrinsics " + in.intrinsics +
                    " --trajectory " + bad_traj + " --out " + dir + "/out2",
                &log),
            2)
      << log;
  EXPECT_NE(log.find("orthonormal"), std::string::npos) << log;
  // Zero focal length.
  const std::string bad_k = dir + "/badK.txt";
  std::ofstream(bad_k) << "0 0 127.5 0 250 79.5 0 0 1\n";
  EXPECT_EQ(test::RunCommand(test::GeodriveBinary() + " render --image " +
                                 in.image + " --depth " + in.depth +
                                 " --intrinsics " + bad_k + " --trajectory " +
                                 in.trajectory + " --out " + dir + "/out3",
                             &log),
            2)
      << log;
}

// Option values are checked where parsed: no silent fallback to
// the preset's value for a negative, NaN, trailing-text or out-of-range one.
TEST(RenderCommand, InvalidOptionValuesExitTwoNamingTheOption) {
  const std::string dir = test::MakeTempDir("render_cmd_values");
  const Inputs in = WriteInputs(dir);
  const std::string base = test::GeodriveBinary() + " render --image " +
                           in.image + " --depth " + in.depth +
                           " --intrinsics " + in.intrinsics + " --trajectory " +
                           in.trajectory + " --out " + dir + "/out";
  for (const std::string bad : {"--radius -1", "--radius nan", "--radius 1.5px",
                                "--near -1", "--near 0", "--points-per-pixel 0",
                                "--points-per-pixel 99", "--far -3"}) {
    std::string log;
    EXPECT_EQ(test::RunCommand(base + " " + bad, &log), 2)
        << bad << ": " << log;
    const std::string option = bad.substr(0, bad.find(' '));
    EXPECT_NE(log.find(option), std::string::npos) << bad << ": " << log;
    EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;
    EXPECT_FALSE(std::filesystem::exists(dir + "/out/render.json")) << bad;
  }
  std::string log;
  EXPECT_EQ(test::RunCommand(base + " --radius 0 --far inf --no-video", &log),
            0)
      << log;
}

}  // namespace
}  // namespace geodrive

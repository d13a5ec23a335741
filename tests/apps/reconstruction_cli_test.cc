// The reconstruction formats and trajectory formats on the command line:
// `info` recognises them, `info --to-tum` writes a camera track in evo's
// order, `render --scene TOOL:PATH` renders one, `eval --traj-format auto`
// scores one, bad tool names are one-line errors (exit 2).

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "geometry/npz.h"
#include "geometry/rigid3.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

using test::GeodriveBinary;
using test::RunCommand;
using ::testing::HasSubstr;

// A VGGT predictions.npz of a 64x32 wall 10 m ahead seen from 4 cameras
// moving 1 m forward per frame: extrinsic cam_from_world (S, 3, 4), depth
// (S, H, W, 1), depth_conf (1 + exp(x)), images (S, 3, H, W) in [0, 1].
std::string WriteVggt(const std::string& dir) {
  const int S = 4, H = 32, W = 64;
  std::vector<float> extrinsic, intrinsic, depth, conf, images;
  for (int s = 0; s < S; ++s) {
    const float e[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, -1.f * s};
    extrinsic.insert(extrinsic.end(), e, e + 12);
    const float k[9] = {50, 0, 32, 0, 50, 16, 0, 0, 1};
    intrinsic.insert(intrinsic.end(), k, k + 9);
    for (int i = 0; i < H * W; ++i) {
      depth.push_back(10.f - s);
      conf.push_back(5.f);
    }
    for (int c = 0; c < 3; ++c)
      for (int i = 0; i < H * W; ++i) images.push_back((i % W) / 64.f);
  }
  std::filesystem::create_directories(dir);
  const std::string path = dir + "/predictions.npz";
  WriteNpz(path,
           {{"extrinsic", NpyArray::Float32({S, 3, 4}, extrinsic.data())},
            {"intrinsic", NpyArray::Float32({S, 3, 3}, intrinsic.data())},
            {"depth", NpyArray::Float32({S, H, W, 1}, depth.data())},
            {"depth_conf", NpyArray::Float32({S, H, W}, conf.data())},
            {"images", NpyArray::Float32({S, 3, H, W}, images.data())}},
           false);
  return path;
}

TEST(ReconstructionCli, InfoRenderEvalOnAVggtFile) {
  const std::string tmp = test::MakeTempDir("recon_cli");
  const std::string npz = WriteVggt(tmp + "/vggt");
  std::string out;
  ASSERT_EQ(RunCommand(GeodriveBinary() + " info " + npz, &out), 0) << out;
  EXPECT_THAT(out, HasSubstr("VGGT reconstruction (vggt), 4 frames, grid "
                             "64x32 (vggt-518 resize"));
  EXPECT_THAT(out, HasSubstr("cam_from_world, inverted"));
  // The folder is recognised too.
  ASSERT_EQ(RunCommand(GeodriveBinary() + " info " + tmp + "/vggt", &out), 0)
      << out;
  // Its camera track as TUM: camera i at z = i (world_from_cam).
  ASSERT_EQ(RunCommand(GeodriveBinary() + " info " + npz + " --to-tum " + tmp +
                           "/cams.tum",
                       &out),
            0)
      << out;
  std::ifstream tum(tmp + "/cams.tum");
  std::vector<std::vector<double>> rows;
  for (std::string line; std::getline(tum, line);) {
    std::istringstream ls(line);
    rows.emplace_back(std::istream_iterator<double>(ls),
                      std::istream_iterator<double>());
  }
  ASSERT_EQ(rows.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    ASSERT_EQ(rows[i].size(), 8u);
    EXPECT_NEAR(rows[i][3], i, 1e-6);  // z
    EXPECT_NEAR(rows[i][7], 1, 1e-9);  // qw last
  }
  // Render along its own poses.
  ASSERT_EQ(RunCommand(GeodriveBinary() + " render --scene vggt:" + npz +
                           " --size 32x64 --out " + tmp + "/render",
                       &out),
            0)
      << out;
  std::ifstream json(tmp + "/render/render.json");
  const std::string report((std::istreambuf_iterator<char>(json)), {});
  EXPECT_THAT(report, HasSubstr("VGGT"));
  // The track against itself as TUM: ADE 0.
  ASSERT_EQ(
      RunCommand(GeodriveBinary() + " eval --metrics ade,fde --pred-traj " +
                     npz + " --gt-traj " + tmp +
                     "/cams.tum --traj-format auto --out " + tmp + "/eval.json",
                 &out),
      0)
      << out;
  EXPECT_THAT(out, HasSubstr("4 poses, alignment none: ADE 0, FDE 0"));
  // Bad tool name and an unrecognised path: one line, exit 2.
  EXPECT_EQ(RunCommand(GeodriveBinary() + " render --scene nope:" + npz +
                           " --out " + tmp + "/r2",
                       &out),
            2);
  EXPECT_THAT(out, HasSubstr("unknown format 'nope'"));
  EXPECT_EQ(RunCommand(GeodriveBinary() + " render --scene " + tmp + " --out " +
                           tmp + "/r3",
                       &out),
            2);
  EXPECT_THAT(out, HasSubstr("not a reconstruction this reader recognises"));
}

TEST(ReconstructionCli, InfoReadsTheRealKittiPoses) {
  std::string out;
  const std::string path = test::RealDataPath("kitti_odometry_00/00.txt");
  ASSERT_EQ(RunCommand(GeodriveBinary() + " info " + path, &out), 0) << out;
  EXPECT_THAT(out, HasSubstr("KITTI odometry poses"));
  EXPECT_THAT(out, HasSubstr("4541 poses, length 3724.19, duration 470.582"));
}

}  // namespace
}  // namespace geodrive

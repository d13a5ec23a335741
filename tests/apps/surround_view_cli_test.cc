// `geodrive build-dataset --cameras` as a user runs it: a six-camera rig pair
// is written whole, resumes, and is the same bytes on a rebuild; bad camera
// lists and options that cannot serve a rig are refused at start with one
// line naming the option.

#include <gtest/gtest.h>

#include <filesystem>
#include <map>

#include "tests/common/test_util.h"

namespace geodrive {
namespace surround_view_cli_test {

namespace fs = std::filesystem;
using test::GeodriveBinary;
using test::RunCommand;

const std::string& World() {
  static const std::string dir =
      test::SharedFixtureDir("cli_rig_world", [](const std::string& d) {
        std::string log;
        EXPECT_EQ(RunCommand(GeodriveBinary() + " synth --out " + d +
                                 " --scenes 1 --seed 5 --size 180x320 "
                                 "--duration 2.5 --cameras all",
                             &log),
                  0)
            << log;
      });
  return dir;
}

std::string RigArgs(const std::string& out) {
  return " build-dataset --dataroot " + World() +
         " --geometry lidar-dense --lidar-dense-width 320 --size 90x160 "
         "--cameras all --max-clips 1 --quiet --out " +
         out;
}

// Every file of the pair folders (report and lock aside), by relative path.
std::map<std::string, std::string> PairFiles(const std::string& out) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(out + "/pairs"))
    if (e.is_regular_file())
      files[fs::relative(e.path(), out).string()] =
          test::ReadFile(e.path().string());
  return files;
}

TEST(SurroundViewCli, SixCameraPairIsWholeResumesAndRepeats) {
  const std::string a = test::MakeTempDir("rig_cli_a");
  const std::string b = test::MakeTempDir("rig_cli_b");
  std::string log;
  ASSERT_EQ(RunCommand(GeodriveBinary() + RigArgs(a), &log), 0) << log;
  const auto files = PairFiles(a);
  int cond_videos = 0;
  for (const auto& [rel, bytes] : files)
    cond_videos += rel.find("/cond_CAM_") != std::string::npos;
  EXPECT_EQ(cond_videos, 6);
  const std::string manifest = test::ReadFile(a + "/manifest.jsonl");
  EXPECT_NE(manifest.find("\"cameras\":[\"CAM_FRONT\",\"CAM_FRONT_LEFT\""),
            std::string::npos)
      << manifest;
  // The report shows each camera's frame-0 coverage and the seam check.
  const std::string report = test::ReadFile(a + "/report.html");
  EXPECT_NE(report.find("cameras, frame-0 coverage: CAM_FRONT 0."),
            std::string::npos);
  EXPECT_NE(report.find("seams, depths within 1 % of the overlap: CAM_FRONT"),
            std::string::npos);
  // A rerun verifies the pair (every camera's files listed with their
  // sizes) and builds nothing.
  ASSERT_EQ(RunCommand(GeodriveBinary() + RigArgs(a), &log), 0) << log;
  ASSERT_EQ(RunCommand(GeodriveBinary() + RigArgs(a) + " 2>&1 | cat", &log), 0);
  EXPECT_EQ(PairFiles(a), files);
  // A second build elsewhere: the same bytes.
  ASSERT_EQ(RunCommand(GeodriveBinary() + RigArgs(b), &log), 0) << log;
  EXPECT_EQ(PairFiles(b), files);
}

TEST(SurroundViewCli, BadCameraListsAndRigOptionsAreRefusedAtStart) {
  const std::string out = test::MakeTempDir("rig_cli_bad");
  const std::map<std::string, std::string> cases = {
      {" --cameras CAM_FRONT,,CAM_BACK", "an empty camera name"},
      {" --cameras CAM_BACK,CAM_BACK", "listed twice"},
      {" --cameras CAM_FRONT,LIDAR_TOP",
       "'LIDAR_TOP' is a lidar, not a camera"},
      {" --cameras CAM_FRONT,CAM_NOWHERE", "no sensor 'CAM_NOWHERE'"},
      {" --cameras all --monst3r " + World(),
       "--cameras needs metric geometry"},
      {" --cameras all --lossless-frames", "--lossless-frames"},
      {" --cameras all --export geodrive-upstream",
       "--export geodrive-upstream"},
  };
  for (const auto& [args, expected] : cases) {
    std::string log;
    const int rc = RunCommand(GeodriveBinary() + " build-dataset --dataroot " +
                                  World() + " --out " + out + "/x" + args +
                                  (args.find("--monst3r") == std::string::npos
                                       ? " --geometry lidar"
                                       : " --geometry monst3r"),
                              &log);
    EXPECT_EQ(rc, 2) << args << "\n" << log;
    EXPECT_EQ(test::CountLines(log), 1) << args << "\n" << log;
    EXPECT_NE(log.find(expected), std::string::npos) << args << "\n" << log;
    EXPECT_FALSE(fs::exists(out + "/x/pairs")) << args;
  }
}

}  // namespace surround_view_cli_test
}  // namespace geodrive

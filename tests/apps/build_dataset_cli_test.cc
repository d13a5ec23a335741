// `geodrive build-dataset` as a user runs it: kill -9 and resume, shards +
// merge, mpirun -n 2, and the exit code of a run with failures. Every run must
// give the same files as one uninterrupted single-process run.

#include <gtest/gtest.h>

#include <algorithm>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "tests/common/test_util.h"

namespace geodrive {
namespace {

namespace fs = std::filesystem;
using test::GeodriveBinary;
using test::RunCommand;

std::map<std::string, std::string> OutputFiles(const std::string& out) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(out)) {
    const std::string rel = fs::relative(e.path(), out).string();
    if (!e.is_regular_file() || rel == "report.html" || rel == ".complete" ||
        rel.rfind(".lock", 0) == 0)
      continue;
    // Shard logs are merged into manifest.jsonl / failures.jsonl; compare
    // those.
    if (rel.find(".shard-") != std::string::npos) continue;
    files[rel] = test::ReadFile(e.path().string());
  }
  return files;
}

const std::string& World() {
  static const std::string dir =
      test::SharedFixtureDir("cli_build_world", [](const std::string& d) {
        std::string log;
        const int rc = RunCommand(
            GeodriveBinary() + " synth --out " + d +
                " --scenes 1 --seed 5 --size 450x800 --duration 6.5 --monst3r",
            &log);
        EXPECT_EQ(rc, 0) << log;
      });
  return dir;
}

std::string BuildArgs(const std::string& out) {
  return " build-dataset --dataroot " + World() + " --monst3r " + World() +
         "/monst3r --out " + out + " --quiet";
}

const std::string& Reference() {
  static const std::string out =
      test::SharedFixtureDir("cli_build_reference", [](const std::string& d) {
        std::string log;
        EXPECT_EQ(RunCommand(GeodriveBinary() + BuildArgs(d), &log), 0) << log;
      });
  return out;
}

TEST(BuildDatasetCli, ReferenceRunBuildsEveryMonst3rClip) {
  const std::string manifest = test::ReadFile(Reference() + "/manifest.jsonl");
  EXPECT_EQ(std::count(manifest.begin(), manifest.end(), '\n'), 3)
      << manifest;  // 0, 24, 48
  EXPECT_TRUE(fs::exists(Reference() + "/report.html"));
}

TEST(BuildDatasetCli, KillMinus9AndResumeGivesIdenticalOutput) {
  const std::string out = test::MakeTempDir("cli_build_killed");
  const std::string pidfile = out + ".pid";
  ASSERT_EQ(RunCommand(GeodriveBinary() + BuildArgs(out) +
                       " > /dev/null 2>&1 & echo $! > " + pidfile),
            0);
  const std::string pid = test::ReadFile(pidfile);
  // Wait until the first pair is committed (or the temporary folder of the
  // second appears).
  bool killed = false;
  for (int i = 0; i < 600 && !killed; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    int committed = 0;
    if (fs::exists(out + "/pairs")) {
      for (const auto& e : fs::directory_iterator(out + "/pairs")) {
        committed += e.path().filename().string().rfind(".tmp-", 0) != 0;
      }
    }
    if (committed >= 1) {
      RunCommand("kill -9 " + pid);
      killed = true;
    }
  }
  ASSERT_TRUE(killed) << "the build never committed a pair";
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  size_t pairs_before = 0;
  for (const auto& e : fs::directory_iterator(out + "/pairs")) {
    pairs_before += e.path().filename().string().rfind(".tmp-", 0) != 0;
  }
  std::printf("killed after %zu committed pair(s); resuming\n", pairs_before);
  EXPECT_LT(pairs_before, 3u) << "kill came too late to test resuming";
  std::string log;
  ASSERT_EQ(RunCommand(GeodriveBinary() + BuildArgs(out), &log), 0) << log;
  EXPECT_TRUE(OutputFiles(out) == OutputFiles(Reference()));
}

// SIGTERM stops cleanly after the current clip (exit 130, no temporary folder
// left) and a rerun completes to the same output.
TEST(BuildDatasetCli, SigtermStopsCleanlyAndResumes) {
  const std::string out = test::MakeTempDir("cli_build_sigterm");
  const std::string pidfile = out + ".pid", rcfile = out + ".rc";
  // The subshell's own output is redirected too, so RunCommand does not wait
  // for it.
  ASSERT_EQ(
      RunCommand("(" + GeodriveBinary() + BuildArgs(out) + "; echo $? > " +
                 rcfile + ") > /dev/null 2>&1 & echo $! > " + pidfile),
      0);
  bool signalled = false;
  for (int i = 0; i < 600 && !signalled; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (fs::exists(out + "/pairs") && !fs::is_empty(out + "/pairs")) {
      // The background subshell's child is the builder.
      RunCommand("pkill -TERM -P " + test::ReadFile(pidfile));
      signalled = true;
    }
  }
  ASSERT_TRUE(signalled);
  for (int i = 0; i < 600 && !fs::exists(rcfile); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const std::string rc = test::ReadFile(rcfile);
  int committed = 0, temporary = 0;
  for (const auto& e : fs::directory_iterator(out + "/pairs")) {
    (e.path().filename().string().rfind(".tmp-", 0) == 0 ? temporary
                                                         : committed)++;
  }
  std::printf(
      "SIGTERM: exit %s, %d pair(s) committed, %d temporary folder(s)\n",
      rc.substr(0, rc.size() - 1).c_str(), committed, temporary);
  EXPECT_EQ(temporary, 0);
  if (committed < 3) {
    EXPECT_EQ(rc, "130\n");  // stopped early: "interrupted, rerun to resume"
  }
  std::string log;
  ASSERT_EQ(RunCommand(GeodriveBinary() + BuildArgs(out), &log), 0) << log;
  EXPECT_TRUE(OutputFiles(out) == OutputFiles(Reference()));
}

TEST(BuildDatasetCli, ShardsAndMergeGiveIdenticalOutput) {
  const std::string out = test::MakeTempDir("cli_build_shards");
  std::string log;
  ASSERT_EQ(
      RunCommand(GeodriveBinary() + BuildArgs(out) + " --shard 0/2", &log), 0)
      << log;
  ASSERT_EQ(
      RunCommand(GeodriveBinary() + BuildArgs(out) + " --shard 1/2", &log), 0)
      << log;
  ASSERT_EQ(
      RunCommand(GeodriveBinary() + " build-dataset --merge " + out, &log), 0)
      << log;
  EXPECT_TRUE(OutputFiles(out) == OutputFiles(Reference()));
}

#ifdef GEODRIVE_WITH_MPI
TEST(BuildDatasetCli, MpirunTwoRanksGivesIdenticalOutput) {
  const std::string out = test::MakeTempDir("cli_build_mpi");
  std::string log;
  ASSERT_EQ(RunCommand("mpirun --allow-run-as-root --oversubscribe -n 2 " +
                           GeodriveBinary() + BuildArgs(out),
                       &log),
            0)
      << log;
  EXPECT_NE(log.find("2 MPI ranks"), std::string::npos) << log;
  EXPECT_TRUE(OutputFiles(out) == OutputFiles(Reference()));
}
#endif

TEST(BuildDatasetCli, FailuresGiveExitCodeThreeAndAreRecorded) {
  const std::string root = test::MakeTempDir("cli_build_bad_world");
  fs::copy(World(), root, fs::copy_options::recursive);
  fs::remove(root + "/monst3r/scene-0001_0024/pred_traj.txt");
  const std::string out = test::MakeTempDir("cli_build_bad_out");
  std::string log;
  const int rc = RunCommand(GeodriveBinary() + " build-dataset --dataroot " +
                                root + " --monst3r " + root +
                                "/monst3r --out " + out + " --quiet",
                            &log);
  EXPECT_EQ(rc, 3) << log;
  EXPECT_NE(log.find("completed with failures"), std::string::npos) << log;
  const std::string failures = test::ReadFile(out + "/failures.jsonl");
  EXPECT_NE(failures.find("scene-0001_0024"), std::string::npos) << failures;
  EXPECT_NE(failures.find("pred_traj.txt"), std::string::npos) << failures;
  const std::string manifest = test::ReadFile(out + "/manifest.jsonl");
  EXPECT_EQ(std::count(manifest.begin(), manifest.end(), '\n'), 2) << manifest;
}

TEST(BuildDatasetCli, BadArgumentsExitTwoWithOneLine) {
  std::string log;
  EXPECT_EQ(
      RunCommand(GeodriveBinary() +
                     " build-dataset --dataroot /nonexistent --out /tmp/x",
                 &log),
      2);
  EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;
  EXPECT_NE(log.find("/nonexistent"), std::string::npos) << log;
}

// The bridges to the tools users run: `geodrive clips` says which
// frames make each clip; MonST3R folders stored under GeoDrive's upstream
// naming (sample_%06d/reconstruction/, numbered by clips.jsonl) are found
// through --monst3r-map and give the same pairs as <clip_id>/ folders; and
// --export geodrive-upstream is read back by a Python mirror of the released
// train.py loader.
TEST(BuildDatasetCli, RoundTripClipsUpstreamLayoutAndExport) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("cv2");
  const std::string base = test::MakeTempDir("cli_round_trip");
  std::string log;
  ASSERT_EQ(RunCommand(GeodriveBinary() + " clips --dataroot " + World() +
                           " --out " + base + "/clips",
                       &log),
            0)
      << log;
  // Re-file every MonST3R folder as upstream writes it.
  std::map<std::string, int> index;
  {
    std::ifstream in(base + "/clips/clips.jsonl");
    std::string line;
    while (std::getline(in, line)) {
      const auto id_at = line.find("\"clip_id\":\"") + 11;
      const std::string id = line.substr(id_at, line.find('"', id_at) - id_at);
      const auto idx_at = line.find("\"index\":") + 8;
      index[id] = std::stoi(line.substr(idx_at));
    }
  }
  ASSERT_FALSE(index.empty());
  int moved = 0;
  for (const auto& e : fs::directory_iterator(World() + "/monst3r")) {
    const std::string id = e.path().filename().string();
    ASSERT_TRUE(index.count(id)) << id << " not in clips.jsonl";
    // The clip's own JSON names its 25 frames, in order, and links them.
    const std::string clip_json =
        test::ReadFile(base + "/clips/" + id + "/clip.json");
    EXPECT_NE(clip_json.find("\"upstream_sample\""), std::string::npos);
    EXPECT_TRUE(fs::is_symlink(base + "/clips/" + id + "/images/00024.jpg"));
    char sample[32];
    std::snprintf(sample, sizeof(sample), "sample_%06d", index[id]);
    const fs::path dst =
        fs::path(base) / "upstream" / sample / "reconstruction";
    fs::create_directories(dst.parent_path());
    fs::copy(e.path(), dst, fs::copy_options::recursive);
    ++moved;
  }
  ASSERT_EQ(moved, 3);
  const std::string out = base + "/pairs";
  ASSERT_EQ(
      RunCommand(GeodriveBinary() + " build-dataset --dataroot " + World() +
                     " --monst3r " + base + "/upstream" + " --monst3r-map " +
                     base + "/clips/clips.jsonl" +
                     " --export geodrive-upstream --out " + out + " --quiet",
                 &log),
      0)
      << log;
  // Same condition videos as from <clip_id>/ folders (the export changes the
  // options hash, not the renders).
  for (const auto& e : fs::directory_iterator(Reference() + "/pairs")) {
    const std::string id = e.path().filename().string();
    EXPECT_EQ(test::ReadFile(out + "/pairs/" + id + "/cond.mp4"),
              test::ReadFile(e.path().string() + "/cond.mp4"))
        << id;
  }
  ASSERT_EQ(RunCommand(std::string(test::kDebianPython) +
                           " " GEODRIVE_SOURCE_DIR
                           "/tests/dataset/upstream_loader_check.py " +
                           out + "/geodrive_upstream " + World() + " 3",
                       &log),
            0)
      << log;
  std::printf("%s", log.c_str());
}

// A log line that cannot be written fails the run with a message; it does
// not abort it (failures.jsonl on a full disk: /dev/full).
TEST(BuildDatasetCli, FailuresLogThatCannotBeWrittenFailsTheRunCleanly) {
  const std::string root = test::MakeTempDir("cli_build_full_world");
  fs::copy(World(), root, fs::copy_options::recursive);
  fs::remove(root + "/monst3r/scene-0001_0024/pred_traj.txt");
  const std::string out = test::MakeTempDir("cli_build_full_out");
  fs::create_symlink("/dev/full", out + "/failures.jsonl");
  std::string log;
  const int rc = RunCommand(GeodriveBinary() + " build-dataset --dataroot " +
                                root + " --monst3r " + root +
                                "/monst3r --out " + out + " --quiet",
                            &log);
  EXPECT_EQ(rc, 3) << log;
  EXPECT_NE(log.find("failures.jsonl: append failed"), std::string::npos)
      << log;
  // The final rewrite of failures.jsonl refuses to replace the device.
  EXPECT_NE(log.find("failures.jsonl: exists and is not a regular file (a "
                     "character device)"),
            std::string::npos)
      << log;
  // (and the report, which reads it, says so too)
  EXPECT_NE(log.find("log write errors "), std::string::npos) << log;
  EXPECT_TRUE(fs::is_symlink(out + "/failures.jsonl"));
  const std::string manifest = test::ReadFile(out + "/manifest.jsonl");
  EXPECT_EQ(std::count(manifest.begin(), manifest.end(), '\n'), 2) << manifest;
}

// No command writes over its own inputs.
TEST(RefinePosesCli, RefusesToWriteIntoItsInputFolder) {
  const std::string dir = test::MakeTempDir("cli_refine_inplace");
  fs::copy(World() + "/monst3r/scene-0001_0000", dir,
           fs::copy_options::recursive);
  const std::string before = test::ReadFile(dir + "/pred_traj.txt");
  std::string log;
  const int rc = RunCommand(GeodriveBinary() + " refine-poses --monst3r " +
                                dir + " --out " + dir + "/pred_traj.txt",
                            &log);
  EXPECT_EQ(rc, 2) << log;
  EXPECT_NE(log.find("is inside the input folder"), std::string::npos) << log;
  EXPECT_EQ(test::ReadFile(dir + "/pred_traj.txt"), before);
}

// `fuse --out` inside the MonST3R folder is refused the same way (a
// cloud named like an input there would overwrite it or mix with its files).
TEST(FuseCli, RefusesToWriteIntoItsInputFolder) {
  const std::string dir = test::MakeTempDir("cli_fuse_inplace");
  fs::copy(World() + "/monst3r/scene-0001_0000", dir,
           fs::copy_options::recursive);
  std::string log;
  const int rc = RunCommand(GeodriveBinary() + " fuse --monst3r " + dir +
                                " --out " + dir + "/cloud.ply",
                            &log);
  EXPECT_EQ(rc, 2) << log;
  EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;
  EXPECT_NE(log.find("is inside the input folder"), std::string::npos) << log;
  EXPECT_FALSE(fs::exists(dir + "/cloud.ply"));
}

}  // namespace
}  // namespace geodrive

// Job guarantees of `geodrive` (docs/RELIABILITY.md, "Job guarantees"): one
// lock per output folder whatever the shard; the manifest holds exactly the
// pairs of the current options and inputs; writers replace only regular files;
// SIGINT/SIGTERM give 130 and leave no temporaries; a file-size limit is a
// write error naming the file.

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "dataset/pairs.h"
#include "geometry/util/files.h"
#include "geometry/util/output_file.h"
#include "geometry/util/status.h"
#include "tests/common/temporaries.h"
#include "tests/common/test_util.h"

namespace geodrive {
// A named namespace, not an anonymous one: the unity build compiles this
// file with others of its folder, whose anonymous helpers share names.
namespace job_guarantees_test {

namespace fs = std::filesystem;
using test::GeodriveBinary;
using test::RunCommand;
using test::Temporaries;

// A one-scene synthetic world: a few seconds to build at 96x160.
const std::string& SmallWorld() {
  static const std::string dir =
      test::SharedFixtureDir("job_guarantees_world", [](const std::string& d) {
        std::string log;
        EXPECT_EQ(RunCommand(GeodriveBinary() + " synth --out " + d +
                                 " --scenes 1 --seed 3 --size 180x320 "
                                 "--duration 3",
                             &log),
                  0)
            << log;
      });
  return dir;
}

std::string Build(const std::string& dataroot, const std::string& out) {
  return GeodriveBinary() + " build-dataset --dataroot " + dataroot +
         " --geometry lidar --clip-frames 8 --size 96x160 --quiet --out " + out;
}

std::vector<std::string> ManifestIds(const std::string& out) {
  std::vector<std::string> ids;
  for (const auto& e : ReadManifest(out + "/manifest.jsonl"))
    ids.push_back(e.clip_id);
  return ids;
}

// Instances: a shard while an unsharded run holds the folder, an unsharded
// run and a merge while a shard runs, a shard of another count, the same
// shard twice.
TEST(JobGuarantees, OneLockPerOutputFolderWhateverTheShard) {
  const std::string out = test::MakeTempDir("jg_lock");
  std::string log;
  {
    const OutputFolderLock unsharded(out + "/.lock", "test",
                                     OutputFolderLock::Mode::kExclusive);
    EXPECT_EQ(RunCommand(Build(SmallWorld(), out) + " --shard 0/2", &log), 2)
        << log;
    EXPECT_NE(log.find("another process (pid "), std::string::npos) << log;
  }
  {
    const OutputFolderLock shard(out + "/.lock", "test",
                                 OutputFolderLock::Mode::kShared);
    EXPECT_EQ(RunCommand(Build(SmallWorld(), out), &log), 2) << log;
    EXPECT_NE(log.find("another process (shard runs) is writing it"),
              std::string::npos)
        << log;
    EXPECT_EQ(
        RunCommand(GeodriveBinary() + " build-dataset --merge " + out, &log), 2)
        << log;
    EXPECT_NE(log.find(".lock"), std::string::npos) << log;
    const OutputFolderLock shard0of3(out + "/.lock.shard-0-of-3", "test",
                                     OutputFolderLock::Mode::kExclusive);
    EXPECT_EQ(RunCommand(Build(SmallWorld(), out) + " --shard 1/2", &log), 2)
        << log;
    EXPECT_NE(log.find("shard-0-of-3 is running"), std::string::npos) << log;
    EXPECT_EQ(RunCommand(Build(SmallWorld(), out) + " --shard 0/3", &log), 2)
        << log;
    EXPECT_NE(log.find("shard 0/3 of the output folder"), std::string::npos)
        << log;
  }
  EXPECT_FALSE(fs::exists(out + "/manifest.jsonl"));
  // Free again: shards of one count run, the merge lists every pair.
  ASSERT_EQ(RunCommand(Build(SmallWorld(), out) + " --shard 0/2", &log), 0)
      << log;
  ASSERT_EQ(RunCommand(Build(SmallWorld(), out) + " --shard 1/2", &log), 0)
      << log;
  ASSERT_EQ(
      RunCommand(GeodriveBinary() + " build-dataset --merge " + out, &log), 0)
      << log;
  EXPECT_FALSE(ManifestIds(out).empty());
}

// Instances: another --stride, another --clip-frames, another dataroot (a
// copy of the same world), and a rerun of the same options (skips).
TEST(JobGuarantees, ManifestHoldsExactlyThePairsOfTheCurrentOptionsAndInputs) {
  const std::string out = test::MakeTempDir("jg_manifest");
  std::string log;
  ASSERT_EQ(RunCommand(Build(SmallWorld(), out) + " --stride 8", &log), 0)
      << log;
  const std::vector<std::string> first = ManifestIds(out);
  ASSERT_GE(first.size(), 2u);
  auto check_manifest = [&](int stride, int frames) {
    for (const auto& e : ReadManifest(out + "/manifest.jsonl")) {
      const PairMeta m = ReadPairMeta(out + "/pairs/" + e.clip_id);
      const nlohmann::json o = nlohmann::json::parse(m.options_json);
      EXPECT_EQ(o.at("clip_stride").get<int>(), stride) << e.clip_id;
      EXPECT_EQ(o.at("clip_frames").get<int>(), frames) << e.clip_id;
    }
  };
  // Another stride: other clip ids; the old pairs stay on disk, unlisted.
  ASSERT_EQ(RunCommand(Build(SmallWorld(), out) + " --stride 13", &log), 0)
      << log;
  EXPECT_NE(log.find("left out of manifest.jsonl"), std::string::npos) << log;
  const std::vector<std::string> second = ManifestIds(out);
  EXPECT_NE(second, first);
  check_manifest(13, 8);
  // Another clip length: every clip rebuilt, none skipped.
  ASSERT_EQ(RunCommand(GeodriveBinary() + " build-dataset --dataroot " +
                           SmallWorld() +
                           " --geometry lidar --clip-frames 6 --stride 13 "
                           "--size 96x160 --out " +
                           out,
                       &log),
            0)
      << log;
  EXPECT_NE(log.find("skipped (already built) 0"), std::string::npos) << log;
  check_manifest(13, 6);
  // Another dataroot holding the same files: rebuilt, never "already built".
  const std::string copy = test::MakeTempDir("jg_world_copy");
  fs::copy(SmallWorld(), copy, fs::copy_options::recursive);
  ASSERT_EQ(RunCommand(GeodriveBinary() + " build-dataset --dataroot " + copy +
                           " --geometry lidar --clip-frames 6 --stride 13 "
                           "--size 96x160 --out " +
                           out,
                       &log),
            0)
      << log;
  EXPECT_NE(log.find("skipped (already built) 0"), std::string::npos) << log;
  EXPECT_NE(log.find("were built from other inputs"), std::string::npos) << log;
  EXPECT_NE(log.find("rebuilt (other inputs) " +
                     std::to_string(ManifestIds(out).size())),
            std::string::npos)
      << log;
  for (const auto& id : ManifestIds(out)) {
    const nlohmann::json o =
        nlohmann::json::parse(ReadPairMeta(out + "/pairs/" + id).options_json);
    EXPECT_EQ(o.at("inputs").at("dataroot").get<std::string>(),
              fs::canonical(copy).string());
  }
  // The same options and inputs again: everything skipped.
  ASSERT_EQ(RunCommand(GeodriveBinary() + " build-dataset --dataroot " + copy +
                           " --geometry lidar --clip-frames 6 --stride 13 "
                           "--size 96x160 --out " +
                           out,
                       &log),
            0)
      << log;
  EXPECT_NE(log.find("pairs built 0,"), std::string::npos) << log;
}

// Instances: a FIFO, a folder, /dev/null behind a link, a socket-less
// character device path, through the commit step of every writer; and the
// build's manifest.jsonl linked to /dev/null (the run fails with exit 3
// naming it; /dev/null is not replaced).
TEST(JobGuarantees, WritersReplaceOnlyRegularFiles) {
  const std::string dir = test::MakeTempDir("jg_not_regular");
  const std::string fifo = dir + "/fifo.txt";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
  fs::create_directories(dir + "/folder.txt");
  fs::create_symlink("/dev/null", dir + "/null.txt");
  for (const std::string& path : {fifo, dir + "/folder.txt", dir + "/null.txt",
                                  std::string("/dev/zero")}) {
    try {
      WriteFileAtomic(path, "x");
      ADD_FAILURE() << path << ": written";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(path + ": exists and is not a "
                                                  "regular file"),
                std::string::npos)
          << e.what();
    }
    try {
      WriteViaTemporary(path, ".txt", [](const std::string& tmp) {
        test::WriteFile(tmp, "x");
        return true;
      });
      ADD_FAILURE() << path << ": written";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("not a regular file"),
                std::string::npos)
          << e.what();
    }
  }
  // CommitTemporaryFile (the video and safetensors writers' commit step).
  const std::string tmp = dir + "/.tmp-commit";
  test::WriteFile(tmp, "x");
  EXPECT_THROW(CommitTemporaryFile(tmp, fifo), InputError);
  EXPECT_FALSE(fs::exists(tmp));  // the temporary is removed
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_TRUE(fs::is_directory(dir + "/folder.txt"));
  EXPECT_TRUE(fs::is_character_file(dir + "/null.txt"));
  for (const auto& e : fs::directory_iterator(dir)) {
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos)
        << e.path();
  }
  // A regular file (or a link to one) is replaced as before.
  test::WriteFile(dir + "/plain.txt", "old");
  WriteFileAtomic(dir + "/plain.txt", "new");
  EXPECT_EQ(test::ReadFile(dir + "/plain.txt"), "new");

  const std::string out = test::MakeTempDir("jg_manifest_device");
  fs::create_symlink("/dev/null", out + "/manifest.jsonl");
  std::string log;
  EXPECT_EQ(RunCommand(Build(SmallWorld(), out), &log), 3) << log;
  EXPECT_NE(log.find("manifest.jsonl: exists and is not a regular file (a "
                     "character device)"),
            std::string::npos)
      << log;
  EXPECT_TRUE(fs::is_symlink(out + "/manifest.jsonl"));
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
}

// `ulimit -f`: SIGXFSZ is ignored, the write fails with EFBIG and the job
// reports it: build-dataset exits 3 with each clip's file named; a one-shot
// command (synth) exits 2 naming the file; neither dies of the signal.
TEST(JobGuarantees, FileSizeLimitIsAWriteErrorNamingTheFile) {
  const std::string out = test::MakeTempDir("jg_fsize");
  std::string log;
  const int rc = RunCommand(
      "bash -c 'ulimit -f 16; exec " + Build(SmallWorld(), out) + "' 2>&1",
      &log);
  EXPECT_EQ(rc, 3) << log;
  EXPECT_NE(log.find("completed with failures (see " + out), std::string::npos)
      << log;
  EXPECT_TRUE(Temporaries(out).empty());
  const std::string failures = test::ReadFile(out + "/failures.jsonl");
  EXPECT_NE(failures.find(".mp4: cannot finish the mp4 (File too large)"),
            std::string::npos)
      << failures;

  const std::string world = test::MakeTempDir("jg_fsize_synth");
  const int synth_rc =
      RunCommand("bash -c 'ulimit -f 16; exec " + GeodriveBinary() +
                     " synth --out " + world +
                     " --scenes 1 --size 180x320 "
                     "--duration 3' 2>&1",
                 &log);
  EXPECT_EQ(synth_rc, 2) << log;
  EXPECT_NE(log.find("error: " + world + "/"), std::string::npos) << log;
}

// SIGTERM twice (the second one exits at once): exit 130, no temporary file
// or folder left, the lock free; the rerun completes.
TEST(JobGuarantees, SecondSigtermExitsAt130WithoutTemporaries) {
  const std::string out = test::MakeTempDir("jg_sigterm");
  const std::string pidfile = out + ".pid", rcfile = out + ".rc";
  ASSERT_EQ(RunCommand("(" + Build(SmallWorld(), out) +
                       " --threads 2 --stride 4; echo $? > " + rcfile +
                       ") > /dev/null 2>&1 & echo $! > " + pidfile),
            0);
  bool signalled = false;
  for (int i = 0; i < 600 && !signalled; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (!fs::exists(out + "/pairs")) continue;
    for (const auto& e : fs::directory_iterator(out + "/pairs")) {
      if (e.path().filename().string().rfind(".tmp-", 0) == 0) {
        RunCommand("pkill -TERM -P " + test::ReadFile(pidfile));
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        RunCommand("pkill -TERM -P " + test::ReadFile(pidfile));
        signalled = true;
        break;
      }
    }
  }
  ASSERT_TRUE(signalled);
  for (int i = 0; i < 600 && !fs::exists(rcfile); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(test::ReadFile(rcfile), "130\n");
  EXPECT_TRUE(Temporaries(out).empty()) << Temporaries(out).front();
  EXPECT_FALSE(LockFileIsHeld(out + "/.lock"));
  std::string log;
  EXPECT_EQ(RunCommand(Build(SmallWorld(), out) + " --stride 4", &log), 0)
      << log;
}

}  // namespace job_guarantees_test
}  // namespace geodrive

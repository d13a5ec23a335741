// Job guarantees of `geodrive-diffusion` (docs/RELIABILITY.md, "Job
// guarantees"): no command writes over its own inputs; one train run per
// --out; a resume continues the newest checkpoint; SIGTERM gives 130 and
// leaves no temporary file or folder.

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <thread>

#include "diffusion/safetensors.h"
#include "geometry/util/files.h"
#include "geometry/util/output_file.h"
#include "tests/common/temporaries.h"
#include "tests/common/test_util.h"
#include "tests/diffusion/diffusion_test_util.h"

namespace geodrive {
namespace diffusion {

std::string DiffusionPairsFixture();  // tests/diffusion/pairs_loader_test.cc

// A named namespace, not an anonymous one: the unity build compiles this
// file with others of its folder, whose anonymous helpers share names.
namespace output_guard_test {

namespace fs = std::filesystem;
using test::DiffusionCommand;
using test::RunCommand;
using test::Temporaries;

// Instances: sample --out = --weights spelled otherwise, sample --out a hard
// link of --latents, generate --out inside its --geometry folder.
TEST(OutputGuard, CommandsRefuseAnOutputThatIsAnInput) {
  const std::string dir = test::MakeTempDir("guard_inputs");
  const std::string weights = dir + "/w.safetensors";
  std::string log;
  ASSERT_EQ(RunCommand(DiffusionCommand() +
                           " init-weights --config tiny --out " + weights,
                       &log),
            0)
      << log;
  const std::string before = test::ReadFile(weights);
  SaveSafetensors(dir + "/latents.safetensors",
                  {{"latents", at::zeros({1, 1, 2, 2, 2})}});
  fs::create_hard_link(dir + "/latents.safetensors", dir + "/link.safetensors");
  const std::string sample =
      DiffusionCommand() + " sample --config tiny --weights " + weights +
      " --latents " + dir + "/latents.safetensors --cond-latents " + dir +
      "/latents.safetensors --steps 1 --no-progress";
  EXPECT_EQ(RunCommand(sample + " --out " + dir + "/./w.safetensors", &log), 2)
      << log;
  EXPECT_NE(log.find("is the input " + weights), std::string::npos) << log;
  EXPECT_EQ(RunCommand(sample + " --out " + dir + "/link.safetensors", &log), 2)
      << log;
  EXPECT_NE(log.find("is the input"), std::string::npos) << log;
  EXPECT_EQ(test::ReadFile(weights), before);

  fs::create_directories(dir + "/geometry");
  EXPECT_EQ(
      RunCommand(DiffusionCommand() + " generate --config tiny --weights " +
                     weights + " --geometry " + dir + "/geometry --out " + dir +
                     "/geometry/video.mp4",
                 &log),
      2)
      << log;
  EXPECT_NE(log.find("is inside the input folder " + dir + "/geometry"),
            std::string::npos)
      << log;
  EXPECT_TRUE(fs::is_empty(dir + "/geometry"));
}

// Instances: a second run on a locked --out, a resume from an earlier
// checkpoint than the newest, a new run into an --out with checkpoints. The
// log is left as it was.
TEST(OutputGuard, TrainRunsOnePerOutAndResumesTheNewestCheckpoint) {
  const std::string out = test::MakeTempDir("guard_train");
  const std::string train = DiffusionCommand() +
                            " train --config tiny-49 --pairs " + out +
                            "/train.jsonl --steps 20 --out " + out;
  std::string log;
  {
    const ExclusiveLock other(out + "/.lock", "test");  // a running train
    EXPECT_EQ(RunCommand(train, &log), 2) << log;
    EXPECT_NE(log.find("another process (pid "), std::string::npos) << log;
  }
  fs::create_directories(out + "/checkpoint-6");
  SaveSafetensors(out + "/checkpoint-6/training_state.safetensors",
                  {{"global_step", at::scalar_tensor(6, at::kLong)}},
                  {{"global_step", "6"}});
  fs::create_directories(out + "/checkpoint-10");
  test::WriteFile(out + "/train_log.csv", "log of the earlier run\n");
  EXPECT_EQ(RunCommand(train + " --resume " + out + "/checkpoint-6", &log), 2)
      << log;
  EXPECT_NE(log.find("step 6, but " + out + "/checkpoint-10 is later"),
            std::string::npos)
      << log;
  EXPECT_EQ(RunCommand(train, &log), 2) << log;
  EXPECT_NE(log.find("holds " + out +
                     "/checkpoint-10 of an earlier run: continue it with "
                     "--resume"),
            std::string::npos)
      << log;
  EXPECT_EQ(test::ReadFile(out + "/train_log.csv"), "log of the earlier run\n");
  EXPECT_FALSE(LockFileIsHeld(out + "/.lock"));
}

// SIGTERM while training (checkpoints every step): exit 130, no temporary
// file or folder, the lock released, every checkpoint folder whole.
TEST(OutputGuard, TrainSigtermExits130WithoutTemporaries) {
  const std::string dir = DiffusionPairsFixture();
  const std::string out = test::MakeTempDir("guard_train_sigterm");
  const std::string pidfile = out + ".pid", rcfile = out + ".rc";
  ASSERT_EQ(
      RunCommand("(" + DiffusionCommand() + " train --config tiny-49 --pairs " +
                 dir + "/train.jsonl --out " + out +
                 " --lr 1e-3 --batch 1 --steps 100000 "
                 "--checkpoint-every 1; echo $? > " +
                 rcfile + ") > /dev/null 2>&1 & echo $! > " + pidfile),
      0);
  bool signalled = false;
  for (int i = 0; i < 3000 && !signalled; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (fs::exists(out + "/checkpoint-2")) {
      RunCommand("pkill -TERM -P " + test::ReadFile(pidfile));
      signalled = true;
    }
  }
  ASSERT_TRUE(signalled);
  for (int i = 0; i < 600 && !fs::exists(rcfile); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(test::ReadFile(rcfile), "130\n");
  EXPECT_TRUE(Temporaries(out).empty()) << Temporaries(out).front();
  EXPECT_FALSE(LockFileIsHeld(out + "/.lock"));
  for (const auto& e : fs::directory_iterator(out)) {
    if (e.path().filename().string().rfind("checkpoint-", 0) != 0) continue;
    EXPECT_TRUE(fs::exists(e.path() / "training_state.safetensors"))
        << e.path();
  }
}

}  // namespace output_guard_test
}  // namespace diffusion
}  // namespace geodrive

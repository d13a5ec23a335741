// End-to-end tests of the `geodrive` binary's command-line contract (help,
// version, exit codes).

#include "apps/cli/cli.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <opencv2/core.hpp>

#include "tests/common/test_util.h"

namespace geodrive {
namespace {

using test::GeodriveBinary;
using test::RunCommand;

// Library exceptions reach the user as one line: LibTorch's message without
// its backtrace, OpenCV's without its leading blank line; allocation failures
// in a library's own words are the out-of-memory line.
TEST(Cli, LibraryExceptionsAreOneLine) {
  const std::string torch_error =
      "The size of tensor a (3) must match the size of tensor b (4) at non-"
      "singleton dimension 1\nException raised from infer_size_impl at "
      "../aten/src/ATen/ExpandUtils.cpp:35 (most recent call first):\nframe "
      "#0: c10::Error::Error(...) + 0x6b (0x7f in libc10.so)\n";
  EXPECT_EQ(FirstLineOf(torch_error),
            "The size of tensor a (3) must match the size of tensor b (4) at "
            "non-singleton dimension 1");
  EXPECT_FALSE(IsOutOfMemoryMessage(torch_error));
  const cv::Exception cv_oom(cv::Error::StsNoMem,
                             "Failed to allocate 4900000000 bytes",
                             "OutOfMemoryError", "alloc.cpp", 73);
  EXPECT_TRUE(IsOutOfMemoryMessage(cv_oom.what()));
  EXPECT_EQ(FirstLineOf(cv_oom.what()).find('\n'), std::string::npos);
  EXPECT_NE(FirstLineOf(cv_oom.what()).find("Failed to allocate"),
            std::string::npos);
  EXPECT_TRUE(IsOutOfMemoryMessage(
      "[enforce fail at alloc_cpu.cpp:75] err == 0. DefaultCPUAllocator: "
      "can't allocate memory: you tried to allocate 10737418240 bytes."));
  EXPECT_EQ(FirstLineOf("\n\n  padded  \n"), "padded");
  EXPECT_EQ(FirstLineOf(""), "(no message)");
  EXPECT_EQ(FirstLineOf(std::string(1000, 'x')).size(), 403u);
}

TEST(Cli, HelpListsSubcommands) {
  std::string out;
  ASSERT_EQ(RunCommand(GeodriveBinary() + " --help", &out), 0);
  EXPECT_NE(out.find("info"), std::string::npos) << out;
}

TEST(Cli, VersionPrintsVersion) {
  std::string out;
  ASSERT_EQ(RunCommand(GeodriveBinary() + " --version", &out), 0);
  EXPECT_NE(out.find("geodrive 0."), std::string::npos) << out;
}

TEST(Cli, UnknownSubcommandExitsTwoWithOneLine) {
  std::string out;
  EXPECT_EQ(RunCommand(GeodriveBinary() + " no-such-command", &out), 2);
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
}

TEST(Cli, NoSubcommandExitsTwo) { EXPECT_EQ(RunCommand(GeodriveBinary()), 2); }

// Every --threads is checked where parsed: `--threads 100000` would make
// libgomp fail (or crash) with a raw message of its own.
TEST(Cli, ThreadCountsAreCheckedWhereParsed) {
  for (const std::string& args :
       {std::string("refine-poses --monst3r /nonexistent --out /tmp/x.txt "
                    "--threads 100000"),
        std::string("refine-poses --monst3r /nonexistent --out /tmp/x.txt "
                    "--threads 1000"),
        std::string("render --cloud /nonexistent.ply --out /tmp/x "
                    "--threads 1000"),
        std::string("render --cloud /nonexistent.ply --out /tmp/x "
                    "--threads 4x"),
        std::string("build-dataset --dataroot /nonexistent --out /tmp/x "
                    "--threads 0"),
        std::string("eval --pred a --gt b --out r.json --threads -1")}) {
    std::string out;
    EXPECT_EQ(RunCommand(GeodriveBinary() + " " + args, &out), 2) << args;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
    EXPECT_NE(out.find("--threads"), std::string::npos) << out;
  }
}

// An output folder that cannot be created is bad input (exit 2), found
// before any metric is computed. Here the folder would have to be created
// under a regular file.
TEST(Cli, UnusableOutputFolderIsBadInputFoundFirst) {
  const std::string file = test::MakeTempDir("cli_out") + "/a_file";
  std::ofstream(file) << "x";
  for (const std::string& args :
       {"render --cloud /nonexistent.ply --trajectory /nonexistent.json "
        "--out " +
            file + "/sub",
        "eval --pred /nonexistent --gt /nonexistent --out " + file +
            "/sub/report.json",
        "clips --dataroot /nonexistent --out " + file + "/sub"}) {
    std::string out;
    EXPECT_EQ(RunCommand(GeodriveBinary() + " " + args, &out), 2) << args;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
    EXPECT_NE(out.find(file + "/sub"), std::string::npos) << out;
  }
}

}  // namespace
}  // namespace geodrive

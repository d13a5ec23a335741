// End-to-end tests of the `geodrive` binary's command-line contract (help, version, exit codes).

#include <gtest/gtest.h>

#include "tests/common/test_util.h"

namespace geodrive {
namespace {

using test::GeodriveBinary;
using test::RunCommand;

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

}  // namespace
}  // namespace geodrive

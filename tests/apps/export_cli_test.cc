// `geodrive export` and `build-dataset --export` as a user runs them: bad
// formats, outputs and clip lengths exit 2 with one line naming the problem.

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "tests/common/test_util.h"

namespace geodrive {
namespace export_cli_test {

using test::GeodriveBinary;
using test::RunCommand;

TEST(ExportCli, BadArgumentsExitTwoWithOneLineNamingTheProblem) {
  const std::string out = test::MakeTempDir("export_cli_bad");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {" export --pairs /nonexistent --format streetcrafter", "/nonexistent"},
      {" export --pairs " + out + " --format gen4c", "unknown format 'gen4c'"},
      {" export --pairs /nonexistent --format gen3c", "/nonexistent"},
      {" build-dataset --dataroot " + out + " --out " + out +
           "/x --export gen3c --clip-frames 41",
       "gen3c needs 121, 241, ... frames (120 N + 1) per clip; --clip-frames "
       "is 41"},
      {" build-dataset --dataroot " + out + " --out " + out +
           "/x --export streetcrafter --clip-frames 20",
       "streetcrafter needs 25 frames per clip; --clip-frames is 20"},
      {" build-dataset --dataroot " + out + " --out " + out +
           "/x --export streetcrafter --preset geodrive-compat",
       "not geodrive-compat"},
      {" build-dataset --dataroot " + out + " --out " + out +
           "/x --export streetcrafter --val-fraction 1.5",
       "--val-fraction must be in [0, 1]"},
  };
  for (const auto& [args, expected] : cases) {
    std::string log;
    EXPECT_EQ(RunCommand(GeodriveBinary() + args, &log), 2) << args << log;
    EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << args << log;
    EXPECT_NE(log.find(expected), std::string::npos) << args << log;
  }
}

}  // namespace export_cli_test
}  // namespace geodrive

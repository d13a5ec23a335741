// `geodrive plan` end to end on the synthetic world: the logged trajectory,
// its shifts, a candidate file and the lattice are scored into plan.json and
// bev.png, the same bytes twice; a bad candidate is one clear error.

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "tests/common/test_util.h"

namespace plan_cli_test {

using geodrive::test::GeodriveBinary;
using geodrive::test::RunCommand;

// The same world as build_dataset_cli_test.cc's (one shared fixture).
const std::string& World() {
  static const std::string dir = geodrive::test::SharedFixtureDir(
      "cli_build_world", [](const std::string& d) {
        std::string log;
        const int rc = RunCommand(
            GeodriveBinary() + " synth --out " + d +
                " --scenes 1 --seed 5 --size 450x800 --duration 6.5 --monst3r",
            &log);
        EXPECT_EQ(rc, 0) << log;
      });
  return dir;
}

std::string PlanArgs(const std::string& out) {
  return " plan --dataroot " + World() + " --clip scene-0001_0024 --out " + out;
}

TEST(PlanCli, ScoresEveryKindOfCandidateIntoPlanJsonAndBev) {
  const std::string dir = geodrive::test::MakeTempDir("plan_cli");
  // Straight ahead at 8 m/s for 2 s, one waypoint per 12 Hz frame.
  std::string jsonl;
  for (int i = 0; i <= 24; ++i) {
    jsonl += "{\"t\": " + std::to_string(i / 12.0) +
             ", \"x\": " + std::to_string(8.0 * i / 12.0) + ", \"y\": 0}\n";
  }
  geodrive::test::WriteFile(dir + "/straight.jsonl", jsonl);
  std::string log;
  const std::string args = PlanArgs(dir + "/a") + " --shifts 1 --sample 5 " +
                           "--candidates " + dir + "/straight.jsonl";
  ASSERT_EQ(RunCommand(GeodriveBinary() + args, &log), 0) << log;
  EXPECT_NE(log.find("plan scene-0001_0024: 9 candidates"), std::string::npos)
      << log;
  const nlohmann::json plan =
      nlohmann::json::parse(geodrive::test::ReadFile(dir + "/a/plan.json"));
  EXPECT_EQ(plan["format"], "geodrive-plan");
  ASSERT_EQ(plan["candidates"].size(), 9u);
  ASSERT_EQ(plan["ranking"].size(), 9u);
  const nlohmann::json& logged = plan["candidates"][0];
  EXPECT_EQ(logged["name"], "logged");
  EXPECT_FALSE(logged["collision"]["collides"].get<bool>());
  EXPECT_DOUBLE_EQ(logged["logged"]["ade_m"].get<double>(), 0.0);
  EXPECT_GE(logged["drivable"]["fraction"].get<double>(), 0.99);
  EXPECT_EQ(plan["candidates"][1]["name"], "logged+1m");
  EXPECT_EQ(plan["candidates"][3]["name"], "straight");
  EXPECT_EQ(plan["candidates"][3]["waypoints"], 25);
  const std::string png = geodrive::test::ReadFile(dir + "/a/bev.png");
  ASSERT_GT(png.size(), 8u);
  EXPECT_EQ(png.substr(1, 3), "PNG");
  // Deterministic: the same bytes again.
  ASSERT_EQ(RunCommand(GeodriveBinary() + PlanArgs(dir + "/b") +
                           " --shifts 1 --sample 5 --candidates " + dir +
                           "/straight.jsonl",
                       &log),
            0)
      << log;
  EXPECT_EQ(geodrive::test::ReadFile(dir + "/a/plan.json"),
            geodrive::test::ReadFile(dir + "/b/plan.json"));
  EXPECT_EQ(png, geodrive::test::ReadFile(dir + "/b/bev.png"));
}

TEST(PlanCli, VisibilityAndConditionVideosOfTheBest) {
  const std::string dir = geodrive::test::MakeTempDir("plan_cli_videos");
  std::string log;
  ASSERT_EQ(RunCommand(GeodriveBinary() + PlanArgs(dir + "/o") +
                           " --shifts 1 --visibility --videos 2",
                       &log),
            0)
      << log;
  const nlohmann::json plan =
      nlohmann::json::parse(geodrive::test::ReadFile(dir + "/o/plan.json"));
  for (const nlohmann::json& c : plan["candidates"]) {
    const double mean = c["visibility"]["mean_coverage"].get<double>();
    EXPECT_GT(mean, 0.0);
    EXPECT_LE(mean, 1.0);
    EXPECT_LE(c["visibility"]["min_coverage"].get<double>(), mean);
  }
  const std::string best = plan["ranking"][0].get<std::string>();
  const std::string second = plan["ranking"][1].get<std::string>();
  EXPECT_GT(
      geodrive::test::ReadFile(dir + "/o/videos/001_" + best + ".mp4").size(),
      1000u);
  EXPECT_GT(
      geodrive::test::ReadFile(dir + "/o/videos/002_" + second + ".mp4").size(),
      1000u);
  EXPECT_EQ(geodrive::test::ReadFile(dir + "/o/videos/003_x.mp4"), "");
  // The clip's frame 0 beside them: generate's --image.
  EXPECT_GT(geodrive::test::ReadFile(dir + "/o/videos/first_frame.png").size(),
            1000u);
}

TEST(PlanCli, BadCandidatesAreOneClearError) {
  const std::string dir = geodrive::test::MakeTempDir("plan_cli_bad");
  const std::string jump = dir + "/jump.jsonl";
  geodrive::test::WriteFile(jump,
                            "{\"t\": 0, \"x\": 0, \"y\": 0}\n"
                            "{\"t\": 0.1, \"x\": 1, \"y\": 0}\n"
                            "{\"t\": 0.2, \"x\": 101, \"y\": 0}\n");
  std::string log;
  EXPECT_EQ(RunCommand(GeodriveBinary() + PlanArgs(dir + "/o") +
                           " --candidates " + jump,
                       &log),
            2);
  EXPECT_EQ(log, "geodrive plan: error: " + jump +
                     ":3: jumps 100 m in 0.1 s (1000 m/s > the limit 100 "
                     "m/s)\n");
  EXPECT_EQ(RunCommand(GeodriveBinary() + PlanArgs(dir + "/o") + " --no-logged",
                       &log),
            2);
  EXPECT_NE(log.find("no candidates"), std::string::npos) << log;
  EXPECT_EQ(
      RunCommand(GeodriveBinary() + PlanArgs(dir + "/o") + " --weight ade=1",
                 &log),
      2);
  EXPECT_NE(log.find("--weight: 'ade=1' is not NAME=VALUE"), std::string::npos)
      << log;
}

}  // namespace plan_cli_test

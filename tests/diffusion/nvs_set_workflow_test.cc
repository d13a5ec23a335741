// The novel-view protocol end to end on synthetic Waymo segments, through the
// command-line tools only (README "Waymo", docs/how-to/waymo.md):
//
//   geodrive synth --format waymo       (3 short segments)
//   geodrive nvs-set --offsets=-3,3     (3 segments x 2 offsets = 6 pairs)
//   geodrive-diffusion init-weights (+ --vae)
//   geodrive-diffusion generate --manifest   (tiny config, 2 steps)
//   geodrive eval --metrics fid,fvd     (small TorchScript stand-ins)
//
// The generated shifted views are compared, as distributions, with the real
// frames of the segments (the pairs' gt.mp4).

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "dataset/pairs.h"
#include "render/video/video_io.h"
#include "tests/common/test_util.h"
#include "tests/diffusion/diffusion_test_util.h"

namespace geodrive {
namespace nvs_set_workflow_test {
namespace {

namespace fs = std::filesystem;

// Runs `command`; the test fails with its output when it does not exit 0.
::testing::AssertionResult Ran(const std::string& command) {
  std::string log;
  const int rc = test::RunCommand(command, &log);
  if (rc == 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << command << " exited " << rc << ":\n"
                                       << log;
}

TEST(NvsSetWorkflow, SynthNvsSetGenerateEvalFidFvd) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("torch");
  const std::string dir = test::MakeTempDir("nvs_set_workflow");
  const std::string g = test::GeodriveBinary();
  const std::string diffusion = test::DiffusionCommand();
  ASSERT_TRUE(Ran(g + " synth --format waymo --out " + dir +
                  "/w --scenes 3 --seed 7 --size 96x144 --duration 1.2 "
                  "--lidar-columns 400"));
  // Pairs of the tiny model's clip length (9 frames) and pixel size (32x48).
  const std::string nvs = dir + "/nvs";
  ASSERT_TRUE(Ran(g + " nvs-set --dataroot " + dir + "/w --offsets=-3,3 " +
                  "--frames 9 --size 32x48 --threads 2 --quiet --out " + nvs));
  const std::vector<ManifestEntry> manifest =
      ReadManifest(nvs + "/manifest.jsonl");
  ASSERT_EQ(manifest.size(), 6u);

  const std::string weights = dir + "/tiny.safetensors";
  const std::string vae = dir + "/vae.safetensors";
  ASSERT_TRUE(
      Ran(diffusion + " init-weights --config tiny --seed 0 --out " + weights));
  ASSERT_TRUE(Ran(diffusion +
                  " init-weights --vae --config tiny --seed 0 --out " + vae));
  const std::string pred = dir + "/pred";
  ASSERT_TRUE(Ran(diffusion + " generate --config tiny --manifest " + nvs +
                  "/manifest.jsonl --out-dir " + pred + " --weights " +
                  weights + " --vae-weights " + vae +
                  " --steps 2 --seed 0 --no-progress"));
  for (const ManifestEntry& e : manifest) {
    const std::vector<cv::Mat> frames =
        ReadVideoFrames(pred + "/" + e.clip_id + ".mp4");
    ASSERT_EQ(frames.size(), 9u) << e.clip_id;
    EXPECT_EQ(frames[0].cols, 48);
    EXPECT_EQ(frames[0].rows, 32);
  }

  // FID and FVD with the small stand-ins of tests/eval (16 and 4 features:
  // 54 frames and 6 clips are more samples than dimensions).
  const std::string models = dir + "/models";
  ASSERT_TRUE(Ran(std::string(test::kDebianPython) +
                  " " GEODRIVE_SOURCE_DIR
                  "/tests/eval/make_torchscript_models.py " +
                  models));
  const std::string report = dir + "/eval/report.json";
  ASSERT_TRUE(Ran(g + " eval --pred " + pred + " --gt " + nvs +
                  "/pairs --metrics fid,fvd --fid-model " + models +
                  "/inception_like.pt --fvd-model " + models +
                  "/i3d_small.pt --threads 1 --out " + report));
  std::ifstream in(report);
  const nlohmann::json j = nlohmann::json::parse(in);
  const nlohmann::json& s = j.at("summary");
  const double fid = s.at("fid").at("value").get<double>();
  const double fvd = s.at("fvd").at("value").get<double>();
  std::printf("6 novel views (tiny model, 2 steps): FID %.4g, FVD %.4g\n", fid,
              fvd);
  // Random weights, 2 steps: far from the real frames, but real numbers.
  EXPECT_TRUE(std::isfinite(fid) && fid > 0) << fid;
  EXPECT_TRUE(std::isfinite(fvd) && fvd > 0) << fvd;
  EXPECT_EQ(s.at("fid").at("pred_samples").get<int>(), 54);
  EXPECT_EQ(s.at("fid").at("gt_samples").get<int>(), 54);
  EXPECT_EQ(s.at("fvd").at("pred_samples").get<int>(), 6);
  EXPECT_EQ(s.at("fvd").at("gt_samples").get<int>(), 6);
  ASSERT_EQ(j.at("videos").size(), 6u);
  for (size_t k = 0; k < manifest.size(); ++k)
    EXPECT_EQ(j.at("videos")[k].at("id"), manifest[k].clip_id);
}

}  // namespace
}  // namespace nvs_set_workflow_test
}  // namespace geodrive

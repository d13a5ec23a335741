// The user's workflow end to end, for each tiny config, through the two
// command-line tools only (docs/DIFFUSION.md "Workflow"):
//
//   geodrive synth --monst3r            (the built-in demo data)
//   geodrive build-dataset              (pairs at the model's pixel size)
//   geodrive-diffusion init-weights     (random tiny backbone)
//   geodrive-diffusion init-weights --vae  (random tiny VAE)
//   geodrive-diffusion train            (a few steps, no validation set)
//   geodrive-diffusion generate --manifest --limit 2
//   geodrive eval --subset predicted    (2 predicted of 3 ground-truth clips)
//
// The tiny VAE file is passed to both train and generate, so both use the
// same VAE (without --vae-weights each draws its own random one).

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "dataset/pairs.h"
#include "diffusion/config.h"
#include "diffusion/safetensors.h"
#include "diffusion/vae.h"
#include "diffusion/vae_config.h"
#include "geometry/util/status.h"
#include "render/video/video_io.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace diffusion {
namespace {

namespace fs = std::filesystem;

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string Geodrive() { return test::GeodriveBinary(); }
std::string Diffusion() {
  return std::string("OMP_NUM_THREADS=1 ") + GEODRIVE_DIFFUSION_BINARY;
}

// test::RunCommand, adding "<name> <seconds>" to *times (the test prints
// where its time goes).
int Timed(const std::string& name,
          const std::string& command,
          std::string* log,
          std::string* times) {
  const auto start = std::chrono::steady_clock::now();
  const int rc = test::RunCommand(command, log);
  const double s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  char text[64];
  std::snprintf(text, sizeof(text), "%s%s %.1f s", times->empty() ? "" : ", ",
                name.c_str(), s);
  *times += text;
  return rc;
}

// The demo world, shared by the configs: the README demo's `synth --monst3r`
// made small. One scene of 3.5 s (43 CAM_FRONT frames) at 90x160 with a
// sparse LiDAR, and MonST3R folders for the first 3 clips of build-dataset's
// default stride (frames 0-24, 6-30, 12-36). The MonST3R folders are what
// costs: 512x288 per frame whatever the camera size, about 2 s per clip.
std::string DemoWorld() {
  static const std::string dir =
      test::SharedFixtureDir("workflow_world", [](const std::string& d) {
        std::string log, times;
        const std::string cmd = Geodrive() + " synth --out " + d +
                                "/world --scenes 1 --seed 7 --size 90x160 "
                                "--duration 3.5 --lidar-azimuth-steps 180 "
                                "--monst3r --monst3r-stride 6 "
                                "--monst3r-max-clips 3";
        if (Timed("synth", cmd, &log, &times) != 0)
          throw std::runtime_error(cmd + " failed:\n" + log);
        std::printf("demo world: %s\n", times.c_str());
      });
  return dir + "/world";
}

struct WorkflowCase {
  std::string config;
  // build-dataset arguments choosing the clips: eval compares equal frame
  // counts, so a pair may not be longer than the model's clip (tiny: 9;
  // tiny-49: 49, the demo's 25-frame pairs padded to 49 and written as 25).
  std::string clip_args;
  int frames;  // frames per pair and per generated video
};

void RunWorkflow(const WorkflowCase& c) {
  const std::string world = DemoWorld();
  const std::string dir = test::MakeTempDir("workflow_" + c.config);
  std::string log, times;

  // 1. Pairs at the model's pixel size (32x48), 3 clips.
  const std::string pairs = dir + "/pairs";
  ASSERT_EQ(Timed("build-dataset",
                  Geodrive() + " build-dataset --dataroot " + world +
                      " --version v1.0-mini --out " + pairs +
                      " --size 32x48 --max-clips 3 --threads 2 "
                      "--quiet " +
                      c.clip_args,
                  &log, &times),
            0)
      << log;
  const std::vector<ManifestEntry> manifest =
      ReadManifest(pairs + "/manifest.jsonl");
  ASSERT_EQ(manifest.size(), 3u) << log;

  // 2. Weights: a random tiny backbone (+ encoder) and the tiny VAE.
  const std::string weights = dir + "/tiny.safetensors";
  ASSERT_EQ(Timed("init-weights",
                  Diffusion() + " init-weights --config " + c.config +
                      " --seed 0 --out " + weights,
                  &log, &times),
            0)
      << log;
  const std::string vae = dir + "/vae.safetensors";
  ASSERT_EQ(Timed("init-weights --vae",
                  Diffusion() + " init-weights --vae --config " + c.config +
                      " --seed 0 --out " + vae,
                  &log, &times),
            0)
      << log;
  {
    // The file holds exactly the VAE's table (diffusers names) and its seeded
    // weights.
    SafetensorsCheckpoint ckpt(vae);
    const Weights w = VaeInitWeights(VaePreset(c.config), 0);
    ASSERT_EQ(ckpt.entries().size(), w.order.size());
    for (const std::string& name : {w.order.front(), w.order.back()})
      EXPECT_TRUE(at::equal(ckpt.Load(name), w.Get(name))) << name;
  }

  // 3. Train a few steps without a validation set.
  const std::string run = dir + "/run";
  ASSERT_EQ(
      Timed("train",
            Diffusion() + " train --config " + c.config + " --pairs " + pairs +
                "/manifest.jsonl --weights " + weights + " --vae-weights " +
                vae + " --out " + run + " --steps 2 --lr 1e-3 --seed 0",
            &log, &times),
      0)
      << log;
  // No validation set: no "val" on the progress line, no sentinel anywhere.
  EXPECT_NE(log.find("train ["), std::string::npos) << log;
  EXPECT_EQ(log.find(" val "), std::string::npos) << log;
  EXPECT_EQ(log.find("-1.0"), std::string::npos) << log;
  const std::string branch =
      run + "/checkpoint-2/branch/diffusion_pytorch_model.safetensors";
  ASSERT_TRUE(fs::exists(branch)) << log;
  const std::string csv = ReadText(run + "/train_log.csv");
  std::istringstream rows(csv);
  std::string line;
  std::getline(rows, line);
  EXPECT_EQ(line, "step,loss,val_loss,lr,grad_norm,seconds");
  int steps = 0;
  while (std::getline(rows, line)) {
    ++steps;
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
    ASSERT_EQ(cells.size(), 6u) << line;
    EXPECT_EQ(cells[0], std::to_string(steps)) << line;
    EXPECT_TRUE(std::isfinite(std::stod(cells[1]))) << line;
    EXPECT_EQ(cells[2], "") << "val_loss without --val-pairs: " << line;
  }
  EXPECT_EQ(steps, 2) << csv;
  const nlohmann::json tlog =
      nlohmann::json::parse(ReadText(run + "/train_log.json"));
  for (const auto& row : tlog.at("log"))
    EXPECT_TRUE(row.at("val_loss").is_null()) << row.dump();

  // 4. Generate the first 2 pairs with the trained encoder.
  const std::string pred = dir + "/pred";
  ASSERT_EQ(Timed("generate",
                  Diffusion() + " generate --config " + c.config +
                      " --manifest " + pairs + "/manifest.jsonl --out-dir " +
                      pred + " --limit 2 --weights " + weights +
                      " --branch-weights " + branch + " --vae-weights " + vae +
                      " --steps 2 --seed 0 --no-progress",
                  &log, &times),
            0)
      << log;
  for (int i = 0; i < 3; ++i) {
    const std::string video = pred + "/" + manifest[i].clip_id + ".mp4";
    if (i < 2) {
      ASSERT_TRUE(fs::exists(video)) << log;
      const std::vector<cv::Mat> frames = ReadVideoFrames(video);
      ASSERT_EQ(static_cast<int>(frames.size()), c.frames) << video;
      EXPECT_EQ(frames[0].cols, 48);
      EXPECT_EQ(frames[0].rows, 32);
    } else {
      EXPECT_FALSE(fs::exists(video)) << "--limit 2 generated " << video;
    }
  }

  // 5. Eval: the default refuses a partial prediction set and says how to
  // evaluate the subset; --subset predicted evaluates 2 of the 3 clips.
  const std::string eval = Geodrive() + " eval --pred " + pred + " --gt " +
                           pairs + "/pairs --threads 1 --out " + dir +
                           "/eval/report.json";
  ASSERT_EQ(Timed("eval (refused)", eval, &log, &times), 2) << log;
  EXPECT_NE(log.find("1 of 3 ground-truth videos have no prediction"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("--subset predicted"), std::string::npos) << log;
  ASSERT_EQ(Timed("eval", eval + " --subset predicted", &log, &times), 0)
      << log;
  EXPECT_NE(log.find("2 predicted of 3 ground-truth videos evaluated"),
            std::string::npos)
      << log;
  const nlohmann::json report =
      nlohmann::json::parse(ReadText(dir + "/eval/report.json"));
  const auto& subset = report.at("subset");
  EXPECT_EQ(subset.at("mode"), "predicted");
  EXPECT_EQ(subset.at("evaluated"), 2);
  EXPECT_EQ(subset.at("ground_truth"), 3);
  EXPECT_EQ(subset.at("without_prediction"),
            nlohmann::json::array({manifest[2].clip_id}));
  ASSERT_EQ(report.at("videos").size(), 2u);
  for (int i = 0; i < 2; ++i) {
    const auto& v = report.at("videos")[i];
    EXPECT_EQ(v.at("id"), manifest[i].clip_id);
    EXPECT_EQ(v.at("frames"), c.frames);
  }
  // Random weights, 2 sampling steps: far from the ground truth, but real
  // numbers (PSNR of unrelated 8-bit images is a few dB to ~20 dB).
  const double psnr = report.at("summary").at("psnr").at("mean");
  const double ssim = report.at("summary").at("ssim").at("mean");
  EXPECT_TRUE(std::isfinite(psnr) && psnr > 3.0 && psnr < 40.0) << psnr;
  EXPECT_TRUE(std::isfinite(ssim) && ssim > -1.0 && ssim < 0.9) << ssim;
  EXPECT_EQ(report.at("summary").at("psnr").at("videos"), 2);
  EXPECT_NE(ReadText(dir + "/eval/report.md")
                .find("2 predicted of 3 ground-truth videos evaluated"),
            std::string::npos);
  std::printf("%s: psnr %.2f dB, ssim %.4f over %d-frame clips; %s\n",
              c.config.c_str(), psnr, ssim, c.frames, times.c_str());
}

// One --config names both models: every DiT preset has a VAE preset with its
// latent channels, and VaePreset takes the DiT name (generate's and
// vae-encode's VaePreset(--config)).
TEST(Workflow, EveryConfigPresetNamesItsVae) {
  for (const std::string& name : ConfigPresetNames()) {
    const DiTConfig dit = ConfigPreset(name);
    const VaeConfig vae = VaePreset(name);
    EXPECT_EQ(vae.name, VaePresetNameForConfig(name)) << name;
    EXPECT_EQ(vae.latent_channels, dit.out_channels) << name;
  }
  EXPECT_EQ(VaePreset("tiny-49").name, "tiny");
  EXPECT_EQ(VaePreset("cogvideox-5b-i2v").latent_channels, 16);
  try {
    VaePreset("huge");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("huge: unknown VAE preset"), std::string::npos) << what;
    EXPECT_NE(what.find("tiny-49"), std::string::npos) << what;
  }
  EXPECT_THROW(VaePresetNameForConfig("huge"), InputError);
}

// tiny generates 9 frames: 9-frame clips, so the LiDAR geometry (the demo's
// MonST3R folders hold 25-frame clips).
TEST(Workflow, TinyBuildTrainGenerateEval) {
  RunWorkflow({"tiny", "--geometry lidar --clip-frames 9", 9});
}

// tiny-49 generates 49 frames: the demo's 25-frame MonST3R pairs, padded to
// 49 in train and generate as upstream, 25 frames written.
TEST(Workflow, Tiny49BuildTrainGenerateEval) {
  RunWorkflow({"tiny-49", "--monst3r " + DemoWorld() + "/monst3r", 25});
}

}  // namespace
}  // namespace diffusion
}  // namespace geodrive

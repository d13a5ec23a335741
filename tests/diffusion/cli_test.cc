// The `geodrive-diffusion` binary: help, init-weights, check-weights,
// deterministic sampling and bad-input exit codes.

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include "diffusion/config.h"
#include "diffusion/safetensors.h"
#include "tests/common/test_util.h"
#include "tests/diffusion/diffusion_test_util.h"

namespace geodrive {
namespace diffusion {
namespace {

// Writes tiny image/cond latents and prompt embeddings into `dir`.
void WriteTinyInputs(const std::string& dir, uint64_t seed) {
  const DiTConfig c = ConfigPreset("tiny");
  at::manual_seed(seed);
  const int64_t C = c.out_channels, F = c.latent_frames, H = c.latent_height,
                W = c.latent_width;
  SaveSafetensors(dir + "/image.safetensors",
                  {{"latents", at::randn({1, 1, C, H, W})}});
  SaveSafetensors(dir + "/cond.safetensors",
                  {{"latents", at::randn({1, F, C, H, W})}});
  SaveSafetensors(
      dir + "/prompt.safetensors",
      {{"prompt_embeds", at::randn({1, c.text_seq_len, c.text_embed_dim})},
       {"negative_prompt_embeds",
        at::randn({1, c.text_seq_len, c.text_embed_dim})}});
}

TEST(DiffusionCli, HelpListsSubcommands) {
  std::string out;
  ASSERT_EQ(test::RunCommand(test::DiffusionCommand() + " --help", &out), 0)
      << out;
  for (const char* sub : {"sample", "init-weights", "check-weights", "names"}) {
    EXPECT_NE(out.find(sub), std::string::npos) << sub;
  }
  ASSERT_EQ(test::RunCommand(test::DiffusionCommand() + " sample --help", &out),
            0)
      << out;
  EXPECT_NE(out.find("--cond-latents"), std::string::npos);
  EXPECT_EQ(
      test::RunCommand(test::DiffusionCommand() + " sample --bogus", &out), 2)
      << out;
}

TEST(DiffusionCli, SampleIsDeterministicForASeed) {
  const std::string dir = test::MakeTempDir("diffusion_cli_sample");
  std::string out;
  ASSERT_EQ(test::RunCommand(
                test::DiffusionCommand() +
                    " init-weights --config tiny --nonzero-branch --out " +
                    dir + "/w.safetensors",
                &out),
            0)
      << out;
  ASSERT_EQ(test::RunCommand(test::DiffusionCommand() +
                                 " check-weights --config tiny --weights " +
                                 dir + "/w.safetensors",
                             &out),
            0)
      << out;
  EXPECT_NE(out.find("0 missing, 0 unexpected, 0 shape-mismatched"),
            std::string::npos)
      << out;
  WriteTinyInputs(dir, 1);
  auto sample = [&](const std::string& name, int seed,
                    const std::string& extra) {
    std::string log;
    const int rc = test::RunCommand(
        test::DiffusionCommand() + " sample --config tiny --weights " + dir +
            "/w.safetensors --latents " + dir +
            "/image.safetensors --cond-latents " + dir +
            "/cond.safetensors --prompt-embeds " + dir +
            "/prompt.safetensors --steps 6 --seed " + std::to_string(seed) +
            " --out " + dir + "/" + name + " " + extra,
        &log);
    EXPECT_EQ(rc, 0) << log;
    return log;
  };
  const std::string log = sample("a.safetensors", 7, "");
  EXPECT_NE(log.find("6/6"), std::string::npos) << "progress bar: " << log;
  sample("b.safetensors", 7, "");
  sample("c.safetensors", 8, "");
  const std::string a = test::ReadFile(dir + "/a.safetensors");
  ASSERT_GT(a.size(), 100u);
  EXPECT_EQ(a, test::ReadFile(dir + "/b.safetensors"));
  EXPECT_NE(a, test::ReadFile(dir + "/c.safetensors"));
  SafetensorsFile f(dir + "/a.safetensors");
  const at::Tensor lat = f.Load("latents");
  const DiTConfig c = ConfigPreset("tiny");
  EXPECT_EQ(lat.sizes(),
            (std::vector<int64_t>{1, c.latent_frames, c.out_channels,
                                  c.latent_height, c.latent_width}));
  EXPECT_TRUE(at::isfinite(lat).all().item<bool>());
  // The condition latents reach the output through the (non-zero) encoder.
  WriteTinyInputs(dir, 2);
  sample("d.safetensors", 7, "");
  EXPECT_NE(a, test::ReadFile(dir + "/d.safetensors"));
  // DDIM runs too and differs from DPM.
  sample("e.safetensors", 7, "--scheduler ddim --no-progress");
  EXPECT_NE(test::ReadFile(dir + "/d.safetensors"),
            test::ReadFile(dir + "/e.safetensors"));
}

TEST(DiffusionCli, BadInputExitsTwoNamingTheFile) {
  const std::string dir = test::MakeTempDir("diffusion_cli_bad");
  std::string out;
  WriteTinyInputs(dir, 3);
  const std::string missing = dir + "/nope.safetensors";
  EXPECT_EQ(test::RunCommand(
                test::DiffusionCommand() + " sample --config tiny --weights " +
                    missing + " --latents " + dir +
                    "/image.safetensors --cond-latents " + dir +
                    "/cond.safetensors --out " + dir + "/o.safetensors",
                &out),
            2);
  EXPECT_NE(out.find(missing), std::string::npos) << out;
  EXPECT_EQ(
      test::RunCommand(test::DiffusionCommand() +
                           " init-weights --config huge --out " + dir + "/x",
                       &out),
      2);
  EXPECT_NE(out.find("unknown preset 'huge'"), std::string::npos) << out;
  EXPECT_EQ(
      test::RunCommand(test::DiffusionCommand() +
                           " init-weights --config cogvideox-5b-i2v --out " +
                           dir + "/x.safetensors",
                       &out),
      2);
  EXPECT_NE(out.find("--allow-large"), std::string::npos) << out;
  // Weights of another shape: the 5B table does not fit a tiny checkpoint.
  ASSERT_EQ(test::RunCommand(test::DiffusionCommand() +
                                 " init-weights --config tiny --out " + dir +
                                 "/w.safetensors",
                             &out),
            0);
  EXPECT_EQ(test::RunCommand(
                test::DiffusionCommand() +
                    " check-weights --config cogvideox-5b-i2v --weights " +
                    dir + "/w.safetensors",
                &out),
            2);
  EXPECT_NE(out.find("shape-mismatched"), std::string::npos) << out;
}

}  // namespace
}  // namespace diffusion
}  // namespace geodrive

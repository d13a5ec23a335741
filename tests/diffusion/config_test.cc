// Config presets, the symbolic 5B-I2V state-dict table against the reference
// notes, the loader report, and the CogVideoX noise schedule against reference
// values.

#include "diffusion/config.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

#include "diffusion/schedule.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace diffusion {
namespace {

using Shape = std::vector<int64_t>;

std::map<std::string, Shape> AsMap(const std::vector<ParamSpec>& specs) {
  std::map<std::string, Shape> m;
  for (const auto& s : specs) {
    EXPECT_TRUE(m.emplace(s.name, s.shape).second) << "duplicate " << s.name;
  }
  return m;
}

TEST(DiffusionConfig, CogVideoX5BI2VPresetNumbers) {
  const DiTConfig c = ConfigPreset("cogvideox-5b-i2v");
  EXPECT_NO_THROW(c.Check());
  EXPECT_EQ(c.num_layers, 42);
  EXPECT_EQ(c.num_heads, 48);
  EXPECT_EQ(c.head_dim, 64);
  EXPECT_EQ(c.inner_dim(), 3072);
  EXPECT_EQ(c.in_channels, 32);
  EXPECT_EQ(c.out_channels, 16);
  EXPECT_EQ(c.patch_size, 2);
  EXPECT_EQ(c.text_embed_dim, 4096);
  EXPECT_EQ(c.text_seq_len, 226);
  EXPECT_EQ(c.time_embed_dim, 512);
  EXPECT_TRUE(c.use_rotary);
  EXPECT_TRUE(c.use_learned_pos);
  EXPECT_EQ(c.tokens_per_frame(), 1350);
  EXPECT_EQ(c.video_tokens(), 17550);
  EXPECT_EQ(c.seq_len(), 17776);
  EXPECT_EQ(c.rope_dim_t(), 16);
  EXPECT_EQ(c.rope_dim_h(), 24);
  EXPECT_EQ(c.rope_dim_w(), 24);
  EXPECT_DOUBLE_EQ(c.norm_eps, 1e-5);
  EXPECT_DOUBLE_EQ(c.qk_norm_eps, 1e-6);
  // Injection: blocks 0-20 get encoder output 0, blocks 21-41 output 1.
  EXPECT_EQ(c.BranchInterval(), 21);
  EXPECT_EQ(20 / c.BranchInterval(), 0);
  EXPECT_EQ(21 / c.BranchInterval(), 1);
  EXPECT_EQ(41 / c.BranchInterval(), 1);
  EXPECT_NO_THROW(ConfigPreset("tiny").Check());
  EXPECT_THROW(ConfigPreset("cogvideox-2b"), InputError);
}

// The tables of reference notes diffusion_and_eval.md §3 ("Backbone parameter
// names").
TEST(DiffusionConfig, FiveBTableMatchesReferenceNotes) {
  const DiTConfig c = ConfigPreset("cogvideox-5b-i2v");
  const auto specs = BackboneParamSpecs(c);
  const auto m = AsMap(specs);
  const std::map<std::string, Shape> top = {
      {"patch_embed.proj.weight", {3072, 32, 2, 2}},
      {"patch_embed.proj.bias", {3072}},
      {"patch_embed.text_proj.weight", {3072, 4096}},
      {"patch_embed.text_proj.bias", {3072}},
      {"patch_embed.pos_embedding", {1, 17776, 3072}},
      {"time_embedding.linear_1.weight", {512, 3072}},
      {"time_embedding.linear_1.bias", {512}},
      {"time_embedding.linear_2.weight", {512, 512}},
      {"time_embedding.linear_2.bias", {512}},
      {"norm_final.weight", {3072}},
      {"norm_final.bias", {3072}},
      {"norm_out.linear.weight", {6144, 512}},
      {"norm_out.linear.bias", {6144}},
      {"norm_out.norm.weight", {3072}},
      {"norm_out.norm.bias", {3072}},
      {"proj_out.weight", {64, 3072}},
      {"proj_out.bias", {64}},
  };
  const std::map<std::string, Shape> block = {
      {"norm1.linear.weight", {18432, 512}},   {"norm1.linear.bias", {18432}},
      {"norm1.norm.weight", {3072}},           {"norm1.norm.bias", {3072}},
      {"attn1.to_q.weight", {3072, 3072}},     {"attn1.to_q.bias", {3072}},
      {"attn1.to_k.weight", {3072, 3072}},     {"attn1.to_k.bias", {3072}},
      {"attn1.to_v.weight", {3072, 3072}},     {"attn1.to_v.bias", {3072}},
      {"attn1.norm_q.weight", {64}},           {"attn1.norm_q.bias", {64}},
      {"attn1.norm_k.weight", {64}},           {"attn1.norm_k.bias", {64}},
      {"attn1.to_out.0.weight", {3072, 3072}}, {"attn1.to_out.0.bias", {3072}},
      {"norm2.linear.weight", {18432, 512}},   {"norm2.linear.bias", {18432}},
      {"norm2.norm.weight", {3072}},           {"norm2.norm.bias", {3072}},
      {"ff.net.0.proj.weight", {12288, 3072}}, {"ff.net.0.proj.bias", {12288}},
      {"ff.net.2.weight", {3072, 12288}},      {"ff.net.2.bias", {3072}},
  };
  std::map<std::string, Shape> expected = top;
  for (int i = 0; i < 42; ++i) {
    for (const auto& [suffix, shape] : block) {
      expected["transformer_blocks." + std::to_string(i) + "." + suffix] =
          shape;
    }
  }
  EXPECT_EQ(m.size(), expected.size());  // 17 + 42 x 24 = 1025
  EXPECT_EQ(specs.size(), 1025u);
  for (const auto& [name, shape] : expected) {
    auto it = m.find(name);
    ASSERT_NE(it, m.end()) << "missing " << name;
    EXPECT_EQ(it->second, shape) << name;
  }
  // "about 132 M per block, x42 ≈ 5.55 B" (reference §1.1).
  std::vector<ParamSpec> block0;
  for (const auto& s : specs) {
    if (s.name.rfind("transformer_blocks.0.", 0) == 0) block0.push_back(s);
  }
  const int64_t per_block = NumElements(block0);
  EXPECT_EQ(per_block, 2 * (18432 * 512 + 18432) + 4 * 3072 + 4 * 64 +
                           4 * (3072 * 3072 + 3072) + 12288 * 3072 + 12288 +
                           3072 * 12288 + 3072);
  EXPECT_NEAR(per_block / 1e6, 132.0, 1.0);
  EXPECT_NEAR(per_block * 42 / 1e9, 5.55, 0.01);
  std::cout << "5B-I2V backbone: " << specs.size() << " tensors, "
            << NumElements(specs) << " parameters (" << per_block
            << " per block)" << std::endl;
}

TEST(DiffusionConfig, BranchTableMatchesReleasedCheckpointLayout) {
  const DiTConfig c = ConfigPreset("cogvideox-5b-i2v");
  const auto m = AsMap(BranchParamSpecs(c));
  EXPECT_EQ(m.at("patch_embed.proj.weight"), (Shape{3072, 32, 2, 2}));
  EXPECT_EQ(m.at("patch_embed.pos_embedding"), (Shape{1, 17776, 3072}));
  EXPECT_EQ(m.at("patch_embed.text_proj.weight"), (Shape{3072, 4096}));
  EXPECT_EQ(m.at("branch_blocks.0.weight"), (Shape{3072, 3072}));
  EXPECT_EQ(m.at("branch_blocks.1.bias"), (Shape{3072}));
  EXPECT_EQ(m.at("transformer_blocks.1.attn1.to_q.weight"),
            (Shape{3072, 3072}));
  EXPECT_EQ(m.count("transformer_blocks.2.attn1.to_q.weight"), 0u);
  EXPECT_EQ(m.count("branch_blocks.2.weight"), 0u);
  EXPECT_EQ(m.at("branch_x_embedder.weight"), (Shape{3072, 32}));
  EXPECT_EQ(m.at("time_embedding.linear_1.weight"), (Shape{512, 3072}));
  EXPECT_TRUE(IsUnusedBranchParam("proj_out.weight"));
  EXPECT_FALSE(IsUnusedBranchParam("branch_blocks.0.weight"));
  // The encoder is ~6 % of the backbone (paper: "about 6 % of parameters"; 2/42
  // blocks + embeds).
  const double ratio = static_cast<double>(NumElements(BranchParamSpecs(c))) /
                       NumElements(BackboneParamSpecs(c));
  EXPECT_GT(ratio, 0.05);
  EXPECT_LT(ratio, 0.08);
}

TEST(DiffusionConfig, LoadReportListsMissingUnexpectedMismatched) {
  const std::vector<ParamSpec> expected = {
      {"a", {2}}, {"b", {3, 3}}, {"c", {1}}};
  const std::vector<ParamSpec> file = {{"a", {2}}, {"b", {3, 4}}, {"z", {5}}};
  const LoadReport r = CompareStateDict("f.safetensors", expected, file);
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.matched, 1);
  EXPECT_EQ(r.missing, (std::vector<std::string>{"c"}));
  EXPECT_EQ(r.unexpected, (std::vector<std::string>{"z"}));
  ASSERT_EQ(r.mismatched.size(), 1u);
  EXPECT_EQ(r.mismatched[0], "b: file [3, 4] vs model [3, 3]");
  EXPECT_NE(r.BriefReport().find("1 missing, 1 unexpected, 1 shape-mismatched"),
            std::string::npos);
  EXPECT_TRUE(CompareStateDict("f", expected, expected).ok());
}

// Reference notes §1.6 anchor table (double precision, s = 1).
TEST(CogVideoXSchedule, AlphaBarAnchorsAndZeroTerminalSnr) {
  const ScheduleConfig sc;
  const std::vector<double> ab = AlphasCumprod(sc);
  ASSERT_EQ(ab.size(), 1000u);
  EXPECT_NEAR(ab[0], 0.99915, 1e-12);  // = 1 - beta_0, unchanged by the rescale
  EXPECT_NEAR(ab[19], 0.98101046, 5e-9);
  EXPECT_NEAR(ab[499], 0.24235917, 5e-9);
  EXPECT_NEAR(ab[979], 8.5788e-05, 5e-10);
  EXPECT_EQ(ab[999], 0.0);  // exactly
  for (size_t i = 1; i < ab.size(); ++i) ASSERT_LT(ab[i], ab[i - 1]) << i;
}

TEST(CogVideoXSchedule, AlphaBarEqualsTorchFloat64Reference) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("torch");
  const std::string dir = test::MakeTempDir("schedule_ref");
  const std::string script = dir + "/ab.py";
  std::ofstream(script) << R"PY(import torch
betas = torch.linspace(0.00085 ** 0.5, 0.012 ** 0.5, 1000, dtype=torch.float64) ** 2
ac = torch.cumprod(1.0 - betas, dim=0)
s = 1.0
ac = ac / (s + (1 - s) * ac)
sq = ac.sqrt()
a0, aT = sq[0].clone(), sq[-1].clone()
sq = (sq - aT) * (a0 / (a0 - aT))
for v in (sq ** 2).tolist():
    print(repr(v))
)PY";
  std::string out;
  ASSERT_EQ(
      test::RunCommand(std::string(test::kDebianPython) + " " + script, &out),
      0)
      << out;
  std::istringstream in(out);
  const std::vector<double> ab = AlphasCumprod(ScheduleConfig{});
  double max_rel = 0;
  for (size_t i = 0; i < ab.size(); ++i) {
    double ref;
    ASSERT_TRUE(in >> ref) << "line " << i;
    const double err = std::abs(ab[i] - ref);
    if (ref > 0) max_rel = std::max(max_rel, err / ref);
    // float64 reassociation only: relative 1e-12 (tail values ~1e-5 amplify
    // absolute error).
    EXPECT_LE(err, 1e-12 * std::max(ref, 1e-3)) << "t=" << i;
  }
  std::cout << "alpha_bar vs torch float64: max relative difference " << max_rel
            << std::endl;
}

TEST(CogVideoXSchedule, TrailingTimestepsMatchNumpy) {
  const ScheduleConfig sc;
  const auto t50 = InferenceTimesteps(sc, 50);
  ASSERT_EQ(t50.size(), 50u);
  for (int k = 0; k < 50; ++k)
    EXPECT_EQ(t50[k], 999 - 20 * k);  // 999, 979, ..., 19
  GEODRIVE_REQUIRE_PYTHON_MODULE("numpy");
  for (int steps : {1, 3, 7, 30, 64, 333, 999, 1000}) {
    std::string out;
    const std::string cmd =
        std::string(test::kDebianPython) +
        " -c 'import numpy as np; print(*(np.round(np.arange(1000, 0, "
        "-1000 / " +
        std::to_string(steps) + ")).astype(np.int64) - 1))'";
    ASSERT_EQ(test::RunCommand(cmd, &out), 0) << out;
    std::istringstream in(out);
    std::vector<int64_t> ref;
    int64_t v;
    while (in >> v) ref.push_back(v);
    EXPECT_EQ(InferenceTimesteps(sc, steps), ref) << "steps " << steps;
  }
}

TEST(CogVideoXSchedule, DpmCoefficientsKeepTorchInfinities) {
  const std::vector<double> ab = AlphasCumprod(ScheduleConfig{});
  // First step: alpha_bar_t = 0 -> lambda = -inf, h = +inf: mult1 = 0, mult2 =
  // -sqrt(ab_prev).
  const DpmCoefficients first = DpmStepCoefficients(ab[999], ab[979], -1, true);
  EXPECT_EQ(first.mult1, 0.0);
  EXPECT_DOUBLE_EQ(first.mult2, -std::sqrt(ab[979]));
  EXPECT_DOUBLE_EQ(first.noise, std::sqrt(1 - ab[979]));
  EXPECT_FALSE(first.second_order);
  // Second step: back = 999 -> r = inf: mult3 = 1, mult4 = 0.
  const DpmCoefficients second =
      DpmStepCoefficients(ab[979], ab[959], ab[999], true);
  EXPECT_TRUE(second.second_order);
  EXPECT_EQ(second.mult3, 1.0);
  EXPECT_EQ(second.mult4, 0.0);
  // Last step (prev < 0, alpha_bar_prev = 1): x_prev = x0 exactly, no noise.
  const DpmCoefficients last = DpmStepCoefficients(ab[19], 1.0, ab[39], false);
  EXPECT_EQ(last.mult1, 0.0);
  EXPECT_EQ(last.mult2, -1.0);
  EXPECT_EQ(last.noise, 0.0);
  EXPECT_FALSE(last.second_order);
  // Dynamic CFG: the scale is 1 at t = S (upstream formula uses the raw
  // timestep).
  EXPECT_DOUBLE_EQ(DynamicGuidanceScale(6.0, 50, 50), 1.0);
}

}  // namespace
}  // namespace diffusion
}  // namespace geodrive

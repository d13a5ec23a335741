// Model (tiny preset): zero-init identity of the condition encoder, encoder
// initialisation, loader round trip and report, freezing under an optimiser
// step, chunking invariance, scheduler steps.

#include "diffusion/model.h"

#include <ATen/ATen.h>
#include <ATen/CPUGeneratorImpl.h>
#include <gtest/gtest.h>
#include <torch/optim/adamw.h>

#include <cmath>
#include <sstream>

#include "diffusion/safetensors.h"
#include "diffusion/schedule.h"
#include "diffusion/scheduler.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace diffusion {
namespace model_test {
namespace {

struct TinyInputs {
  at::Tensor noisy, image, cond, text, t;
};

TinyInputs MakeInputs(const DiTConfig& c, int64_t batch, uint64_t seed) {
  at::Generator gen = at::make_generator<at::CPUGeneratorImpl>(seed);
  const int64_t C = c.out_channels;
  TinyInputs in;
  in.noisy = at::randn(
      {batch, c.latent_frames, C, c.latent_height, c.latent_width}, gen);
  in.image = at::randn(
      {batch, c.latent_frames, C, c.latent_height, c.latent_width}, gen);
  in.cond = at::randn(
      {batch, c.latent_frames, C, c.latent_height, c.latent_width}, gen);
  in.text = at::randn({batch, c.text_seq_len, c.text_embed_dim}, gen);
  in.t = at::full({batch}, 759.0);
  return in;
}

TEST(DiffusionModel, ZeroInitEncoderLeavesBackboneBitIdentical) {
  at::manual_seed(test::kTestSeed);
  const DiTConfig c = ConfigPreset("tiny");
  const Weights backbone = InitWeights(BackboneParamSpecs(c), 1);
  const Weights branch = InitBranchFromBackbone(c, backbone, 2);
  const TinyInputs in = MakeInputs(c, 2, 3);
  const at::Tensor x = at::cat({in.noisy, in.image}, 2);
  at::NoGradGuard no_grad;
  const at::Tensor plain = BackboneForward(c, backbone, x, in.text, in.t, {});
  const std::vector<at::Tensor> res =
      BranchForward(c, branch, in.noisy, in.cond, in.text, in.t);
  ASSERT_EQ(res.size(), 2u);
  for (const auto& r : res) {
    EXPECT_EQ(r.sizes(),
              (std::vector<int64_t>{2, c.video_tokens(), c.inner_dim()}));
    EXPECT_EQ(r.abs().max().item<float>(), 0.0f);
  }
  const at::Tensor with = BackboneForward(c, backbone, x, in.text, in.t, res);
  EXPECT_EQ(plain.sizes(),
            (std::vector<int64_t>{2, c.latent_frames, c.out_channels,
                                  c.latent_height, c.latent_width}));
  EXPECT_GT(plain.std().item<float>(), 0.01f);
  EXPECT_TRUE(at::equal(plain, with));
  // Control: non-zero projections do change the output (the test above can
  // fail).
  Weights nz = branch.Clone();
  nz.Set("branch_blocks.1.weight",
         at::randn({c.inner_dim(), c.inner_dim()}) * 0.1);
  const auto res_nz = BranchForward(c, nz, in.noisy, in.cond, in.text, in.t);
  const at::Tensor changed =
      BackboneForward(c, backbone, x, in.text, in.t, res_nz);
  EXPECT_GT((changed - plain).abs().max().item<float>(), 1e-4f);
  // Output 1 is only injected after block i >= ceil(4 / 2) = 2: zeroing output
  // 0 of res_nz leaves `changed` unchanged since branch_blocks.0 is still zero.
  EXPECT_EQ(res_nz[0].abs().max().item<float>(), 0.0f);
}

TEST(DiffusionModel, EncoderInitialisedAsFromTransformer) {
  const DiTConfig c = ConfigPreset("tiny");
  const Weights backbone = InitWeights(BackboneParamSpecs(c), 1);
  const Weights branch = InitBranchFromBackbone(c, backbone, 2);
  for (const std::string name :
       {"transformer_blocks.0.attn1.to_q.weight",
        "transformer_blocks.1.ff.net.2.bias", "time_embedding.linear_2.weight",
        "patch_embed.proj.bias"}) {
    EXPECT_TRUE(at::equal(branch.Get(name), backbone.Get(name))) << name;
  }
  const at::Tensor bw = backbone.Get("patch_embed.proj.weight");
  const at::Tensor pw = branch.Get("patch_embed.proj.weight");
  const int64_t lat = c.out_channels;
  EXPECT_EQ(pw.size(1), c.branch_in_channels);
  EXPECT_TRUE(at::equal(pw.narrow(1, 0, lat), bw.narrow(1, 0, lat)));
  EXPECT_TRUE(at::equal(pw.narrow(1, lat, lat), bw.narrow(1, 0, lat)));
  // Upstream quirk: text_proj and pos_embedding are not copied.
  EXPECT_FALSE(at::equal(branch.Get("patch_embed.text_proj.weight"),
                         backbone.Get("patch_embed.text_proj.weight")));
  EXPECT_EQ(branch.Get("branch_blocks.0.weight").abs().max().item<float>(),
            0.0f);
  EXPECT_EQ(branch.Get("branch_blocks.1.bias").abs().max().item<float>(), 0.0f);
  // Clones, not aliases.
  EXPECT_NE(branch.Get("transformer_blocks.0.attn1.to_q.weight").data_ptr(),
            backbone.Get("transformer_blocks.0.attn1.to_q.weight").data_ptr());
}

TEST(DiffusionModel, LoaderRoundTripExactAndReport) {
  const DiTConfig c = ConfigPreset("tiny");
  const Weights backbone = InitWeights(BackboneParamSpecs(c), 5);
  const Weights branch = InitBranchFromBackbone(c, backbone, 6);
  const std::string dir = test::MakeTempDir("diffusion_loader");
  NamedTensors all;
  AppendForSave(backbone, "", &all);
  AppendForSave(branch, "branch.", &all);
  const std::string path = dir + "/w.safetensors";
  SaveSafetensors(path, all);
  LoadReport rb, rr;
  const Weights b2 = LoadWeights(path, BackboneParamSpecs(c), "", true, &rb);
  const Weights r2 =
      LoadWeights(path, BranchParamSpecs(c), "branch.", true, &rr);
  EXPECT_TRUE(rb.ok() && rb.unexpected.empty()) << rb.BriefReport();
  EXPECT_TRUE(rr.ok() && rr.unexpected.empty()) << rr.BriefReport();
  EXPECT_EQ(rb.matched, static_cast<int64_t>(BackboneParamSpecs(c).size()));
  for (const auto& name : backbone.order) {
    EXPECT_TRUE(at::equal(b2.Get(name), backbone.Get(name))) << name;
  }
  for (const auto& name : branch.order)
    EXPECT_TRUE(at::equal(r2.Get(name), branch.Get(name)));

  // bfloat16 checkpoints (the released format) load as the exact float32 of the
  // stored values.
  NamedTensors bf;
  for (const auto& [n, t] : all) bf.emplace_back(n, t.to(at::kBFloat16));
  SaveSafetensors(dir + "/bf16.safetensors", bf);
  const Weights b3 = LoadWeights(dir + "/bf16.safetensors",
                                 BackboneParamSpecs(c), "", true, &rb);
  EXPECT_TRUE(at::equal(
      b3.Get("proj_out.weight"),
      backbone.Get("proj_out.weight").to(at::kBFloat16).to(at::kFloat)));

  // A damaged checkpoint: one missing, one renamed (unexpected), one reshaped.
  NamedTensors bad;
  for (const auto& [n, t] : all) {
    if (n.rfind("branch.", 0) == 0 || n == "norm_final.bias") continue;
    if (n == "proj_out.bias") {
      bad.emplace_back("proj_out.bias_renamed", t);
    } else if (n == "transformer_blocks.1.attn1.to_k.weight") {
      bad.emplace_back(n, t.narrow(0, 0, t.size(0) - 1));
    } else {
      bad.emplace_back(n, t);
    }
  }
  const std::string bad_path = dir + "/bad.safetensors";
  SaveSafetensors(bad_path, bad);
  LoadReport r;
  LoadWeights(bad_path, BackboneParamSpecs(c), "", false, &r);
  EXPECT_EQ(r.missing,
            (std::vector<std::string>{"norm_final.bias", "proj_out.bias"}));
  EXPECT_EQ(r.unexpected, (std::vector<std::string>{"proj_out.bias_renamed"}));
  ASSERT_EQ(r.mismatched.size(), 1u);
  EXPECT_NE(r.mismatched[0].find("transformer_blocks.1.attn1.to_k.weight"),
            std::string::npos);
  try {
    LoadWeights(bad_path, BackboneParamSpecs(c), "", true, nullptr);
    ADD_FAILURE() << "strict load accepted a damaged checkpoint";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(bad_path), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("2 missing"), std::string::npos)
        << e.what();
  }
}

// Non-finite weights are an error naming the tensor, in every dtype the
// checkpoints use (a NaN in the VAE gave an all-black video and exit 0).
TEST(DiffusionModel, NonFiniteWeightsAreRefusedNamingTheTensor) {
  const DiTConfig c = ConfigPreset("tiny");
  const Weights backbone = InitWeights(BackboneParamSpecs(c), 5);
  const std::string dir = test::MakeTempDir("diffusion_nan_weights");
  const std::string victim = "proj_out.weight";
  int k = 0;
  for (const double bad : {NAN, INFINITY, -INFINITY}) {
    for (const auto dtype : {at::kFloat, at::kBFloat16, at::kHalf}) {
      NamedTensors all;
      AppendForSave(backbone, "", &all);
      for (auto& [n, t] : all) {
        t = t.to(dtype);
        if (n == victim) {
          t = t.clone();
          t.view({-1})[3] = bad;
        }
      }
      const std::string path =
          dir + "/w" + std::to_string(k++) + ".safetensors";
      SaveSafetensors(path, all);
      try {
        LoadWeights(path, BackboneParamSpecs(c), "", true, nullptr);
        ADD_FAILURE() << "accepted " << bad << " in dtype " << dtype;
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("tensor '" + victim +
                                             "' holds 1 NaN or Inf"),
                  std::string::npos)
            << e.what();
      }
    }
  }
}

TEST(DiffusionModel, OptimiserStepOnEncoderLeavesBackboneFrozen) {
  const DiTConfig c = ConfigPreset("tiny");
  Weights backbone = InitWeights(BackboneParamSpecs(c), 11);
  Weights branch = InitBranchFromBackbone(c, backbone, 12);
  const Weights before = backbone.Clone();
  const Weights branch_before = branch.Clone();
  backbone.SetRequiresGrad(false);
  branch.SetRequiresGrad(true);
  std::vector<at::Tensor> params;
  for (const auto& name : branch.order) params.push_back(branch.Get(name));
  torch::optim::AdamW opt(params,
                          torch::optim::AdamWOptions(1e-3).betas({0.9, 0.95}));
  const TinyInputs in = MakeInputs(c, 1, 13);
  for (int step = 0; step < 2; ++step) {
    opt.zero_grad();
    const auto res = BranchForward(c, branch, in.noisy, in.cond, in.text, in.t);
    const at::Tensor v = BackboneForward(
        c, backbone, at::cat({in.noisy, in.image}, 2), in.text, in.t, res);
    const at::Tensor loss = (v - in.noisy).pow(2).mean();
    loss.backward();
    opt.step();
  }
  for (const auto& name : backbone.order) {
    EXPECT_FALSE(backbone.Get(name).grad().defined()) << name;
    EXPECT_TRUE(at::equal(backbone.Get(name), before.Get(name))) << name;
  }
  // The zero projections received gradient and moved; after them, the cloned
  // blocks too.
  EXPECT_GT(branch.Get("branch_blocks.0.weight").abs().max().item<float>(),
            0.0f);
  EXPECT_GT(branch.Get("branch_blocks.1.weight").abs().max().item<float>(),
            0.0f);
  EXPECT_FALSE(
      at::equal(branch.Get("transformer_blocks.0.attn1.to_q.weight"),
                branch_before.Get("transformer_blocks.0.attn1.to_q.weight")));
}

TEST(DiffusionModel, ChunkedAttentionAndFeedForwardMatchUnchunked) {
  DiTConfig c = ConfigPreset("tiny");
  const Weights backbone = InitWeights(BackboneParamSpecs(c), 21);
  const TinyInputs in = MakeInputs(c, 2, 22);
  at::NoGradGuard no_grad;
  const at::Tensor x = at::cat({in.noisy, in.image}, 2);
  const at::Tensor ref = BackboneForward(c, backbone, x, in.text, in.t, {});
  ForwardOptions small;
  small.attention_chunk_bytes =
      4096;  // 2 x 26 tokens x 4 B rows: 19 queries, 1 head per chunk
  small.ff_token_chunk = 5;
  const at::Tensor chunked =
      BackboneForward(c, backbone, x, in.text, in.t, {}, small);
  const float err = (chunked - ref).abs().max().item<float>();
  std::cout << "chunked vs unchunked forward: max abs difference " << err
            << std::endl;
  EXPECT_LT(err, 1e-5f);  // same math, float32 summation order only
}

// Plain-softmax attention of one block computed here independently (no
// chunking, no RoPE helper reuse) must equal the block's attention
// contribution: checks head split, QK-norm, RoPE pairs.
TEST(DiffusionModel, AttentionMatchesDirectFormula) {
  DiTConfig c = ConfigPreset("tiny");
  c.num_layers = 1;
  c.branch_layers = 1;
  Weights w = InitWeights(BackboneParamSpecs(c), 31);
  // Make norm2/FF contribute nothing and norm1 an identity modulation with gate
  // 1, so that video_out = video + attn(video).
  at::NoGradGuard no_grad;
  const std::string p = "transformer_blocks.0.";
  const int64_t D = c.inner_dim();
  at::Tensor lin = at::zeros({6 * D, c.time_embed_dim});
  at::Tensor bias = at::zeros({6 * D});
  bias.narrow(0, 2 * D, D).fill_(1.0);  // gate
  bias.narrow(0, 5 * D, D).fill_(1.0);  // text gate
  w.Set(p + "norm1.linear.weight", lin);
  w.Set(p + "norm1.linear.bias", bias);
  w.Set(p + "norm2.linear.weight", lin.clone());
  w.Set(p + "norm2.linear.bias",
        at::zeros({6 * D}));  // gates 0: FF adds nothing
  w.Set(p + "attn1.norm_q.weight", at::rand({c.head_dim}) + 0.5);
  w.Set(p + "attn1.norm_k.bias", at::randn({c.head_dim}) * 0.1);
  const int64_t F = 2, gh = 2, gw = 3, Nv = F * gh * gw, L = 3, B = 1;
  const at::Tensor video = at::randn({B, Nv, D}), text = at::randn({B, L, D});
  const RotaryTables rope = Rotary3D(c, F, gh, gw);
  at::Tensor v_out = video, t_out = text;
  BlockForward(c, w, p, at::zeros({B, c.time_embed_dim}), rope,
               ForwardOptions{}, &v_out, &t_out);

  // Direct formula, per head, per token, in double.
  const at::Tensor x = at::cat({text, video}, 1).to(at::kDouble);
  const at::Tensor xn =
      at::layer_norm(x, {D}, w.Get(p + "norm1.norm.weight").to(at::kDouble),
                     w.Get(p + "norm1.norm.bias").to(at::kDouble), c.norm_eps);
  auto lin_d = [&](const std::string& n, const at::Tensor& in) {
    return at::linear(in, w.Get(p + n + ".weight").to(at::kDouble),
                      w.Get(p + n + ".bias").to(at::kDouble));
  };
  const int64_t N = L + Nv, H = c.num_heads, hd = c.head_dim;
  at::Tensor q = lin_d("attn1.to_q", xn).view({N, H, hd});
  at::Tensor k = lin_d("attn1.to_k", xn).view({N, H, hd});
  at::Tensor v = lin_d("attn1.to_v", xn).view({N, H, hd});
  q = at::layer_norm(q, {hd}, w.Get(p + "attn1.norm_q.weight").to(at::kDouble),
                     w.Get(p + "attn1.norm_q.bias").to(at::kDouble),
                     c.qk_norm_eps);
  k = at::layer_norm(k, {hd}, w.Get(p + "attn1.norm_k.weight").to(at::kDouble),
                     w.Get(p + "attn1.norm_k.bias").to(at::kDouble),
                     c.qk_norm_eps);
  // RoPE from the definition: position (f, y, x) rotates pair j of each axis
  // block by pos*θ^(−2j/d).
  auto rotate = [&](at::Tensor t) {
    at::Tensor out = t.clone();
    auto acc = out.accessor<double, 3>();
    auto src = t.accessor<double, 3>();
    const int dims[3] = {c.rope_dim_t(), c.rope_dim_h(), c.rope_dim_w()};
    for (int64_t n = L; n < N; ++n) {
      const int64_t i = n - L;
      const int64_t pos[3] = {i / (gh * gw), (i / gw) % gh, i % gw};
      for (int64_t h = 0; h < H; ++h) {
        int off = 0;
        for (int a = 0; a < 3; ++a) {
          for (int j = 0; j < dims[a] / 2; ++j) {
            const double ang = pos[a] * std::pow(10000.0, -2.0 * j / dims[a]);
            const double x0 = src[n][h][off + 2 * j],
                         x1 = src[n][h][off + 2 * j + 1];
            acc[n][h][off + 2 * j] = x0 * std::cos(ang) - x1 * std::sin(ang);
            acc[n][h][off + 2 * j + 1] =
                x1 * std::cos(ang) + x0 * std::sin(ang);
          }
          off += dims[a];
        }
      }
    }
    return out;
  };
  q = rotate(q);
  k = rotate(k);
  at::Tensor o = at::zeros({N, H, hd}, at::kDouble);
  for (int64_t h = 0; h < H; ++h) {
    const at::Tensor s =
        at::softmax(at::matmul(q.select(1, h), k.select(1, h).t()) /
                        std::sqrt(static_cast<double>(hd)),
                    -1);
    o.select(1, h).copy_(at::matmul(s, v.select(1, h)));
  }
  const at::Tensor attn = lin_d("attn1.to_out.0", o.reshape({1, N, D}));
  const at::Tensor expect_video = video.to(at::kDouble) + attn.narrow(1, L, Nv);
  const at::Tensor expect_text = text.to(at::kDouble) + attn.narrow(1, 0, L);
  const double ev =
      (v_out.to(at::kDouble) - expect_video).abs().max().item<double>();
  const double et =
      (t_out.to(at::kDouble) - expect_text).abs().max().item<double>();
  std::cout << "block attention vs direct formula: video " << ev << ", text "
            << et << std::endl;
  EXPECT_LT(ev, 2e-5);
  EXPECT_LT(et, 2e-5);
}

// The full tiny forward (encoder with non-zero projections injected into the
// backbone) against tests/diffusion/cogvideox_reference.py, an independent
// torch implementation written after the diffusers module code: checks
// patchify/unpatchify order, time embedding, RoPE, injection.
TEST(DiffusionModel, ForwardMatchesIndependentTorchReference) {
  at::manual_seed(test::kTestSeed);
  GEODRIVE_REQUIRE_PYTHON_MODULE("torch");
  DiTConfig c = ConfigPreset("tiny");
  c.conditioning_scale = 0.7;
  Weights backbone = InitWeights(BackboneParamSpecs(c), 51);
  Weights branch = InitBranchFromBackbone(c, backbone, 52);
  for (int k = 0; k < c.branch_layers; ++k) {
    const std::string b = "branch_blocks." + std::to_string(k);
    branch.Set(b + ".weight", at::randn({c.inner_dim(), c.inner_dim()}) * 0.2);
    branch.Set(b + ".bias", at::randn({c.inner_dim()}) * 0.1);
  }
  const TinyInputs in = MakeInputs(c, 2, 53);
  const at::Tensor ts = at::tensor({999.0f, 37.0f});
  const std::string dir = test::MakeTempDir("diffusion_reference");
  NamedTensors w;
  AppendForSave(backbone, "", &w);
  AppendForSave(branch, "branch.", &w);
  SaveSafetensors(dir + "/w.safetensors", w);
  SaveSafetensors(dir + "/in.safetensors", {{"noisy", in.noisy},
                                            {"image", in.image},
                                            {"cond", in.cond},
                                            {"text", in.text},
                                            {"timesteps", ts}});
  std::ostringstream cfg;
  cfg << "{\"heads\": " << c.num_heads << ", \"head_dim\": " << c.head_dim
      << ", \"patch\": " << c.patch_size << ", \"eps\": " << c.norm_eps
      << ", \"qk_eps\": " << c.qk_norm_eps << ", \"layers\": " << c.num_layers
      << ", \"branch_layers\": " << c.branch_layers
      << ", \"scale\": " << c.conditioning_scale << "}";
  std::string out;
  ASSERT_EQ(
      test::RunCommand(
          std::string(test::kDebianPython) + " " + GEODRIVE_SOURCE_DIR +
              "/tests/diffusion/cogvideox_reference.py " + dir +
              "/w.safetensors " + dir + "/in.safetensors '" + cfg.str() + "'",
          &out),
      0)
      << out;
  at::NoGradGuard no_grad;
  const auto res = BranchForward(c, branch, in.noisy, in.cond, in.text, ts);
  const at::Tensor got =
      BackboneForward(c, backbone, at::cat({in.noisy, in.image}, 2), in.text,
                      ts, res)
          .reshape({-1});
  std::istringstream lines(out);
  std::vector<float> ref;
  double v;
  while (lines >> v) ref.push_back(static_cast<float>(v));
  ASSERT_EQ(static_cast<int64_t>(ref.size()), got.numel())
      << out.substr(0, 500);
  const at::Tensor r = at::tensor(ref);
  const float err = (got - r).abs().max().item<float>();
  const float scale = r.abs().max().item<float>();
  std::cout << "tiny forward vs torch reference: max abs difference " << err
            << " (max |out| " << scale << ")" << std::endl;
  EXPECT_GT(scale, 0.1f);
  EXPECT_LT(
      err,
      1e-4f);  // float32, different op order (chunking, scaling before matmul)
}

TEST(CogVideoXScheduler, DdimStepEqualsClosedForm) {
  const std::vector<double> ab = AlphasCumprod(ScheduleConfig{});
  at::manual_seed(41);
  const at::Tensor x = at::randn({2, 3, 4, 5}, at::kDouble);
  const at::Tensor v = at::randn({2, 3, 4, 5}, at::kDouble);
  for (auto [t, prev] :
       std::vector<std::pair<int, int>>{{999, 979}, {499, 479}, {19, -1}}) {
    const double at_ = ab[t], ap = prev < 0 ? 1.0 : ab[prev];
    const at::Tensor got = DdimStep(v, x, at_, ap);
    // DDIM (η = 0) written as x_prev = √ᾱp·x0 + √(1−ᾱp)·ε̂ with x0, ε̂ from
    // v-prediction: x0 = √ᾱt·x − √(1−ᾱt)·v, ε̂ = √(1−ᾱt)·x + √ᾱt·v.
    const at::Tensor x0 = std::sqrt(at_) * x - std::sqrt(1 - at_) * v;
    const at::Tensor eps = std::sqrt(1 - at_) * x + std::sqrt(at_) * v;
    const at::Tensor want = std::sqrt(ap) * x0 + std::sqrt(1 - ap) * eps;
    EXPECT_LT((got - want).abs().max().item<double>(), 1e-12) << "t=" << t;
  }
}

TEST(CogVideoXScheduler, DpmSecondOrderStepEqualsFormula) {
  const std::vector<double> ab = AlphasCumprod(ScheduleConfig{});
  at::manual_seed(42);
  const at::Tensor x = at::randn({1, 2, 3, 4}, at::kDouble);
  const at::Tensor v = at::randn({1, 2, 3, 4}, at::kDouble);
  const at::Tensor old_x0 = at::randn({1, 2, 3, 4}, at::kDouble);
  const double at_ = ab[499], ap = ab[479], ab_back = ab[519];
  at::Tensor x0;
  const at::Tensor got =
      DpmStep(v, old_x0, x, at_, ap, ab_back, true,
              at::make_generator<at::CPUGeneratorImpl>(9), &x0);
  // Same noise stream: the second draw is used.
  at::Generator g = at::make_generator<at::CPUGeneratorImpl>(9);
  at::randn(x.sizes(), g, x.options());
  const at::Tensor noise = at::randn(x.sizes(), g, x.options());
  const double lam = 0.5 * std::log(at_ / (1 - at_)),
               lam_p = 0.5 * std::log(ap / (1 - ap));
  const double lam_b = 0.5 * std::log(ab_back / (1 - ab_back));
  const double h = lam_p - lam, r = (lam - lam_b) / h;
  const at::Tensor x0_ref = std::sqrt(at_) * x - std::sqrt(1 - at_) * v;
  const at::Tensor d = (1 + 1 / (2 * r)) * x0_ref - (1 / (2 * r)) * old_x0;
  const at::Tensor want =
      std::sqrt((1 - ap) / (1 - at_)) * std::exp(-h) * x -
      std::expm1(-2 * h) * std::sqrt(ap) * d +
      std::sqrt(1 - ap) * std::sqrt(-std::expm1(-2 * h)) * noise;
  EXPECT_LT((got - want).abs().max().item<double>(), 1e-12);
  EXPECT_LT((x0 - x0_ref).abs().max().item<double>(), 1e-12);
  // CFG on a [uncond; cond] batch: u + g (c - u).
  const at::Tensor cfg = ClassifierFreeGuidance(at::cat({x, v}, 0), 6.0);
  EXPECT_LT((cfg - (x + 6.0 * (v - x))).abs().max().item<double>(), 1e-12);
}

}  // namespace
}  // namespace model_test
}  // namespace diffusion
}  // namespace geodrive

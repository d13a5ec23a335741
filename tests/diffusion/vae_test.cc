// Tests of CogVideoX's 3D causal VAE (diffusion/vae.h): the diffusers
// state-dict table of the real config, frame batching / frame counts, shapes
// 49 -> 13 -> 49, causality at frame-batch granularity, the GroupNorm effect
// of the batching, parity with an independent torch reference
// (tests/diffusion/vae_reference.py) and a tiny-config round trip after a
// short fit.

#include "diffusion/vae.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/optim/adam.h>

#include <algorithm>
#include <map>
#include <sstream>

#include "diffusion/safetensors.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"
#include "tests/diffusion/diffusion_test_util.h"

namespace geodrive {
namespace diffusion {
namespace {

std::string ConfigJson(const VaeConfig& c) {
  std::ostringstream s;
  s << "{\"in_channels\": " << c.in_channels
    << ", \"latent_channels\": " << c.latent_channels
    << ", \"block_out_channels\": [";
  for (size_t i = 0; i < c.block_out_channels.size(); ++i)
    s << (i ? ", " : "") << c.block_out_channels[i];
  s << "], \"layers_per_block\": " << c.layers_per_block
    << ", \"norm_num_groups\": " << c.norm_num_groups
    << ", \"temporal_compression_ratio\": " << c.temporal_compression << "}";
  return s.str();
}

std::string ReferenceCommand(const std::string& args) {
  return std::string(test::kDebianPython) + " " + GEODRIVE_SOURCE_DIR +
         "/tests/diffusion/vae_reference.py " + args;
}

// A smooth moving pattern in [-1, 1]: [1, 3, F, H, W].
at::Tensor SmoothVideo(int64_t frames, int64_t h, int64_t w) {
  at::Tensor t = at::arange(frames, at::kFloat).view({1, 1, frames, 1, 1});
  at::Tensor y = at::arange(h, at::kFloat).view({1, 1, 1, h, 1});
  at::Tensor x = at::arange(w, at::kFloat).view({1, 1, 1, 1, w});
  at::Tensor ch = at::arange(3, at::kFloat).view({1, 3, 1, 1, 1});
  return 0.8 * at::sin(0.35 * x + 0.25 * y - 0.3 * t + 2.0 * ch);
}

TEST(VaeConfig, RealTableHasDiffusersNamesShapesAndCount) {
  const VaeConfig c = VaePreset("cogvideox-5b-i2v");
  const auto specs = VaeParamSpecs(c);
  std::map<std::string, std::vector<int64_t>> table;
  for (const auto& s : specs) table[s.name] = s.shape;
  EXPECT_EQ(table.size(), specs.size()) << "duplicate names";
  // Names and shapes of diffusers' AutoencoderKLCogVideoX state dict (the
  // reference notes §1.5 and the module code).
  const std::map<std::string, std::vector<int64_t>> expected = {
      {"encoder.conv_in.conv.weight", {128, 3, 3, 3, 3}},
      {"encoder.down_blocks.0.resnets.0.conv1.conv.weight",
       {128, 128, 3, 3, 3}},
      {"encoder.down_blocks.0.resnets.0.norm1.weight", {128}},
      {"encoder.down_blocks.0.downsamplers.0.conv.weight", {128, 128, 3, 3}},
      {"encoder.down_blocks.1.resnets.0.conv_shortcut.weight",
       {256, 128, 1, 1, 1}},
      {"encoder.down_blocks.3.resnets.0.conv_shortcut.weight",
       {512, 256, 1, 1, 1}},
      {"encoder.down_blocks.3.resnets.2.conv2.conv.bias", {512}},
      {"encoder.mid_block.resnets.1.conv2.conv.weight", {512, 512, 3, 3, 3}},
      {"encoder.norm_out.weight", {512}},
      {"encoder.conv_out.conv.weight", {32, 512, 3, 3, 3}},
      {"decoder.conv_in.conv.weight", {512, 16, 3, 3, 3}},
      {"decoder.mid_block.resnets.0.norm1.norm_layer.weight", {512}},
      {"decoder.mid_block.resnets.0.norm1.conv_y.conv.weight",
       {512, 16, 1, 1, 1}},
      {"decoder.up_blocks.0.resnets.0.norm1.norm_layer.weight", {512}},
      {"decoder.up_blocks.0.resnets.0.norm1.conv_y.conv.weight",
       {512, 16, 1, 1, 1}},
      {"decoder.up_blocks.0.resnets.3.conv2.conv.weight", {512, 512, 3, 3, 3}},
      {"decoder.up_blocks.0.upsamplers.0.conv.weight", {512, 512, 3, 3}},
      {"decoder.up_blocks.1.resnets.0.conv_shortcut.weight",
       {256, 512, 1, 1, 1}},
      {"decoder.up_blocks.3.resnets.0.conv_shortcut.weight",
       {128, 256, 1, 1, 1}},
      {"decoder.norm_out.conv_b.conv.bias", {128}},
      {"decoder.conv_out.conv.weight", {3, 128, 3, 3, 3}},
  };
  for (const auto& [name, shape] : expected) {
    ASSERT_TRUE(table.count(name)) << name;
    EXPECT_EQ(table[name], shape) << name;
  }
  // Absent in diffusers: quant convs, a 4th upsampler / downsampler, temb.
  for (const char* absent :
       {"quant_conv.weight", "post_quant_conv.weight",
        "encoder.down_blocks.3.downsamplers.0.conv.weight",
        "decoder.up_blocks.3.upsamplers.0.conv.weight",
        "encoder.down_blocks.0.resnets.0.temb_proj.weight",
        "encoder.down_blocks.0.resnets.0.conv_shortcut.weight"}) {
    EXPECT_FALSE(table.count(absent)) << absent;
  }
  // 436 tensors, 215,583,907 parameters: the state dict of the module tree of
  // vae_reference.py (built after diffusers) for this config, the "215.6 M"
  // usually quoted for CogVideoX's VAE.
  std::cout << "real VAE: " << specs.size() << " tensors, "
            << NumElements(specs) << " parameters" << std::endl;
  EXPECT_EQ(specs.size(), 436u);
  EXPECT_EQ(NumElements(specs), 215583907);
}

// The C++ table equals, name by name and in order, the state dict of the
// torch module tree written after diffusers (real and tiny configs).
TEST(VaeConfig, TableEqualsTorchModuleTree) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("torch");
  for (const char* preset : {"cogvideox-5b-i2v", "tiny"}) {
    const VaeConfig c = VaePreset(preset);
    std::string out;
    ASSERT_EQ(test::RunCommand(
                  ReferenceCommand("names '" + ConfigJson(c) + "'"), &out),
              0)
        << out;
    std::ostringstream mine;
    for (const auto& s : VaeParamSpecs(c)) {
      mine << s.name;
      for (int64_t d : s.shape) mine << " " << d;
      mine << "\n";
    }
    EXPECT_EQ(out, mine.str()) << preset;
  }
}

TEST(VaeConfig, FrameBatchesAndFrameCounts) {
  const VaeConfig c = VaePreset("tiny");
  const auto b = VaeFrameBatches(49, 8);
  ASSERT_EQ(b.size(), 6u);
  EXPECT_EQ(b[0], (std::pair<int64_t, int64_t>{0, 9}));
  EXPECT_EQ(b[1], (std::pair<int64_t, int64_t>{9, 17}));
  EXPECT_EQ(b[5], (std::pair<int64_t, int64_t>{41, 49}));
  const auto d = VaeFrameBatches(13, 2);
  ASSERT_EQ(d.size(), 6u);
  EXPECT_EQ(d[0], (std::pair<int64_t, int64_t>{0, 3}));
  EXPECT_EQ(d[5], (std::pair<int64_t, int64_t>{11, 13}));
  EXPECT_EQ(VaeFrameBatches(1, 8).size(), 1u);
  EXPECT_EQ(VaeFrameBatches(1, 8)[0], (std::pair<int64_t, int64_t>{0, 1}));
  for (int k = 0; k <= 12; ++k) {
    EXPECT_EQ(c.LatentFrames(1 + 4 * k), 1 + k) << k;
    // An odd latent count 1 + k decodes to 1 + 4k frames; an even one to
    // 4(1 + k) (diffusers: every batch then has an even frame count).
    EXPECT_EQ(c.PixelFrames(1 + k), k % 2 == 0 ? 1 + 4 * k : 4 * (1 + k)) << k;
  }
  VaeConfig bad = c;
  bad.block_out_channels = {8, 16, 16};  // spatial 4 != 8
  EXPECT_THROW(bad.Check(), InputError);
  EXPECT_THROW(VaePreset("huge"), InputError);
}

TEST(Vae, FortyNineFramesToThirteenLatentsAndBack) {
  const VaeConfig c = VaePreset("tiny");
  const Weights w = VaeInitWeights(c, 7);
  at::NoGradGuard no_grad;
  const at::Tensor video = SmoothVideo(49, 16, 24);
  const at::Tensor lat = VaeEncode(c, w, video);
  EXPECT_EQ(lat.sizes(), (std::vector<int64_t>{1, 4, 13, 2, 3}));
  EXPECT_TRUE(at::isfinite(lat).all().item<bool>());
  const at::Tensor dec = VaeDecode(c, w, lat);
  EXPECT_EQ(dec.sizes(), (std::vector<int64_t>{1, 3, 49, 16, 24}));
  EXPECT_TRUE(at::isfinite(dec).all().item<bool>());
  // One image: 1 frame -> 1 latent -> 1 frame.
  const at::Tensor one = VaeEncode(c, w, video.narrow(2, 0, 1));
  EXPECT_EQ(one.sizes(), (std::vector<int64_t>{1, 4, 1, 2, 3}));
  EXPECT_EQ(VaeDecode(c, w, one).sizes(),
            (std::vector<int64_t>{1, 3, 1, 16, 24}));
  // Deterministic: same weights seed and input -> identical bytes.
  const Weights w2 = VaeInitWeights(c, 7);
  EXPECT_TRUE(at::equal(VaeEncode(c, w2, video), lat));
  EXPECT_TRUE(at::equal(VaeDecode(c, w2, lat), dec));
  // Bad input: one line naming the problem.
  EXPECT_THROW(VaeEncode(c, w, video.narrow(2, 0, 4)), InputError);
  EXPECT_THROW(VaeEncode(c, w, video.narrow(3, 0, 12)), InputError);
  EXPECT_THROW(VaeDecode(c, w, lat.narrow(1, 0, 3)), InputError);
}

// The real preset runs (random weights, a 9-frame 16x16 clip): every
// block, group count and channel change of the 215.6 M-parameter VAE.
TEST(Vae, RealConfigRunsOnSmallClip) {
  const VaeConfig c = VaePreset("cogvideox-5b-i2v");
  const Weights w = VaeInitWeights(c, 13);
  at::NoGradGuard no_grad;
  const at::Tensor lat = VaeEncode(c, w, SmoothVideo(9, 16, 16));
  EXPECT_EQ(lat.sizes(), (std::vector<int64_t>{1, 16, 3, 2, 2}));
  const at::Tensor dec = VaeDecode(c, w, lat);
  EXPECT_EQ(dec.sizes(), (std::vector<int64_t>{1, 3, 9, 16, 16}));
  EXPECT_TRUE(at::isfinite(dec).all().item<bool>());
}

// Causality. The causal convs (first-frame padding, cache across frame
// batches) never look ahead, but GroupNorm statistics span the whole frame
// batch (as in diffusers), so the output is causal at frame-batch granularity:
// pixel batches [0, 9), [9, 17), ... -> latents [0, 3), [3, 5), ...
TEST(Vae, EncodeIsCausalAtFrameBatchGranularity) {
  const VaeConfig c = VaePreset("tiny");
  const Weights w = VaeInitWeights(c, 8);
  at::NoGradGuard no_grad;
  const at::Tensor video = SmoothVideo(49, 16, 24);
  const at::Tensor base = VaeEncode(c, w, video);
  for (auto [t, keep] :
       std::vector<std::pair<int64_t, int64_t>>{{9, 3}, {17, 5}, {41, 11}}) {
    at::Tensor v = video.clone();
    v.narrow(2, t, 49 - t).add_(at::randn_like(v.narrow(2, t, 49 - t)) * 0.5);
    const at::Tensor lat = VaeEncode(c, w, v);
    const double same =
        test::MaxAbs(lat.narrow(2, 0, keep) - base.narrow(2, 0, keep));
    const double changed = test::MaxAbs(lat.narrow(2, keep, 13 - keep) -
                                        base.narrow(2, keep, 13 - keep));
    std::cout << "encode: perturb frames >= " << t << ": latents < " << keep
              << " change " << same << ", later latents " << changed
              << std::endl;
    EXPECT_EQ(same, 0.0);
    EXPECT_GT(changed, 1e-3);
  }
}

TEST(Vae, DecodeIsCausalAtFrameBatchGranularity) {
  const VaeConfig c = VaePreset("tiny");
  const Weights w = VaeInitWeights(c, 9);
  at::NoGradGuard no_grad;
  const at::Tensor lat = at::randn({1, 4, 13, 2, 3});
  const at::Tensor base = VaeDecode(c, w, lat);
  for (auto [t, keep] :
       std::vector<std::pair<int64_t, int64_t>>{{3, 9}, {5, 17}, {11, 41}}) {
    at::Tensor z = lat.clone();
    z.narrow(2, t, 13 - t).add_(at::randn_like(z.narrow(2, t, 13 - t)));
    const at::Tensor dec = VaeDecode(c, w, z);
    const double same =
        test::MaxAbs(dec.narrow(2, 0, keep) - base.narrow(2, 0, keep));
    const double changed = test::MaxAbs(dec.narrow(2, keep, 49 - keep) -
                                        base.narrow(2, keep, 49 - keep));
    std::cout << "decode: perturb latents >= " << t << ": frames < " << keep
              << " change " << same << ", later frames " << changed
              << std::endl;
    EXPECT_EQ(same, 0.0);
    EXPECT_GT(changed, 1e-3);
  }
}

// The frame batching is what diffusers computes, and it is not a no-op: the
// per-batch GroupNorm statistics differ from a whole-video pass. A video that
// fits in the first batch (9 frames, 3 latents) gives the same result both
// ways.
TEST(Vae, FrameBatchingChangesGroupNormStatistics) {
  const VaeConfig c = VaePreset("tiny");
  const Weights w = VaeInitWeights(c, 10);
  at::NoGradGuard no_grad;
  VaeOptions whole;
  whole.frame_batching = false;
  const at::Tensor video = SmoothVideo(25, 16, 24);
  const double enc_diff =
      test::MaxAbs(VaeEncode(c, w, video) - VaeEncode(c, w, video, whole));
  const at::Tensor lat = at::randn({1, 4, 7, 2, 3});
  const double dec_diff =
      test::MaxAbs(VaeDecode(c, w, lat) - VaeDecode(c, w, lat, whole));
  const at::Tensor v9 = video.narrow(2, 0, 9);
  const double first_diff =
      test::MaxAbs(VaeEncode(c, w, v9) - VaeEncode(c, w, v9, whole));
  const at::Tensor z3 = lat.narrow(2, 0, 3);
  const double first_dec =
      test::MaxAbs(VaeDecode(c, w, z3) - VaeDecode(c, w, z3, whole));
  std::cout << "batched vs whole-video: encode " << enc_diff << ", decode "
            << dec_diff << "; single batch: " << first_diff << ", " << first_dec
            << std::endl;
  EXPECT_GT(enc_diff, 1e-3);
  EXPECT_GT(dec_diff, 1e-3);
  EXPECT_EQ(first_diff, 0.0);
  EXPECT_EQ(first_dec, 0.0);
}

// Encode (17 frames: two frame batches) and decode (5 latents: two batches)
// against vae_reference.py, nn.Modules written after diffusers with its
// framewise _encode / _decode loops.
TEST(Vae, MatchesIndependentTorchReference) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("torch");
  const VaeConfig c = VaePreset("tiny");
  const Weights w = VaeInitWeights(c, 11);
  at::manual_seed(test::kTestSeed);
  const std::string dir = test::MakeTempDir("vae_reference");
  NamedTensors nt;
  AppendForSave(w, "", &nt);
  SaveSafetensors(dir + "/w.safetensors", nt);
  const at::Tensor video =
      (SmoothVideo(17, 16, 24) + 0.1 * at::randn({1, 3, 17, 16, 24}))
          .contiguous();
  const at::Tensor lat = at::randn({1, 4, 5, 2, 3});
  SaveSafetensors(dir + "/video.safetensors", {{"x", video}});
  SaveSafetensors(dir + "/lat.safetensors", {{"x", lat}});
  at::NoGradGuard no_grad;
  const at::Tensor mine_enc = VaeEncode(c, w, video);
  const at::Tensor mine_dec = VaeDecode(c, w, lat);
  for (const std::string mode : {"encode", "decode"}) {
    const bool enc = mode == "encode";
    std::string out;
    ASSERT_EQ(test::RunCommand(
                  ReferenceCommand(mode + " '" + ConfigJson(c) + "' " + dir +
                                   "/w.safetensors " + dir +
                                   (enc ? "/video" : "/lat") + ".safetensors"),
                  &out),
              0)
        << out;
    std::istringstream lines(out);
    std::vector<float> ref;
    double v;
    while (lines >> v) ref.push_back(static_cast<float>(v));
    const at::Tensor got = (enc ? mine_enc : mine_dec).reshape({-1});
    ASSERT_EQ(static_cast<int64_t>(ref.size()), got.numel())
        << out.substr(0, 500);
    const at::Tensor r = at::tensor(ref);
    const double err = test::MaxAbs(got - r), scale = test::MaxAbs(r);
    std::cout << mode << " vs torch reference: max abs difference " << err
              << " (max |out| " << scale << ")" << std::endl;
    EXPECT_GT(scale, 0.1);
    // float32, same ops in another order (pair means vs avg_pool1d).
    EXPECT_LT(err, 1e-5 * std::max(1.0, scale));
  }
}

// A random VAE does not reconstruct anything, so the round trip is made
// meaningful by fitting the tiny VAE (Adam, 80 steps) on one 9-frame video:
// the encode -> decode reconstruction error must fall well below that of the
// random initialisation and below the video's own variance.
TEST(Vae, TinyRoundTripAfterShortFit) {
  const VaeConfig c = VaePreset("tiny");
  Weights w = VaeInitWeights(c, 12);
  w.SetRequiresGrad(true);
  std::vector<at::Tensor> params;
  for (const auto& name : w.order) params.push_back(w.Get(name));
  torch::optim::Adam opt(params, torch::optim::AdamOptions(3e-3));
  const at::Tensor video = SmoothVideo(9, 16, 16);
  const double var = video.var().item<double>();
  double first = 0;
  for (int step = 0; step < 80; ++step) {
    opt.zero_grad();
    const at::Tensor rec = VaeDecode(c, w, VaeEncode(c, w, video));
    const at::Tensor loss = (rec - video).pow(2).mean();
    loss.backward();
    opt.step();
    if (step == 0) first = loss.item<double>();
  }
  at::NoGradGuard no_grad;
  const at::Tensor rec = VaeDecode(c, w, VaeEncode(c, w, video));
  const double mse = (rec - video).pow(2).mean().item<double>();
  std::cout << "tiny round trip MSE: random init " << first << ", after 80 "
            << "Adam steps " << mse << " (video variance " << var << ")"
            << std::endl;
  EXPECT_EQ(rec.sizes(), video.sizes());
  EXPECT_LT(mse, 0.2 * first);
  EXPECT_LT(mse, 0.25 * var);
}

}  // namespace
}  // namespace diffusion
}  // namespace geodrive

// `geodrive-diffusion vae-encode` / `vae-decode` (diffusion/vae_command.cc):
// the tiny-config round trip through the binary (shapes, metadata, the 16-bit
// PNG frames against the float32 tensor, the frame-folder input, the MP4,
// byte-identical reruns), the decoder's tensor output against the torch
// reference (tests/diffusion/vae_reference.py) and bad inputs. Each run of the
// binary costs about 0.6 s of LibTorch start-up, so the runs are few.

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

#include "diffusion/model.h"
#include "diffusion/safetensors.h"
#include "diffusion/vae.h"
#include "geometry/image_io.h"
#include "render/video/video_io.h"
#include "tests/common/test_util.h"
#include "tests/diffusion/diffusion_test_util.h"

namespace geodrive {
namespace diffusion {
namespace {

namespace fs = std::filesystem;

// Runs the binary with `args`; returns its combined output, expecting `rc`.
std::string RunCli(const std::string& args, int rc = 0) {
  std::string out;
  EXPECT_EQ(test::RunCommand(test::DiffusionCommand() + " " + args, &out), rc)
      << args << "\n"
      << out;
  return out;
}

// A smooth moving pattern plus noise, clamped to [-1, 1]: [1, 3, F, H, W].
at::Tensor TestVideo(int64_t frames, int64_t h, int64_t w) {
  at::Tensor t = at::arange(frames, at::kFloat).view({1, 1, frames, 1, 1});
  at::Tensor y = at::arange(h, at::kFloat).view({1, 1, 1, h, 1});
  at::Tensor x = at::arange(w, at::kFloat).view({1, 1, 1, 1, w});
  at::Tensor ch = at::arange(3, at::kFloat).view({1, 3, 1, 1, 1});
  return (0.8 * at::sin(0.35 * x + 0.25 * y - 0.3 * t + 2.0 * ch) +
          0.1 * at::randn({1, 3, frames, h, w}))
      .clamp(-1.0, 1.0)
      .contiguous();
}

// A frame folder's 16-bit PNGs 00000.png ... as their integer values v,
// RGB: [1, 3, F, H, W] float64.
at::Tensor ReadFrames16(const std::string& dir, int64_t frames) {
  std::vector<at::Tensor> out;
  for (int64_t f = 0; f < frames; ++f) {
    char name[32];
    std::snprintf(name, sizeof(name), "/%05lld.png", static_cast<long long>(f));
    const cv::Mat bgr = ReadImageUnchanged(dir + name);
    EXPECT_EQ(bgr.type(), CV_16UC3) << name;
    cv::Mat fl;
    bgr.convertTo(fl, CV_64F);
    out.push_back(at::from_blob(fl.data, {fl.rows, fl.cols, 3}, at::kDouble)
                      .index_select(2, at::tensor({2, 1, 0}, at::kLong))
                      .permute({2, 0, 1}));
  }
  return at::stack(out, 1).unsqueeze(0);
}

// Encode (tensor input, random tiny VAE from --seed) -> decode to a tensor,
// 16-bit frames and an MP4; everything checked against the library called
// in-process, then the same commands again, byte for byte.
TEST(VaeCommand, TinyRoundTripShapesMetadataFramesAndDeterminism) {
  const std::string dir = test::MakeTempDir("vae_command_round_trip");
  const VaeConfig c = VaePreset("tiny");
  const Weights w = VaeInitWeights(c, 3);
  at::manual_seed(test::kTestSeed);
  const at::Tensor video = TestVideo(17, 16, 24);
  SaveSafetensors(dir + "/video.safetensors", {{"video", video}});

  auto round_trip = [&](const std::string& sub) {
    const std::string d = dir + "/" + sub;
    RunCli("vae-encode --config tiny --seed 3 --tensor " + dir +
           "/video.safetensors --out " + d + "/lat.safetensors");
    return RunCli("vae-decode --config tiny --seed 3 --latents " + d +
                  "/lat.safetensors --out-tensor " + d +
                  "/dec.safetensors --out-frames " + d +
                  "/frames --out-video " + d + "/dec.mp4");
  };
  const std::string log = round_trip("a");
  EXPECT_NE(log.find("[1, 3, 17, 16, 24]"), std::string::npos) << log;
  // Without --config, vae-decode takes the latents' config metadata: the
  // same tensor as with --config tiny.
  const std::string log_meta = RunCli("vae-decode --seed 3 --latents " + dir +
                                      "/a/lat.safetensors --out-tensor " + dir +
                                      "/meta_dec.safetensors");
  EXPECT_NE(log_meta.find("VAE tiny, random tiny VAE (seed 3)"),
            std::string::npos)
      << log_meta;
  EXPECT_TRUE(test::ReadFile(dir + "/meta_dec.safetensors") ==
              test::ReadFile(dir + "/a/dec.safetensors"));

  // Latents: [B, F', C, h, w] = mean x 0.7, as generate stores them.
  const SafetensorsFile lat_file(dir + "/a/lat.safetensors");
  const at::Tensor lat = lat_file.Load("latents");
  ASSERT_EQ(lat.sizes(), (std::vector<int64_t>{1, 5, 4, 2, 3}));
  EXPECT_EQ(lat.scalar_type(), at::kFloat);
  const auto& lm = lat_file.metadata();
  EXPECT_EQ(lm.at("format"), "geodrive-vae-latents");
  EXPECT_EQ(lm.at("layout"), "BFCHW");
  EXPECT_EQ(std::stod(lm.at("scaling_factor")), c.scaling_factor);
  EXPECT_EQ(lm.at("config"), "tiny");
  at::NoGradGuard no_grad;
  const at::Tensor mean = VaeEncode(c, w, video);
  // Same library, same input, one thread each: equal up to float32 rounding
  // of the x 0.7 / 0.7 (the CLI and this process may pick other kernels).
  EXPECT_LT(
      test::MaxAbs(lat - (mean * c.scaling_factor).permute({0, 2, 1, 3, 4})),
      1e-6);

  // Decoded tensor: float32 [B, 3, F, H, W], unclamped.
  const SafetensorsFile dec_file(dir + "/a/dec.safetensors");
  const at::Tensor dec = dec_file.Load("video");
  ASSERT_EQ(dec.sizes(), (std::vector<int64_t>{1, 3, 17, 16, 24}));
  EXPECT_EQ(dec.scalar_type(), at::kFloat);
  EXPECT_EQ(dec_file.metadata().at("layout"), "BCFHW");
  EXPECT_EQ(dec_file.metadata().at("format"), "geodrive-vae-video");
  const at::Tensor expected =
      VaeDecode(c, w, (lat / c.scaling_factor).permute({0, 2, 1, 3, 4}));
  EXPECT_LT(test::MaxAbs(dec - expected),
            1e-5 * std::max(1.0, test::MaxAbs(expected)));
  // A random VAE overshoots [-1, 1]: the tensor keeps it, the frames clamp.
  const double peak = test::MaxAbs(dec);
  std::cout << "decoded max |x| " << peak << std::endl;

  // 16-bit frames: v = round((clamp(x) + 1) * 32767.5), so v / 32767.5 - 1
  // is within half a step (1/65535) of the clamped tensor.
  const at::Tensor v16 = ReadFrames16(dir + "/a/frames", 17);
  EXPECT_FALSE(fs::exists(dir + "/a/frames/00017.png"));
  const double quant =
      test::MaxAbs(v16 / 32767.5 - 1.0 - dec.to(at::kDouble).clamp(-1.0, 1.0));
  std::cout << "16-bit frames vs clamped tensor: max abs " << quant
            << " (bound 1/65535 = " << 1.0 / 65535 << ")" << std::endl;
  EXPECT_LE(quant, 1.0 / 65535 + 1e-12);
  EXPECT_GT(quant, 0.0);

  // Encoding the 16-bit frames uses all 16 bits: the command reads them as
  // x / 32767.5 - 1 in float32, as here.
  const at::Tensor frames = v16.to(at::kFloat) / 32767.5 - 1.0;
  RunCli("vae-encode --seed 3 --frames " + dir + "/a/frames --out " + dir +
         "/lat_frames.safetensors");
  const at::Tensor lat_frames =
      SafetensorsFile(dir + "/lat_frames.safetensors").Load("latents");
  EXPECT_LT(
      test::MaxAbs(lat_frames - (VaeEncode(c, w, frames) * c.scaling_factor)
                                    .permute({0, 2, 1, 3, 4})),
      1e-6);
  // The MP4: 17 8-bit frames of 24x16.
  const std::vector<cv::Mat> mp4 = ReadVideoFrames(dir + "/a/dec.mp4");
  ASSERT_EQ(mp4.size(), 17u);
  EXPECT_EQ(mp4[0].size(), cv::Size(24, 16));

  // Deterministic: the same commands again give byte-identical files.
  std::vector<std::string> files = {"lat.safetensors", "dec.safetensors"};
  for (int f = 0; f < 17; ++f) {
    char name[32];
    std::snprintf(name, sizeof(name), "frames/%05d.png", f);
    files.push_back(name);
  }
  std::vector<std::string> first;
  for (const std::string& file : files)
    first.push_back(test::ReadFile(dir + "/a/" + file));
  fs::remove_all(dir + "/a/frames");  // vae-decode wants an empty folder
  round_trip("a");
  for (size_t i = 0; i < files.size(); ++i) {
    EXPECT_GT(first[i].size(), 100u) << files[i];
    EXPECT_TRUE(first[i] == test::ReadFile(dir + "/a/" + files[i])) << files[i];
  }
}

// The decoder's float32 output, through the command line (the layout and
// scaling_factor handling included), against vae_reference.py: 7 latent
// frames -> 25 frames, three decode batches [0, 3), [3, 5), [5, 7), so the
// causal-conv caches carry twice.
TEST(VaeCommand, DecoderMatchesTorchReference) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("torch");
  const std::string dir = test::MakeTempDir("vae_command_reference");
  const VaeConfig c = VaePreset("tiny");
  NamedTensors weights;
  AppendForSave(VaeInitWeights(c, 11), "", &weights);
  SaveSafetensors(dir + "/w.safetensors", weights);
  at::manual_seed(test::kTestSeed);
  // As `sample` writes them: [B, F', C, h, w] x scaling_factor, no metadata.
  const at::Tensor unscaled = at::randn({1, 4, 7, 2, 3});
  const at::Tensor scaled =
      (unscaled * c.scaling_factor).permute({0, 2, 1, 3, 4}).contiguous();
  SaveSafetensors(dir + "/lat.safetensors", {{"latents", scaled}});
  // The reference decodes exactly what the command divides out.
  SaveSafetensors(
      dir + "/ref_in.safetensors",
      {{"x",
        (scaled / c.scaling_factor).permute({0, 2, 1, 3, 4}).contiguous()}});
  RunCli("vae-decode --vae-weights " + dir + "/w.safetensors --latents " + dir +
         "/lat.safetensors --out-tensor " + dir + "/dec.safetensors");
  const at::Tensor mine =
      SafetensorsFile(dir + "/dec.safetensors").Load("video");
  ASSERT_EQ(mine.sizes(), (std::vector<int64_t>{1, 3, 25, 16, 24}));

  std::ostringstream config;
  config << "{\"in_channels\": 3, \"latent_channels\": " << c.latent_channels
         << ", \"block_out_channels\": [8, 16, 16, 16], \"layers_per_block\": "
         << c.layers_per_block << ", \"norm_num_groups\": " << c.norm_num_groups
         << ", \"temporal_compression_ratio\": " << c.temporal_compression
         << "}";
  ASSERT_EQ(c.block_out_channels, (std::vector<int>{8, 16, 16, 16}));
  std::string out;
  ASSERT_EQ(
      test::RunCommand(
          std::string(test::kDebianPython) + " " + GEODRIVE_SOURCE_DIR +
              "/tests/diffusion/vae_reference.py decode '" + config.str() +
              "' " + dir + "/w.safetensors " + dir + "/ref_in.safetensors",
          &out),
      0)
      << out;
  std::istringstream lines(out);
  std::vector<float> values;
  double v;
  while (lines >> v) values.push_back(static_cast<float>(v));
  ASSERT_EQ(static_cast<int64_t>(values.size()), mine.numel())
      << out.substr(0, 500);
  const at::Tensor ref = at::tensor(values).view(mine.sizes());
  const double err = test::MaxAbs(mine - ref), scale = test::MaxAbs(ref);
  const double mean_err = (mine - ref).abs().mean().item<double>();
  std::cout << "vae-decode vs torch reference: max abs " << err << ", mean abs "
            << mean_err << " (max |out| " << scale << ")" << std::endl;
  EXPECT_GT(scale, 0.1);
  // Debian's python3-torch and libtorch-dev are one LibTorch build, so both
  // sides run the same kernels and the difference measured here is 0. The
  // limit leaves room for another LibTorch or CPU (other kernels, other
  // summation orders): float32 through ~30 convolutions and GroupNorms
  // accumulates a few 1e-7 relative error; 1e-5 of max(1, |out|) is ~100
  // float32 ulps, still below half a 16-bit PNG step at |out| <= 1, and far
  // below what a real difference (a wrong pad, resize or frame batch) gives
  // (Vae.FrameBatchingChangesGroupNormStatistics: 2.7).
  EXPECT_LT(err, 1e-5 * std::max(1.0, scale));
}

TEST(VaeCommand, BadInputsExitTwoWithOneLineNamingTheInput) {
  const std::string dir = test::MakeTempDir("vae_command_bad");
  auto expect_error = [&](const std::string& args, const std::string& needle) {
    const std::string out = RunCli(args, 2);
    EXPECT_NE(out.find(needle), std::string::npos) << args << "\n" << out;
    // One line: "geodrive-diffusion vae-...: error: ...".
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  };
  const std::string enc = "vae-encode --out " + dir + "/o.safetensors ";
  // 16 frames (not 1 + 4k), a NaN.
  SaveSafetensors(dir + "/f16.safetensors",
                  {{"video", at::zeros({1, 3, 16, 16, 16})}});
  expect_error(enc + "--tensor " + dir + "/f16.safetensors",
               "f16.safetensors: 16 frames: the VAE takes 1 + 4k frames (13 "
               "or 17");
  at::Tensor nan = at::zeros({1, 3, 5, 16, 16});
  nan[0][1][2][3][4] = std::nanf("");
  SaveSafetensors(dir + "/nan.safetensors", {{"video", nan}});
  expect_error(enc + "--tensor " + dir + "/nan.safetensors",
               "nan.safetensors: 1 NaN and 0 infinite values");
  // Decode: a missing file; latents of another channel count.
  expect_error("vae-decode --latents " + dir +
                   "/none.safetensors --out-tensor " + dir + "/d.safetensors",
               dir + "/none.safetensors");
  SaveSafetensors(dir + "/lat3.safetensors",
                  {{"latents", at::zeros({1, 2, 3, 2, 2})}});
  expect_error("vae-decode --latents " + dir +
                   "/lat3.safetensors --out-tensor " + dir + "/d.safetensors",
               "lat3.safetensors: latents [1, 2, 3, 2, 2] are not BFCHW with "
               "C = 4");
  // The metadata's config is the default VAE (here the 5B one, whose weights
  // must be given); a --config naming another VAE is refused; a config that
  // names no VAE preset says so.
  SaveSafetensors(dir + "/lat5b.safetensors",
                  {{"latents", at::zeros({1, 2, 16, 2, 2})}},
                  {{"config", "cogvideox-5b-i2v"}});
  const std::string dec5b = "vae-decode --latents " + dir +
                            "/lat5b.safetensors --out-tensor " + dir +
                            "/d.safetensors";
  expect_error(dec5b, "--config cogvideox-5b-i2v: give --vae-weights");
  expect_error(dec5b + " --config tiny-49",
               "lat5b.safetensors: latents of the cogvideox-5b-i2v VAE "
               "(metadata config 'cogvideox-5b-i2v'), but --config tiny-49 is "
               "the tiny VAE");
  SaveSafetensors(dir + "/latx.safetensors",
                  {{"latents", at::zeros({1, 2, 4, 2, 2})}},
                  {{"config", "nonsense"}});
  expect_error("vae-decode --latents " + dir +
                   "/latx.safetensors --out-tensor " + dir + "/d.safetensors",
               "latx.safetensors: metadata config 'nonsense' names no VAE "
               "preset");
  EXPECT_FALSE(fs::exists(dir + "/o.safetensors"));
  EXPECT_FALSE(fs::exists(dir + "/d.safetensors"));
}

}  // namespace
}  // namespace diffusion
}  // namespace geodrive

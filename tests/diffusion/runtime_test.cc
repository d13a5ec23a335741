// Device and dtype (diffusion/runtime.h) on the CPU: option parsing, the
// attention kernels against each other and the plain formula, bf16 / fp16
// weights and forward against float32, checkpoints loaded in their own dtype,
// sampling in bf16, and the CLI's errors for devices this LibTorch lacks.

#include "diffusion/runtime.h"

#include <ATen/ATen.h>
#include <ATen/CPUGeneratorImpl.h>
#include <gtest/gtest.h>

#include <cstring>

#include "diffusion/model.h"
#include "diffusion/runtime_torch.h"
#include "diffusion/safetensors.h"
#include "diffusion/sampler.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"
#include "tests/diffusion/diffusion_test_util.h"

namespace geodrive {
namespace diffusion {
namespace runtime_test {
namespace {

TEST(DiffusionRuntime, ParsesDevicesAndDtypesWholeString) {
  EXPECT_FALSE(ParseDevice("cpu").is_cuda());
  EXPECT_EQ(ParseDevice("cuda").ToString(), "cuda:0");
  EXPECT_EQ(ParseDevice("cuda:3").index, 3);
  for (const char* bad : {"", "gpu", "cuda:", "cuda:-1", "cuda:1x", "CPU",
                          "cuda:99999", " cpu"}) {
    try {
      ParseDevice(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("--device"), std::string::npos);
    }
  }
  EXPECT_EQ(ParseDtype("bf16"), ComputeDtype::kBFloat16);
  EXPECT_EQ(ParseDtype("float16"), ComputeDtype::kFloat16);
  EXPECT_EQ(ParseDtype("fp32"), ComputeDtype::kFloat32);
  EXPECT_THROW(ParseDtype("fp8"), InputError);
  EXPECT_THROW(ParseDtype("bf16 "), InputError);
  EXPECT_EQ(ParseAttentionBackend("fused"), AttentionBackend::kFused);
  EXPECT_THROW(ParseAttentionBackend("flash"), InputError);
  // Debian's 1.13 has no public fused kernel: auto is the chunked path there.
  EXPECT_EQ(ResolveAttentionBackend(AttentionBackend::kAuto),
            GetRuntimeInfo().public_sdpa ? AttentionBackend::kFused
                                         : AttentionBackend::kChunked);
}

TEST(DiffusionRuntime, CudaOnACpuOnlyLibTorchIsAnInputError) {
  RuntimeOptions r;
  const RuntimeInfo info = GetRuntimeInfo();
  if (info.cuda_available) {
    // A CUDA build: the visible devices pass, the next ordinal does not.
    r.device = ParseDevice("cuda:" + std::to_string(info.cuda_devices));
    EXPECT_THROW(r.Check(), InputError);
    r.device = ParseDevice("cuda:0");
    EXPECT_NO_THROW(r.Check());
    return;
  }
  r.device = ParseDevice("cuda:0");
  try {
    r.Check();
    FAIL() << "accepted cuda on a CPU-only LibTorch";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no CUDA support"), std::string::npos)
        << e.what();
  }
}

struct Inputs {
  at::Tensor x, text, t, noisy, cond;
};

Inputs MakeInputs(const DiTConfig& c, uint64_t seed) {
  at::Generator gen = at::make_generator<at::CPUGeneratorImpl>(seed);
  const int64_t B = 2, F = c.latent_frames, C = c.out_channels;
  Inputs in;
  in.noisy = at::randn({B, F, C, c.latent_height, c.latent_width}, gen);
  in.cond = at::randn({B, F, C, c.latent_height, c.latent_width}, gen);
  in.x = at::cat({in.noisy, at::randn(in.noisy.sizes(), gen)}, 2);
  in.text = at::randn({B, c.text_seq_len, c.text_embed_dim}, gen);
  in.t = at::full({B}, 333.0);
  return in;
}

// The fused kernel (1.13: the private _scaled_dot_product_attention) and the
// chunked path, with chunks small enough to split heads and queries, give the
// same forward (float32 summation order only).
TEST(DiffusionRuntime, FusedAndChunkedAttentionAgree) {
  const DiTConfig c = ConfigPreset("tiny");
  const Weights w = InitWeights(BackboneParamSpecs(c), 41);
  Weights branch = InitBranchFromBackbone(c, w, 42);
  const Inputs in = MakeInputs(c, 43);
  at::NoGradGuard no_grad;
  ForwardOptions chunked, fused;
  chunked.attention = AttentionBackend::kChunked;
  chunked.attention_chunk_bytes = 4096;  // 2 x 26 x 4 B rows: 19 queries
  fused.attention = AttentionBackend::kFused;
  const auto rc =
      BranchForward(c, branch, in.noisy, in.cond, in.text, in.t, chunked);
  const auto rf =
      BranchForward(c, branch, in.noisy, in.cond, in.text, in.t, fused);
  const at::Tensor a = BackboneForward(c, w, in.x, in.text, in.t, rc, chunked);
  const at::Tensor b = BackboneForward(c, w, in.x, in.text, in.t, rf, fused);
  const double err = (a - b).abs().max().item<double>();
  std::cout << "fused vs chunked attention: max abs difference " << err
            << std::endl;
  EXPECT_LT(err, 1e-5);
  EXPECT_GT(a.abs().max().item<double>(), 0.1);  // not a vacuous comparison
}

// bf16 (and, where the CPU kernels have it, fp16) weights run the whole
// forward in that dtype; the result is the float32 one within the format's
// precision. bf16 has an 8-bit significand (relative rounding 2^-9 per
// operation); through 4 blocks the output differs by a few per cent of its
// magnitude, fp16 (11 bits) by about 8x less. LibTorch 1.13 has no fp16 matmul
// on the CPU: there RuntimeOptions::Check rejects fp16 with one line.
TEST(DiffusionRuntime, ReducedPrecisionForwardTracksFloat32) {
  const DiTConfig c = ConfigPreset("tiny");
  const Inputs in = MakeInputs(c, 51);
  at::NoGradGuard no_grad;
  const Weights w32 = InitWeights(BackboneParamSpecs(c), 52);
  const at::Tensor ref = BackboneForward(c, w32, in.x, in.text, in.t, {});
  const double scale = ref.abs().max().item<double>();
  std::vector<ComputeDtype> dtypes = {ComputeDtype::kBFloat16};
  RuntimeOptions fp16_cpu;
  fp16_cpu.dtype = ComputeDtype::kFloat16;
  if (GetRuntimeInfo().public_sdpa) {  // LibTorch >= 2
    dtypes.push_back(ComputeDtype::kFloat16);
  } else {
    try {
      fp16_cpu.Check();
      ADD_FAILURE() << "fp16 on the CPU accepted by LibTorch 1.x";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("--dtype fp16"), std::string::npos);
    }
  }
  for (ComputeDtype d : dtypes) {
    WeightPlacement place;
    place.dtype = d;
    const Weights w = InitWeights(BackboneParamSpecs(c), 52, place);
    EXPECT_EQ(w.Get("proj_out.weight").scalar_type(), ToScalarType(d));
    EXPECT_EQ(w.Bytes() * 2, w32.Bytes());
    const at::Tensor out = BackboneForward(c, w, in.x, in.text, in.t, {});
    EXPECT_EQ(out.scalar_type(), ToScalarType(d));
    const double err = (out.to(at::kFloat) - ref).abs().max().item<double>();
    std::cout << DtypeName(d) << " vs fp32 forward: max abs difference " << err
              << " (output max " << scale << ")" << std::endl;
    EXPECT_LT(err, (d == ComputeDtype::kBFloat16 ? 0.05 : 0.01) * scale);
    EXPECT_GT(err, 0.0);  // it really ran in reduced precision
  }
}

// A BF16 checkpoint loads into bf16 bit for bit (no float32 round trip), and
// into fp32 by exact widening.
TEST(DiffusionRuntime, Bf16CheckpointLoadsInItsOwnDtype) {
  const std::string dir = test::MakeTempDir("diffusion_runtime_bf16");
  const DiTConfig c = ConfigPreset("tiny");
  WeightPlacement bf16;
  bf16.dtype = ComputeDtype::kBFloat16;
  const Weights w = InitWeights(BackboneParamSpecs(c), 61, bf16);
  std::vector<std::pair<std::string, at::Tensor>> all;
  AppendForSave(w, "", &all);
  SaveSafetensors(dir + "/w.safetensors", all);
  EXPECT_EQ(
      SafetensorsFile(dir + "/w.safetensors").Entry("proj_out.weight").dtype,
      "BF16");
  LoadReport report;
  const Weights same = LoadWeights(
      dir + "/w.safetensors", BackboneParamSpecs(c), "", true, &report, bf16);
  const Weights wide = LoadWeights(dir + "/w.safetensors",
                                   BackboneParamSpecs(c), "", true, &report);
  for (const auto& name : w.order) {
    const at::Tensor& a = w.Get(name);
    const at::Tensor& b = same.Get(name);
    ASSERT_EQ(b.scalar_type(), at::kBFloat16) << name;
    ASSERT_EQ(std::memcmp(a.data_ptr(), b.data_ptr(), a.nbytes()), 0) << name;
    ASSERT_EQ(wide.Get(name).scalar_type(), at::kFloat) << name;
    ASSERT_TRUE(at::equal(wide.Get(name), a.to(at::kFloat))) << name;
  }
}

// The whole sampler in bf16 on the CPU: float32 latents out, close to the
// float32 sampler's (3 steps), and the CLI reports the runtime.
TEST(DiffusionRuntime, SampleInBf16GivesFloat32LatentsNearFp32) {
  const std::string dir = test::MakeTempDir("diffusion_runtime_sample");
  std::string log;
  ASSERT_EQ(test::RunCommand(
                test::DiffusionCommand() +
                    " init-weights --config tiny --nonzero-branch --out " +
                    dir + "/w.safetensors",
                &log),
            0)
      << log;
  const DiTConfig c = ConfigPreset("tiny");
  at::Generator gen = at::make_generator<at::CPUGeneratorImpl>(71);
  const int64_t C = c.out_channels, F = c.latent_frames;
  SaveSafetensors(
      dir + "/image.safetensors",
      {{"latents",
        at::randn({1, 1, C, c.latent_height, c.latent_width}, gen)}});
  SaveSafetensors(
      dir + "/cond.safetensors",
      {{"latents",
        at::randn({1, F, C, c.latent_height, c.latent_width}, gen)}});
  auto sample = [&](const std::string& out, const std::string& extra) {
    std::string l;
    EXPECT_EQ(test::RunCommand(test::DiffusionCommand() +
                                   " sample --config tiny --weights " + dir +
                                   "/w.safetensors --latents " + dir +
                                   "/image.safetensors --cond-latents " + dir +
                                   "/cond.safetensors --steps 3 --no-progress "
                                   "--out " +
                                   dir + "/" + out + " " + extra,
                               &l),
              0)
        << l;
    return l;
  };
  sample("fp32.safetensors", "");
  const std::string l = sample("bf16.safetensors", "--dtype bf16");
  EXPECT_NE(l.find("on cpu bf16"), std::string::npos) << l;
  SafetensorsFile a(dir + "/fp32.safetensors"), b(dir + "/bf16.safetensors");
  EXPECT_EQ(b.Entry("latents").dtype, "F32");
  EXPECT_EQ(b.metadata().at("dtype"), "bf16");
  const at::Tensor la = a.Load("latents"), lb = b.Load("latents");
  const double err = (la - lb).abs().max().item<double>();
  std::cout << "bf16 vs fp32 sampler (3 DPM steps): max abs difference " << err
            << " (latents max " << la.abs().max().item<double>() << ")"
            << std::endl;
  // The noise and scheduler are float32 in both; only the model's output
  // differs, by bf16 rounding (a few per cent, see above), times the DPM
  // coefficients (< 1 at these steps).
  EXPECT_LT(err, 0.1 * la.abs().max().item<double>());
  EXPECT_GT(err, 0.0);
  // Bad runtime options: one line naming the option, exit 2.
  for (const char* extra :
       {"--device gpu", "--dtype bf17", "--attention flash"}) {
    std::string bad;
    EXPECT_EQ(
        test::RunCommand(
            test::DiffusionCommand() + " sample --config tiny --weights " +
                dir + "/w.safetensors --latents " + dir +
                "/image.safetensors --cond-latents " + dir +
                "/cond.safetensors --out " + dir + "/x.safetensors " + extra,
            &bad),
        2)
        << extra << ": " << bad;
    // The option named is the one given (--vae-dtype, not --dtype).
    const std::string option(extra, std::string(extra).find(' '));
    EXPECT_NE(bad.find(option + ":"), std::string::npos) << bad;
  }
  // --vae-dtype is named as itself (vae-decode has it, sample does not).
  {
    std::string bad;
    EXPECT_EQ(
        test::RunCommand(test::DiffusionCommand() + " vae-decode --latents " +
                             dir + "/image.safetensors --out-tensor " + dir +
                             "/v.safetensors --vae-dtype bf17",
                         &bad),
        2)
        << bad;
    EXPECT_NE(bad.find("--vae-dtype: 'bf17' is not a dtype"), std::string::npos)
        << bad;
  }
  if (!GetRuntimeInfo().cuda_available) {
    std::string bad;
    EXPECT_EQ(test::RunCommand(test::DiffusionCommand() +
                                   " check-weights --config tiny "
                                   "--weights " +
                                   dir + "/w.safetensors --device cuda",
                               &bad),
              2)
        << bad;
    EXPECT_NE(bad.find("no CUDA support"), std::string::npos) << bad;
  }
  std::string check;
  ASSERT_EQ(test::RunCommand(test::DiffusionCommand() +
                                 " check-weights --config tiny --weights " +
                                 dir + "/w.safetensors --dtype bf16",
                             &check),
            0)
      << check;
  EXPECT_NE(check.find("stored as F32"), std::string::npos) << check;
  EXPECT_NE(check.find("GB in bf16 on cpu"), std::string::npos) << check;
}

}  // namespace
}  // namespace runtime_test
}  // namespace diffusion
}  // namespace geodrive

// `geodrive-diffusion vae-encode` and `vae-decode`: CogVideoX's VAE
// (diffusion/vae.h) alone, between videos, lossless frames and tensors, so
// that its numbers can be checked against another implementation
// (docs/DIFFUSION.md, "VAE").
//
//   vae-encode: a video file, a folder of PNG/JPG frames (8- or 16-bit) or a
//     safetensors tensor [B, 3, F, H, W] in [-1, 1] -> the latent mean
//     x scaling_factor as "latents" [B, F', C, H/8, W/8], the layout `sample`
//     reads and `generate` keeps under <stem>_latents/.
//   vae-decode: such latents (or `sample`'s output) -> float32 "video"
//     [B, 3, F, H, W] unclamped, 16-bit PNG frames and/or an 8-bit MP4.

#include <ATen/ATen.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include "apps/cli/cli.h"
#include "diffusion/config.h"
#include "diffusion/model.h"
#include "diffusion/runtime_cli.h"
#include "diffusion/runtime_torch.h"
#include "diffusion/safetensors.h"
#include "diffusion/vae.h"
#include "diffusion/vae_config.h"
#include "geometry/image_io.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"
#include "render/video/video.h"
#include "render/video/video_io.h"

namespace geodrive {
namespace diffusion {
namespace {

namespace fs = std::filesystem;

// __metadata__ of the files written here.
constexpr char kFormatKey[] = "format";
constexpr char kLatentsFormat[] = "geodrive-vae-latents";
constexpr char kVideoFormat[] = "geodrive-vae-video";
constexpr char kLayoutKey[] = "layout";
constexpr char kScaleKey[] = "scaling_factor";
// Latents as the transformer takes them (`sample --latents`, generate's
// <stem>_latents/*.safetensors): [batch, latent frames, channels, h, w].
constexpr char kLatentLayoutBFCHW[] = "BFCHW";
// diffusers' VAE layout: [batch, channels, frames, height, width].
constexpr char kLayoutBCFHW[] = "BCFHW";

// 16-bit PNG frames: [-1, 1] -> [0, 65535].
constexpr double kHalf16 = 65535.0 / 2.0;

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
      .count();
}

// The shortest text that reads back as `v` ("0.7").
std::string FormatDouble(double v) {
  char buffer[64];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof(buffer), v);
  return ec == std::errc() ? std::string(buffer, end) : std::to_string(v);
}

std::string LowerExtension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) {
    return static_cast<char>(std::tolower(c));
  });
  return ext;
}

// ---- The VAE ----

// The preset `config` names: a VAE preset, or a DiT config preset for the VAE
// it pairs with (VaePreset).
VaeConfig VaeConfigFor(const std::string& config) {
  VaeConfig c = VaePreset(config);
  c.Check();
  return c;
}

// The weights of `vae_weights` for `c`, or random tiny weights from `seed`;
// *source gets "random tiny VAE (seed N)" or the checkpoint path.
Weights LoadVae(const VaeConfig& c,
                const std::string& config,
                const std::string& vae_weights,
                uint64_t seed,
                const RuntimeOptions& runtime,
                std::string* source) {
  // On --device in --vae-dtype (random weights drawn in float32 on the CPU,
  // then placed: the same numbers on every device).
  WeightPlacement placement;
  placement.device = runtime.device;
  placement.dtype = runtime.vae_dtype;
  if (vae_weights.empty()) {
    GEODRIVE_CHECK_INPUT(c.name == "tiny", "--config ", config,
                         ": give --vae-weights (diffusers vae/"
                         "diffusion_pytorch_model.safetensors); random "
                         "weights from --seed are for the tiny presets only");
    *source = "random tiny VAE (seed " + std::to_string(seed) + ")";
    return VaeInitWeights(c, seed).To(
        ComputeOptions(placement.device, placement.dtype));
  }
  *source = vae_weights;
  LoadReport report;
  return LoadWeights(vae_weights, VaeParamSpecs(c), "", true, &report,
                     placement);
}

// ---- Inputs ----

// The tensor called `preferred`, else the file's only tensor.
at::Tensor LoadNamedOrOnly(const SafetensorsFile& file,
                           const std::string& preferred) {
  if (file.Has(preferred)) return file.Load(preferred);
  if (file.entries().size() == 1) return file.Load(file.entries()[0].name);
  std::string names;
  for (const auto& e : file.entries())
    names += (names.empty() ? "" : ", ") + e.name;
  ThrowInputError(file.path(), "no tensor '", preferred,
                  "' and not exactly one tensor (has: ",
                  names.empty() ? "none" : names, ")");
}

void CheckFinite(const at::Tensor& t, const std::string& what) {
  if (at::isfinite(t).all().item<bool>()) return;
  const int64_t nan = at::isnan(t).sum().item<int64_t>();
  const int64_t inf = at::isinf(t).sum().item<int64_t>();
  ThrowInputError(what, nan, " NaN and ", inf, " infinite values");
}

// A video tensor [B, 3, F, H, W] the encoder accepts: F = 1 + 4k, H and W
// multiples of 8, finite. `what` names the input in errors.
void CheckVideoShape(const at::Tensor& v,
                     const VaeConfig& c,
                     const std::string& what) {
  GEODRIVE_CHECK_INPUT(v.dim() == 5 && v.size(1) == c.in_channels, what,
                       ": expected a video [B, ", c.in_channels,
                       ", F, H, W], got ", ShapeToString(v.sizes().vec()));
  const int64_t frames = v.size(2), h = v.size(3), w = v.size(4);
  const int64_t t = c.temporal_compression, s = c.spatial_compression;
  GEODRIVE_CHECK_INPUT(v.size(0) >= 1 && frames >= 1 && h >= 1 && w >= 1, what,
                       ": empty video ", ShapeToString(v.sizes().vec()));
  if ((frames - 1) % t != 0) {
    const int64_t below = 1 + (frames - 1) / t * t;
    ThrowInputError(what, frames, " frames: the VAE takes 1 + ", t,
                    "k frames (", below, " or ", below + t,
                    "; 49 for CogVideoX)");
  }
  GEODRIVE_CHECK_INPUT(h % s == 0 && w % s == 0, what, ": ", w, "x", h,
                       " pixels: width and height must be multiples of ", s);
  CheckFinite(v, what);
}

// One frame as float32 [3, H, W] in [-1, 1]. A 16-bit PNG keeps its 16 bits
// (x / 32767.5 - 1); anything else is read as 8-bit RGB (x / 127.5 - 1), as
// `generate` reads frames. *bits gets 8 or 16.
at::Tensor ReadFrame(const std::string& file, int* bits) {
  cv::Mat raw;
  if (LowerExtension(file) == ".png") raw = ReadImageUnchanged(file);
  at::Tensor hwc;
  double half = 127.5;
  if (!raw.empty() && raw.depth() == CV_16U) {
    // ReadImageUnchanged: gray, BGR or BGRA.
    const int cn = raw.channels();
    GEODRIVE_CHECK_INPUT(cn == 1 || cn == 3 || cn == 4, file,
                         ": 16-bit PNG with ", cn, " channels");
    cv::Mat f;
    raw.convertTo(f, CV_32F);  // exact for 16-bit integers
    hwc = at::from_blob(f.data, {f.rows, f.cols, cn}, at::kFloat).clone();
    hwc = cn == 1 ? hwc.expand({f.rows, f.cols, 3})
                  : hwc.index_select(2, at::tensor({2, 1, 0}, at::kLong));
    half = kHalf16;
    *bits = 16;
  } else {
    const cv::Mat rgb = ReadImageRgb(file);
    cv::Mat f;
    rgb.convertTo(f, CV_32F);
    hwc = at::from_blob(f.data, {f.rows, f.cols, 3}, at::kFloat).clone();
    *bits = 8;
  }
  return (hwc.permute({2, 0, 1}) / half - 1.0).contiguous();
}

// The .png/.jpg/.jpeg files of `dir`, sorted by name.
std::vector<std::string> FrameFiles(const std::string& dir) {
  GEODRIVE_CHECK_INPUT(fs::is_directory(dir), dir,
                       fs::exists(dir) ? ": not a folder (--frames takes a "
                                         "folder of PNG/JPG frames)"
                                       : ": no such folder");
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.is_regular_file() && IsImageFile(entry.path().string()))
      files.push_back(entry.path().string());
  }
  std::sort(files.begin(), files.end());
  GEODRIVE_CHECK_INPUT(!files.empty(), dir,
                       ": no .png/.jpg/.jpeg frames in the folder");
  return files;
}

// [F, 3, H, W] frames -> [1, 3, F, H, W].
at::Tensor StackFrames(const std::vector<at::Tensor>& frames) {
  return at::stack(frames, 1).unsqueeze(0).contiguous();
}

// ---- vae-encode ----

struct VaeEncodeOptions {
  // VAE preset: tiny, cogvideox-5b-i2v, or a DiT config preset (tiny-49) for
  // the VAE it pairs with.
  std::string config = "tiny";
  // VAE checkpoint (diffusers vae/diffusion_pytorch_model.safetensors); empty:
  // random weights from `seed` (tiny presets only, for tests).
  std::string vae_weights;
  uint64_t seed = 0;
  // Device and VAE dtype (--device, --vae-dtype); the output is float32.
  RuntimeOptions runtime;
  // Exactly one input. A video file (.mp4 ...; 8-bit RGB frames).
  std::string video;
  // A folder of PNG/JPG frames sorted by name; 16-bit PNGs keep 16 bits.
  std::string frames;
  // A safetensors file: "video" (or its only tensor) [B, 3, F, H, W] in
  // [-1, 1], any float dtype.
  std::string tensor;
  // Output safetensors: "latents" [B, F', C, H/8, W/8] float32.
  std::string out;
  // Store the latent mean itself instead of mean x scaling_factor.
  bool no_scale = false;

  void Check() const {
    GEODRIVE_CHECK_INPUT(
        !video.empty() + !frames.empty() + !tensor.empty() == 1,
        "give exactly one input: --video FILE, --frames DIR or "
        "--tensor FILE.safetensors");
    GEODRIVE_CHECK_INPUT(!out.empty(), "--out FILE.safetensors is required");
    GEODRIVE_CHECK_INPUT(LowerExtension(out) == ".safetensors", out,
                         ": --out must end in .safetensors");
  }
};

struct VaeEncodeResult {
  std::string out, source, vae;
  std::vector<int64_t> video_shape, latents_shape;
  int bits = 0;  // 8 or 16 for frames; 32 for a float tensor
  double scale = 1, seconds = 0;

  std::string BriefReport() const {
    std::ostringstream s;
    s << out << ": latents " << ShapeToString(latents_shape)
      << " (B, F, C, h, w), latent mean x " << scale << ", from "
      << ShapeToString(video_shape) << " (B, 3, F, H, W, " << bits
      << "-bit) of " << source << "; VAE " << vae << "; " << std::fixed
      << std::setprecision(2) << seconds << " s";
    return s.str();
  }
};

VaeEncodeResult RunVaeEncode(const VaeEncodeOptions& o) {
  o.Check();
  const auto start = std::chrono::steady_clock::now();
  VaeEncodeResult r;
  r.out = o.out;
  // Inputs first (cheap checks before the weights load).
  at::Tensor video;
  if (!o.video.empty()) {
    GEODRIVE_CHECK_INPUT(IsVideoFile(o.video), o.video,
                         ": --video takes a video file (.mp4/.avi/.mkv/.mov/"
                         ".webm); give a folder of frames with --frames");
    std::vector<at::Tensor> frames;
    for (const cv::Mat& rgb : ReadVideoFrames(o.video)) {
      cv::Mat f;
      rgb.convertTo(f, CV_32F);
      frames.push_back((at::from_blob(f.data, {f.rows, f.cols, 3}, at::kFloat)
                                .permute({2, 0, 1}) /
                            127.5 -
                        1.0)
                           .contiguous());
    }
    video = StackFrames(frames);
    r.source = o.video;
    r.bits = 8;
  } else if (!o.frames.empty()) {
    std::vector<at::Tensor> frames;
    const std::vector<std::string> files = FrameFiles(o.frames);
    for (const std::string& file : files) {
      int bits = 8;
      frames.push_back(ReadFrame(file, &bits));
      r.bits = std::max(r.bits, bits);
      GEODRIVE_CHECK_INPUT(frames.back().sizes() == frames.front().sizes(),
                           file, ": ", frames.back().size(2), "x",
                           frames.back().size(1), " pixels but ", files[0],
                           " is ", frames.front().size(2), "x",
                           frames.front().size(1));
    }
    video = StackFrames(frames);
    r.source = o.frames;
    CheckOutputFileOutsideInput(o.out, o.frames);
  } else {
    const SafetensorsFile file(o.tensor);
    video = LoadNamedOrOnly(file, "video");
    GEODRIVE_CHECK_INPUT(at::isFloatingType(video.scalar_type()), o.tensor,
                         ": the video must be a float tensor, got ",
                         video.scalar_type());
    video = video.to(at::kFloat).contiguous();
    r.source = o.tensor;
    r.bits = 32;
  }
  const VaeConfig c = VaeConfigFor(o.config);
  CheckVideoShape(video, c, r.source);
  if (!o.tensor.empty()) {
    const double lo = video.min().item<double>();
    const double hi = video.max().item<double>();
    GEODRIVE_CHECK_INPUT(lo >= -1.0 && hi <= 1.0, o.tensor, ": values in [", lo,
                         ", ", hi,
                         "]; the VAE takes [-1, 1] (clamp or rescale first)");
  }
  // An unusable output folder fails now; the weights load last.
  CreateOutputDirectory(fs::absolute(o.out).parent_path().string());
  const Weights w =
      LoadVae(c, o.config, o.vae_weights, o.seed, o.runtime, &r.vae);
  r.video_shape = video.sizes().vec();
  r.scale = o.no_scale ? 1.0 : c.scaling_factor;
  at::Tensor latents;
  {
    at::NoGradGuard no_grad;
    // As generate: the mean (the posterior's mode) x scaling_factor, in the
    // transformer's [B, F, C, h, w].
    latents = (VaeEncode(c, w, video).to(at::kCPU, at::kFloat) * r.scale)
                  .permute({0, 2, 1, 3, 4})
                  .contiguous();
  }
  r.latents_shape = latents.sizes().vec();
  const std::map<std::string, std::string> metadata = {
      {kFormatKey, kLatentsFormat},
      {kLayoutKey, kLatentLayoutBFCHW},
      {kScaleKey, FormatDouble(r.scale)},
      {"config", o.config},
      {"vae", r.vae},
      {"source", r.source},
      {"video_shape", ShapeToString(r.video_shape)},
  };
  SaveSafetensors(o.out, {{"latents", latents}}, metadata);
  r.seconds = SecondsSince(start);
  return r;
}

// ---- vae-decode ----

struct VaeDecodeOptions {
  // VAE preset (as vae-encode); empty: the latents' "config" metadata (what
  // vae-encode, `sample` and `generate` write), else tiny.
  std::string config;
  // VAE checkpoint; empty: random tiny weights from `seed`.
  std::string vae_weights;
  uint64_t seed = 0;
  // Device and VAE dtype (--device, --vae-dtype); the output is float32.
  RuntimeOptions runtime;
  // Input safetensors: "latents" (or its only tensor), any float dtype.
  std::string latents;
  // Layout of the latents: "auto" (the file's "layout" metadata, else BFCHW
  // as `sample` and `generate` write), "BFCHW" or "BCFHW" (diffusers').
  std::string layout = "auto";
  // The latents are the VAE's mean itself, not mean x scaling_factor (a file
  // whose metadata states its scaling_factor needs no flag).
  bool no_scale = false;
  // Outputs (at least one). float32 "video" [B, 3, F, H, W], unclamped.
  std::string out_tensor;
  // 16-bit RGB PNGs DIR/00000.png ..., clamped to [-1, 1] and mapped to
  // [0, 65535] (batch 1 only).
  std::string out_frames;
  // 8-bit MP4 (H.264) as `generate` writes (batch 1 only).
  std::string out_video;
  double fps = 8.0;

  void Check() const {
    GEODRIVE_CHECK_INPUT(!latents.empty(),
                         "--latents FILE.safetensors is required");
    GEODRIVE_CHECK_INPUT(
        !out_tensor.empty() || !out_frames.empty() || !out_video.empty(),
        "give at least one output: --out-tensor FILE.safetensors, "
        "--out-frames DIR or --out-video FILE.mp4");
    GEODRIVE_CHECK_INPUT(
        out_tensor.empty() || LowerExtension(out_tensor) == ".safetensors",
        out_tensor, ": --out-tensor must end in .safetensors");
    GEODRIVE_CHECK_INPUT(out_video.empty() || IsVideoFile(out_video), out_video,
                         ": --out-video must be a video file name "
                         "(.mp4)");
    GEODRIVE_CHECK_INPUT(layout == "auto" || layout == kLatentLayoutBFCHW ||
                             layout == kLayoutBCFHW,
                         "--layout ", layout, " is not auto, BFCHW or BCFHW");
    GEODRIVE_CHECK_INPUT(std::isfinite(fps) && fps > 0,
                         "--fps must be positive");
  }
};

struct VaeDecodeResult {
  std::string latents, config, vae, layout;
  std::vector<int64_t> latents_shape, video_shape;
  double scale = 1, seconds = 0;
  std::vector<std::string> outputs;

  std::string BriefReport() const {
    std::ostringstream s;
    s << latents << ": " << ShapeToString(latents_shape) << " (" << layout
      << ") / " << scale << " -> video " << ShapeToString(video_shape)
      << " (B, 3, F, H, W); VAE " << config << ", " << vae << "; wrote";
    for (const std::string& out : outputs) s << " " << out;
    s << "; " << std::fixed << std::setprecision(2) << seconds << " s";
    return s.str();
  }
};

// The VAE preset vae-decode uses: --config, else the latents' "config"
// metadata, else tiny. A --config naming another VAE than the metadata's is
// an error (the latents would decode to noise).
std::string DecodeConfigName(const VaeDecodeOptions& o,
                             const std::map<std::string, std::string>& meta) {
  const auto it = meta.find("config");
  if (it == meta.end()) return o.config.empty() ? "tiny" : o.config;
  std::string from_meta;
  try {
    from_meta = VaeConfigFor(it->second).name;
  } catch (const InputError& e) {
    ThrowInputError(o.latents, "metadata config '", it->second,
                    "' names no VAE preset (", e.what(), "); give --config");
  }
  if (o.config.empty()) return it->second;
  const std::string given = VaeConfigFor(o.config).name;
  GEODRIVE_CHECK_INPUT(given == from_meta, o.latents, ": latents of the ",
                       from_meta, " VAE (metadata config '", it->second,
                       "'), but --config ", o.config, " is the ", given,
                       " VAE");
  return o.config;
}

// `dir` for --out-frames: created, and holding no frames of an earlier run
// (they would mix with these).
void PrepareFrameFolder(const std::string& dir) {
  CreateOutputDirectory(dir);
  for (const auto& entry : fs::directory_iterator(dir)) {
    GEODRIVE_CHECK_INPUT(
        !(entry.is_regular_file() && IsImageFile(entry.path().string())), dir,
        ": already holds image files (", entry.path().filename().string(),
        "); frames of another run would mix with these: give an empty or new "
        "folder");
  }
}

// [3, F, H, W] in about [-1, 1] -> 16-bit RGB PNGs dir/00000.png, ...:
// round((clamp(x, -1, 1) + 1) * 65535 / 2), computed in double so the only
// error is the rounding (at most 1/65535 in [-1, 1] units).
std::vector<std::string> WriteFrames16(const at::Tensor& video,
                                       const std::string& dir) {
  const at::Tensor q =
      ((video.to(at::kDouble).clamp(-1.0, 1.0) + 1.0) * kHalf16)
          .round()
          .to(at::kInt)
          .permute({1, 2, 3, 0})  // [F, H, W, 3]
          .contiguous();
  const int h = static_cast<int>(q.size(1)), w = static_cast<int>(q.size(2));
  std::vector<std::string> paths;
  for (int64_t f = 0; f < q.size(0); ++f) {
    const at::Tensor frame = q[f].contiguous();
    const cv::Mat as_int(h, w, CV_32SC3, frame.data_ptr<int>());
    cv::Mat rgb16;
    as_int.convertTo(rgb16, CV_16U);  // exact: values are in [0, 65535]
    char name[32];
    std::snprintf(name, sizeof(name), "%05lld.png", static_cast<long long>(f));
    paths.push_back((fs::path(dir) / name).string());
    WriteImageRgb(paths.back(), rgb16);
  }
  return paths;
}

// [3, F, H, W] -> RGB uint8 frames, as `generate` writes its MP4.
std::vector<cv::Mat> Frames8(const at::Tensor& video) {
  const at::Tensor u8 = ((video.clamp(-1.0, 1.0) + 1.0) * 127.5)
                            .round()
                            .to(at::kByte)
                            .permute({1, 2, 3, 0})
                            .contiguous();
  std::vector<cv::Mat> out;
  for (int64_t f = 0; f < u8.size(0); ++f) {
    const at::Tensor frame = u8[f].contiguous();
    out.push_back(cv::Mat(static_cast<int>(frame.size(0)),
                          static_cast<int>(frame.size(1)), CV_8UC3,
                          frame.data_ptr<uint8_t>())
                      .clone());
  }
  return out;
}

VaeDecodeResult RunVaeDecode(const VaeDecodeOptions& o) {
  o.Check();
  const auto start = std::chrono::steady_clock::now();
  VaeDecodeResult r;
  r.latents = o.latents;
  const SafetensorsFile file(o.latents);
  at::Tensor z = LoadNamedOrOnly(file, "latents");
  GEODRIVE_CHECK_INPUT(at::isFloatingType(z.scalar_type()), o.latents,
                       ": the latents must be a float tensor, got ",
                       z.scalar_type());
  const auto& meta = file.metadata();
  r.layout = o.layout;
  if (r.layout == "auto") {
    const auto it = meta.find(kLayoutKey);
    r.layout = it != meta.end() ? it->second : kLatentLayoutBFCHW;
    GEODRIVE_CHECK_INPUT(
        r.layout == kLatentLayoutBFCHW || r.layout == kLayoutBCFHW, o.latents,
        ": metadata layout '", r.layout, "' is not BFCHW or BCFHW");
  }
  r.config = DecodeConfigName(o, meta);
  const VaeConfig c = VaeConfigFor(r.config);
  const int channel_dim = r.layout == kLatentLayoutBFCHW ? 2 : 1;
  GEODRIVE_CHECK_INPUT(z.dim() == 5 && z.size(channel_dim) == c.latent_channels,
                       o.latents, ": latents ", ShapeToString(z.sizes().vec()),
                       " are not ", r.layout, " with C = ", c.latent_channels,
                       " (the ", c.name, " VAE's latent channels)");
  GEODRIVE_CHECK_INPUT(z.numel() > 0, o.latents, ": empty latents ",
                       ShapeToString(z.sizes().vec()));
  z = z.to(at::kFloat);
  CheckFinite(z, o.latents);
  r.latents_shape = z.sizes().vec();
  // The factor the latents carry: the metadata's, else the config's.
  const auto scale_it = meta.find(kScaleKey);
  if (scale_it != meta.end()) {
    char* end = nullptr;
    r.scale = std::strtod(scale_it->second.c_str(), &end);
    GEODRIVE_CHECK_INPUT(end != scale_it->second.c_str() && *end == '\0' &&
                             std::isfinite(r.scale) && r.scale > 0,
                         o.latents, ": metadata scaling_factor '",
                         scale_it->second, "' is not a positive number");
    GEODRIVE_CHECK_INPUT(!o.no_scale || r.scale == 1.0, o.latents,
                         ": --no-scale, but the metadata says the latents "
                         "are scaled by ",
                         scale_it->second);
  } else {
    r.scale = o.no_scale ? 1.0 : c.scaling_factor;
  }
  if (!o.out_frames.empty() || !o.out_video.empty()) {
    GEODRIVE_CHECK_INPUT(z.size(0) == 1, o.latents, ": batch of ", z.size(0),
                         "; --out-frames and --out-video write one video "
                         "(use --out-tensor)");
  }
  if (!o.out_frames.empty()) PrepareFrameFolder(o.out_frames);
  for (const std::string& out : {o.out_tensor, o.out_video}) {
    if (!out.empty())
      CreateOutputDirectory(fs::absolute(out).parent_path().string());
  }
  const Weights w =
      LoadVae(c, r.config, o.vae_weights, o.seed, o.runtime, &r.vae);
  at::Tensor video;
  {
    at::NoGradGuard no_grad;
    at::Tensor unscaled = z / r.scale;
    if (r.layout == kLatentLayoutBFCHW)
      unscaled = unscaled.permute({0, 2, 1, 3, 4});
    video = VaeDecode(c, w, unscaled.contiguous()).to(at::kCPU, at::kFloat);
  }
  r.video_shape = video.sizes().vec();
  if (!o.out_tensor.empty()) {
    SaveSafetensors(o.out_tensor, {{"video", video}},
                    {{kFormatKey, kVideoFormat},
                     {kLayoutKey, kLayoutBCFHW},
                     {"range", "unclamped (about [-1, 1])"},
                     {"config", r.config},
                     {"vae", r.vae},
                     {"source", o.latents},
                     {"latents_divided_by", FormatDouble(r.scale)}});
    r.outputs.push_back(o.out_tensor);
  }
  if (!o.out_frames.empty()) {
    const auto paths = WriteFrames16(video[0], o.out_frames);
    r.outputs.push_back(o.out_frames + "/ (" + std::to_string(paths.size()) +
                        " 16-bit PNGs)");
  }
  if (!o.out_video.empty()) {
    VideoWriteOptions vo;
    vo.fps = o.fps;
    const VideoWriteResult vw = WriteVideo(o.out_video, Frames8(video[0]), vo);
    r.outputs.push_back(o.out_video + " (" + vw.fourcc +
                        (vw.fell_back ? ", fallback" : "") + ")");
  }
  r.seconds = SecondsSince(start);
  return r;
}

// ---- Command line ----

const char kConfigHelp[] =
    "VAE preset: tiny, cogvideox-5b-i2v, or a DiT config preset (tiny-49) "
    "for the VAE it pairs with";
const char kWeightsHelp[] =
    "VAE checkpoint (diffusers vae/diffusion_pytorch_model.safetensors, or "
    "an index). Default with a tiny preset: random weights from --seed "
    "(tests only)";

CommandRunner SetupVaeEncode(CLI::App& cmd) {
  auto o = std::make_shared<VaeEncodeOptions>();
  cmd.footer(
      "Encodes a video with CogVideoX's 3D causal VAE (diffusers' frame "
      "batching) and writes the\nlatent mean x scaling_factor (0.7) as "
      "'latents' [B, F', C, H/8, W/8] float32, the layout\n`sample --latents` "
      "reads and `generate` keeps; the __metadata__ states layout, "
      "scaling_factor,\nconfig, VAE and source. The video needs 1 + 4k frames "
      "(F' = 1 + k) and a width and height\nthat are multiples of 8. Pixels "
      "map to [-1, 1]: x / 127.5 - 1 (8-bit), x / 32767.5 - 1 (16-bit\nPNG). "
      "Exit codes: 0 ok, 2 bad arguments or input.");
  cmd.add_option("--config", o->config, kConfigHelp)->capture_default_str();
  cmd.add_option("--vae-weights", o->vae_weights, kWeightsHelp);
  cmd.add_option("--seed", o->seed, "seed of the random tiny weights")
      ->capture_default_str();
  cmd.add_option("--video", o->video, "input video file (8-bit RGB frames)");
  cmd.add_option("--frames", o->frames,
                 "input folder of PNG/JPG frames, sorted by name (16-bit PNGs "
                 "keep 16 bits)");
  cmd.add_option("--tensor", o->tensor,
                 "input safetensors: 'video' (or its only tensor) [B, 3, F, "
                 "H, W] in [-1, 1]");
  cmd.add_option("--out", o->out, "output latents.safetensors")->required();
  cmd.add_flag("--no-scale", o->no_scale,
               "store the latent mean without the scaling_factor");
  auto runtime = std::make_shared<RuntimeArgs>();
  AddRuntimeOptions(cmd, runtime.get(), kRuntimeVae | kRuntimeNoDitDtype);
  return [o, runtime] {
    o->runtime = runtime->Parse();
    std::cout << RunVaeEncode(*o).BriefReport() << std::endl;
    return kExitOk;
  };
}

CommandRunner SetupVaeDecode(CLI::App& cmd) {
  auto o = std::make_shared<VaeDecodeOptions>();
  cmd.footer(
      "Decodes latents with CogVideoX's 3D causal VAE (diffusers' frame "
      "batching): F' latent frames\ngive 1 + 4(F' - 1) frames (4F' for an "
      "even F'), 8x the latent height and width. Reads\n'latents' as "
      "vae-encode, `sample` and `generate` write them ([B, F', C, h, w], x "
      "scaling_factor);\n--layout BCFHW and --no-scale take diffusers' "
      "unscaled [B, C, F', h, w]. --out-tensor keeps\nthe decoder's float32 "
      "output unclamped (for comparison with a reference implementation);\n"
      "--out-frames writes 16-bit PNGs, round((clamp(x, -1, 1) + 1) * "
      "32767.5); --out-video an 8-bit MP4.\nExit codes: 0 ok, 2 bad arguments "
      "or input.");
  cmd.add_option("--config", o->config,
                 std::string(kConfigHelp) +
                     "; default: the latents' config metadata (vae-encode, "
                     "sample and generate write it), else tiny");
  cmd.add_option("--vae-weights", o->vae_weights, kWeightsHelp);
  cmd.add_option("--seed", o->seed, "seed of the random tiny weights")
      ->capture_default_str();
  cmd.add_option("--latents", o->latents,
                 "input safetensors: 'latents' (or its only tensor)")
      ->required();
  cmd.add_option("--layout", o->layout,
                 "auto (the file's metadata, else BFCHW), BFCHW or BCFHW")
      ->capture_default_str();
  cmd.add_flag("--no-scale", o->no_scale,
               "the latents are not multiplied by scaling_factor (an error "
               "when the file's metadata states another factor)");
  cmd.add_option("--out-tensor", o->out_tensor,
                 "output safetensors: 'video' [B, 3, F, H, W] float32, "
                 "unclamped");
  cmd.add_option("--out-frames", o->out_frames,
                 "output folder of 16-bit RGB PNGs 00000.png, ... (batch 1)");
  cmd.add_option("--out-video", o->out_video,
                 "output 8-bit MP4, as generate writes (batch 1)");
  cmd.add_option("--fps", o->fps, "--out-video frame rate")
      ->capture_default_str();
  auto runtime = std::make_shared<RuntimeArgs>();
  AddRuntimeOptions(cmd, runtime.get(), kRuntimeVae | kRuntimeNoDitDtype);
  return [o, runtime] {
    o->runtime = runtime->Parse();
    std::cout << RunVaeDecode(*o).BriefReport() << std::endl;
    return kExitOk;
  };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(vae_encode,
                          "vae-encode",
                          "VAE-encode a video (file, PNG frames or tensor) to "
                          "latents.safetensors",
                          SetupVaeEncode);
GEODRIVE_REGISTER_COMMAND(vae_decode,
                          "vae-decode",
                          "VAE-decode latents to a float32 tensor, 16-bit PNG "
                          "frames and/or an MP4",
                          SetupVaeDecode);

}  // namespace diffusion
}  // namespace geodrive

#include "diffusion/vae.h"

#include <ATen/ATen.h>

#include <string>
#include <unordered_map>

#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace diffusion {

namespace {

// Causal-conv caches by conv name (diffusers' nested conv_cache dicts): the
// last kernel_t - 1 time-padded input frames of the previous frame batch.
using ConvCache = std::unordered_map<std::string, at::Tensor>;

// CogVideoXCausalConv3d (pad_mode "first"): time padded on the left with the
// cached frames of the previous batch, else the first frame repeated
// kernel_t - 1 times; zero spatial padding of (kernel - 1) / 2; stride 1.
at::Tensor CausalConv(const Weights& w,
                      const std::string& name,
                      const at::Tensor& x,
                      ConvCache* cache) {
  const at::Tensor& weight = w.Get(name + ".conv.weight");
  const int64_t kt = weight.size(2);
  const int64_t ph = (weight.size(3) - 1) / 2, pw = (weight.size(4) - 1) / 2;
  at::Tensor in = x;
  if (kt > 1) {
    auto it = cache->find(name);
    at::Tensor pad = it != cache->end()
                         ? it->second
                         : x.narrow(2, 0, 1).repeat({1, 1, kt - 1, 1, 1});
    in = at::cat({pad, x}, 2);
    (*cache)[name] = in.narrow(2, in.size(2) - (kt - 1), kt - 1).clone();
  }
  if (ph > 0 || pw > 0) in = at::constant_pad_nd(in, {pw, pw, ph, ph}, 0);
  return at::conv3d(in, weight, w.Get(name + ".conv.bias"));
}

at::Tensor GroupNorm(const VaeConfig& c,
                     const Weights& w,
                     const std::string& name,
                     const at::Tensor& x) {
  return at::group_norm(x, c.norm_num_groups, w.Get(name + ".weight"),
                        w.Get(name + ".bias"), c.norm_eps);
}

// CogVideoXSpatialNorm3D: GroupNorm(f) * conv_y(zq) + conv_b(zq), zq
// nearest-resized to f's (T, H, W); for an odd frame count > 1 the first frame
// and the rest are resized separately.
at::Tensor SpatialNorm(const VaeConfig& c,
                       const Weights& w,
                       const std::string& name,
                       const at::Tensor& f,
                       const at::Tensor& zq,
                       ConvCache* cache) {
  const int64_t t = f.size(2), h = f.size(3), wd = f.size(4);
  at::Tensor z;
  if (t > 1 && t % 2 == 1) {
    at::Tensor first = at::upsample_nearest3d(zq.narrow(2, 0, 1), {1, h, wd});
    at::Tensor rest =
        at::upsample_nearest3d(zq.narrow(2, 1, zq.size(2) - 1), {t - 1, h, wd});
    z = at::cat({first, rest}, 2);
  } else {
    z = at::upsample_nearest3d(zq, {t, h, wd});
  }
  at::Tensor y = CausalConv(w, name + ".conv_y", z, cache);
  at::Tensor b = CausalConv(w, name + ".conv_b", z, cache);
  // GroupNorm eps is fixed at 1e-6 in CogVideoXSpatialNorm3D.
  at::Tensor n =
      at::group_norm(f, c.norm_num_groups, w.Get(name + ".norm_layer.weight"),
                     w.Get(name + ".norm_layer.bias"), 1e-6);
  return n * y + b;
}

// CogVideoXResnetBlock3D without time embedding (dropout 0). `zq` defined:
// spatial norms (decoder).
at::Tensor Resnet(const VaeConfig& c,
                  const Weights& w,
                  const std::string& name,
                  const at::Tensor& x,
                  const at::Tensor& zq,
                  ConvCache* cache) {
  auto norm = [&](const std::string& n, const at::Tensor& v) {
    return zq.defined() ? SpatialNorm(c, w, name + n, v, zq, cache)
                        : GroupNorm(c, w, name + n, v);
  };
  at::Tensor h = at::silu(norm(".norm1", x));
  h = CausalConv(w, name + ".conv1", h, cache);
  h = at::silu(norm(".norm2", h));
  h = CausalConv(w, name + ".conv2", h, cache);
  at::Tensor shortcut = x;
  if (w.Has(name + ".conv_shortcut.weight")) {
    shortcut = at::conv3d(x, w.Get(name + ".conv_shortcut.weight"),
                          w.Get(name + ".conv_shortcut.bias"));
  }
  return h + shortcut;
}

// Applies a Conv2d to every frame of [B, C, T, H, W].
at::Tensor FrameConv2d(const Weights& w,
                       const std::string& name,
                       const at::Tensor& x,
                       int64_t stride,
                       int64_t padding) {
  const int64_t b = x.size(0), c = x.size(1), t = x.size(2);
  at::Tensor f =
      x.permute({0, 2, 1, 3, 4}).reshape({b * t, c, x.size(3), x.size(4)});
  f = at::conv2d(f, w.Get(name + ".weight"), w.Get(name + ".bias"), {stride},
                 {padding});
  return f.reshape({b, t, f.size(1), f.size(2), f.size(3)})
      .permute({0, 2, 1, 3, 4});
}

// CogVideoXDownsample3D: optional time halving (odd count: first frame kept,
// the rest averaged in pairs), zero pad right/bottom by 1, Conv2d 3x3 stride 2.
at::Tensor Downsample(const Weights& w,
                      const std::string& name,
                      at::Tensor x,
                      bool compress_time) {
  if (compress_time) {
    auto pairs = [](const at::Tensor& v) {
      const auto s = v.sizes();
      return v.reshape({s[0], s[1], s[2] / 2, 2, s[3], s[4]}).mean(3);
    };
    const int64_t t = x.size(2);
    if (t % 2 == 1) {
      at::Tensor first = x.narrow(2, 0, 1);
      x = t > 1 ? at::cat({first, pairs(x.narrow(2, 1, t - 1))}, 2) : first;
    } else {
      x = pairs(x);
    }
  }
  x = at::constant_pad_nd(x, {0, 1, 0, 1}, 0);
  return FrameConv2d(w, name + ".conv", x, 2, 0);
}

// CogVideoXUpsample3D: nearest x2 in space (and in time when compress_time: an
// odd count > 1 keeps the first frame once), then Conv2d 3x3 padding 1.
at::Tensor Upsample(const Weights& w,
                    const std::string& name,
                    const at::Tensor& x,
                    bool compress_time) {
  const int64_t t = x.size(2), h = 2 * x.size(3), wd = 2 * x.size(4);
  at::Tensor u;
  if (compress_time && t > 1 && t % 2 == 1) {
    at::Tensor first = at::upsample_nearest3d(x.narrow(2, 0, 1), {1, h, wd});
    at::Tensor rest =
        at::upsample_nearest3d(x.narrow(2, 1, t - 1), {2 * (t - 1), h, wd});
    u = at::cat({first, rest}, 2);
  } else if (compress_time && t > 1) {
    u = at::upsample_nearest3d(x, {2 * t, h, wd});
  } else {
    u = at::upsample_nearest3d(x, {t, h, wd});
  }
  return FrameConv2d(w, name + ".conv", u, 1, 1);
}

// CogVideoXEncoder3D on one frame batch: [B, 3, T, H, W] -> [B, 2 C_lat, T',
// H/8, W/8] (mean, logvar).
at::Tensor Encoder(const VaeConfig& c,
                   const Weights& w,
                   const at::Tensor& x,
                   ConvCache* cache) {
  const int nb = static_cast<int>(c.block_out_channels.size());
  const at::Tensor none;
  at::Tensor h = CausalConv(w, "encoder.conv_in", x, cache);
  for (int i = 0; i < nb; ++i) {
    const std::string b = "encoder.down_blocks." + std::to_string(i);
    for (int j = 0; j < c.layers_per_block; ++j) {
      h = Resnet(c, w, b + ".resnets." + std::to_string(j), h, none, cache);
    }
    if (i != nb - 1) {
      h = Downsample(w, b + ".downsamplers.0", h, i < c.TimeCompressBlocks());
    }
  }
  for (int j = 0; j < 2; ++j) {
    h = Resnet(c, w, "encoder.mid_block.resnets." + std::to_string(j), h, none,
               cache);
  }
  h = at::silu(GroupNorm(c, w, "encoder.norm_out", h));
  return CausalConv(w, "encoder.conv_out", h, cache);
}

// CogVideoXDecoder3D on one latent batch: [B, C_lat, T, h, w] -> [B, 3, T'',
// 8h, 8w].
at::Tensor Decoder(const VaeConfig& c,
                   const Weights& w,
                   const at::Tensor& z,
                   ConvCache* cache) {
  const int nb = static_cast<int>(c.block_out_channels.size());
  at::Tensor h = CausalConv(w, "decoder.conv_in", z, cache);
  for (int j = 0; j < 2; ++j) {
    h = Resnet(c, w, "decoder.mid_block.resnets." + std::to_string(j), h, z,
               cache);
  }
  for (int i = 0; i < nb; ++i) {
    const std::string b = "decoder.up_blocks." + std::to_string(i);
    for (int j = 0; j < c.layers_per_block + 1; ++j) {
      h = Resnet(c, w, b + ".resnets." + std::to_string(j), h, z, cache);
    }
    if (i != nb - 1) {
      h = Upsample(w, b + ".upsamplers.0", h, i < c.TimeCompressBlocks());
    }
  }
  h = at::silu(SpatialNorm(c, w, "decoder.norm_out", h, z, cache));
  return CausalConv(w, "decoder.conv_out", h, cache);
}

std::vector<std::pair<int64_t, int64_t>> Batches(bool batching,
                                                 int64_t frames,
                                                 int64_t batch) {
  if (!batching) return {{0, frames}};
  return VaeFrameBatches(frames, batch);
}

}  // namespace

void VaeOptions::Check() const {}

namespace {

// Device and dtype of the VAE's weights (all alike).
at::TensorOptions WeightOptions(const Weights& w) {
  TORCH_CHECK(!w.order.empty(), "VAE weights are empty");
  return w.Get(w.order.front()).options();
}

}  // namespace

Weights VaeInitWeights(const VaeConfig& config, uint64_t seed) {
  Weights w = InitWeights(VaeParamSpecs(config), seed);
  for (const std::string& name : w.order) {
    const at::Tensor& t = w.Get(name);
    if (t.dim() != 1) continue;
    std::string module = name.substr(0, name.rfind('.'));
    bool group_norm = false;
    for (const char* n : {".norm1", ".norm2", ".norm_out", ".norm_layer"}) {
      group_norm |= EndsWith(module, n);
    }
    if (!group_norm) continue;
    w.Set(name,
          EndsWith(name, ".weight") ? at::ones_like(t) : at::zeros_like(t));
  }
  return w;
}

at::Tensor VaeEncodeMoments(const VaeConfig& config,
                            const Weights& w,
                            const at::Tensor& video,
                            at::Tensor* logvar,
                            const VaeOptions& options) {
  config.Check();
  options.Check();
  const int64_t sc = config.spatial_compression;
  GEODRIVE_CHECK_INPUT(video.dim() == 5 && video.size(1) == config.in_channels,
                       "VAE encode: video must be [B, ", config.in_channels,
                       ", F, H, W], got ", video.sizes());
  const int64_t frames = video.size(2);
  GEODRIVE_CHECK_INPUT(
      frames >= 1 && (frames - 1) % config.temporal_compression == 0,
      "VAE encode: frame count ", frames, " is not 1 + ",
      config.temporal_compression, "k");
  GEODRIVE_CHECK_INPUT(video.size(3) % sc == 0 && video.size(4) % sc == 0 &&
                           video.size(3) > 0 && video.size(4) > 0,
                       "VAE encode: frame size ", video.size(3), "x",
                       video.size(4), " is not a multiple of ", sc);
  // Computed on the device and in the dtype of the weights.
  const at::Tensor x = video.to(WeightOptions(w));
  ConvCache cache;
  std::vector<at::Tensor> parts;
  for (const auto& [s, e] :
       Batches(options.frame_batching, frames, config.encode_frame_batch)) {
    parts.push_back(Encoder(config, w, x.narrow(2, s, e - s), &cache));
  }
  at::Tensor h = parts.size() == 1 ? parts[0] : at::cat(parts, 2);
  const int64_t lat = config.latent_channels;
  if (logvar != nullptr) *logvar = h.narrow(1, lat, lat).clamp(-30.0, 20.0);
  return h.narrow(1, 0, lat).contiguous();
}

at::Tensor VaeEncode(const VaeConfig& config,
                     const Weights& w,
                     const at::Tensor& video,
                     const VaeOptions& options) {
  return VaeEncodeMoments(config, w, video, nullptr, options);
}

at::Tensor VaeDecode(const VaeConfig& config,
                     const Weights& w,
                     const at::Tensor& latents,
                     const VaeOptions& options) {
  config.Check();
  options.Check();
  GEODRIVE_CHECK_INPUT(
      latents.dim() == 5 && latents.size(1) == config.latent_channels &&
          latents.size(2) >= 1 && latents.size(3) >= 1 && latents.size(4) >= 1,
      "VAE decode: latents must be [B, ", config.latent_channels,
      ", F, h, w], got ", latents.sizes());
  const at::Tensor z = latents.to(WeightOptions(w));
  ConvCache cache;
  std::vector<at::Tensor> parts;
  for (const auto& [s, e] :
       Batches(options.frame_batching, z.size(2), config.decode_frame_batch)) {
    parts.push_back(Decoder(config, w, z.narrow(2, s, e - s), &cache));
  }
  return parts.size() == 1 ? parts[0] : at::cat(parts, 2);
}

}  // namespace diffusion
}  // namespace geodrive

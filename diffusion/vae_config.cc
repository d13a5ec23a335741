#include "diffusion/vae_config.h"

#include <algorithm>

#include "geometry/util/status.h"

namespace geodrive {
namespace diffusion {

namespace {

// Frames after one time-compressing down block (diffusers
// CogVideoXDownsample3D): an odd count keeps the first frame and averages the
// rest in pairs.
int64_t HalveTime(int64_t t) { return t % 2 == 1 ? 1 + (t - 1) / 2 : t / 2; }

// Frames after one time-upsampling up block (CogVideoXUpsample3D): an odd count
// > 1 keeps the first frame once and doubles the rest; 1 stays 1.
int64_t DoubleTime(int64_t t) {
  if (t == 1) return 1;
  return t % 2 == 1 ? 1 + 2 * (t - 1) : 2 * t;
}

void AddConv(std::vector<ParamSpec>* out,
             const std::string& name,
             int64_t cout,
             int64_t cin,
             std::vector<int64_t> kernel) {
  std::vector<int64_t> shape = {cout, cin};
  shape.insert(shape.end(), kernel.begin(), kernel.end());
  out->push_back({name + ".weight", shape});
  out->push_back({name + ".bias", {cout}});
}

void AddGroupNorm(std::vector<ParamSpec>* out,
                  const std::string& name,
                  int64_t c) {
  out->push_back({name + ".weight", {c}});
  out->push_back({name + ".bias", {c}});
}

// CogVideoXSpatialNorm3D: norm_layer, conv_y, conv_b (registration order).
void AddSpatialNorm(std::vector<ParamSpec>* out,
                    const std::string& name,
                    int64_t c,
                    int64_t zc) {
  AddGroupNorm(out, name + ".norm_layer", c);
  AddConv(out, name + ".conv_y.conv", c, zc, {1, 1, 1});
  AddConv(out, name + ".conv_b.conv", c, zc, {1, 1, 1});
}

// CogVideoXResnetBlock3D (temb_channels 0): norm1, norm2, conv1, conv2,
// conv_shortcut (plain 1x1x1 Conv3d) when the channel count changes.
// `zc` > 0: spatial norms conditioned on zc latent channels (decoder).
void AddResnet(std::vector<ParamSpec>* out,
               const std::string& name,
               int64_t cin,
               int64_t cout,
               int64_t zc) {
  if (zc > 0) {
    AddSpatialNorm(out, name + ".norm1", cin, zc);
    AddSpatialNorm(out, name + ".norm2", cout, zc);
  } else {
    AddGroupNorm(out, name + ".norm1", cin);
    AddGroupNorm(out, name + ".norm2", cout);
  }
  AddConv(out, name + ".conv1.conv", cout, cin, {3, 3, 3});
  AddConv(out, name + ".conv2.conv", cout, cout, {3, 3, 3});
  if (cin != cout) AddConv(out, name + ".conv_shortcut", cout, cin, {1, 1, 1});
}

}  // namespace

std::vector<std::pair<int64_t, int64_t>> VaeFrameBatches(int64_t frames,
                                                         int64_t batch) {
  std::vector<std::pair<int64_t, int64_t>> out;
  const int64_t n = std::max<int64_t>(frames / batch, 1);
  const int64_t rem = frames % batch;
  for (int64_t i = 0; i < n; ++i) {
    const int64_t start = batch * i + (i == 0 ? 0 : rem);
    const int64_t end = std::min(frames, batch * (i + 1) + rem);
    out.emplace_back(start, end);
  }
  return out;
}

int VaeConfig::TimeCompressBlocks() const {
  int n = 0;
  while ((1 << n) < temporal_compression) ++n;
  return n;
}

int64_t VaeConfig::LatentFrames(int64_t frames) const {
  int64_t total = 0;
  for (const auto& [start, end] : VaeFrameBatches(frames, encode_frame_batch)) {
    int64_t t = end - start;
    for (int i = 0; i < TimeCompressBlocks(); ++i) t = HalveTime(t);
    total += t;
  }
  return total;
}

int64_t VaeConfig::PixelFrames(int64_t latent_frames) const {
  int64_t total = 0;
  for (const auto& [start, end] :
       VaeFrameBatches(latent_frames, decode_frame_batch)) {
    int64_t t = end - start;
    for (int i = 0; i < TimeCompressBlocks(); ++i) t = DoubleTime(t);
    total += t;
  }
  return total;
}

void VaeConfig::Check() const {
  const std::string what = "VAE config '" + name + "'";
  GEODRIVE_CHECK_INPUT(in_channels >= 1 && latent_channels >= 1, what,
                       ": in_channels and latent_channels must be >= 1");
  GEODRIVE_CHECK_INPUT(block_out_channels.size() >= 1, what,
                       ": block_out_channels is empty");
  GEODRIVE_CHECK_INPUT(layers_per_block >= 1 && norm_num_groups >= 1, what,
                       ": layers_per_block and norm_num_groups must be >= 1");
  for (int c : block_out_channels) {
    GEODRIVE_CHECK_INPUT(
        c >= 1 && c % norm_num_groups == 0, what, ": block channel count ", c,
        " is not a positive multiple of norm_num_groups ", norm_num_groups);
  }
  GEODRIVE_CHECK_INPUT(
      spatial_compression == (1 << (block_out_channels.size() - 1)), what,
      ": spatial_compression ", spatial_compression, " must be 2^(blocks - 1)");
  GEODRIVE_CHECK_INPUT(
      temporal_compression >= 1 &&
          (1 << TimeCompressBlocks()) == temporal_compression &&
          TimeCompressBlocks() <=
              static_cast<int>(block_out_channels.size()) - 1,
      what, ": temporal_compression ", temporal_compression,
      " must be a power of two <= spatial_compression");
  GEODRIVE_CHECK_INPUT(norm_eps > 0 && scaling_factor > 0, what,
                       ": norm_eps and scaling_factor must be positive");
  GEODRIVE_CHECK_INPUT(encode_frame_batch >= 1 && decode_frame_batch >= 1, what,
                       ": frame batch sizes must be >= 1");
}

VaeConfig VaePreset(const std::string& name) {
  VaeConfig c;
  if (name == "tiny") {
    c.name = "tiny";  // defaults: 4 latent channels, channels 8/16/16/16
    return c;
  }
  if (name == "cogvideox-5b-i2v") {
    // THUDM/CogVideoX-5b-I2V vae/config.json (AutoencoderKLCogVideoX).
    c.name = name;
    c.in_channels = 3;
    c.latent_channels = 16;
    c.block_out_channels = {128, 256, 256, 512};
    c.layers_per_block = 3;
    c.norm_num_groups = 32;
    c.norm_eps = 1e-6;
    c.scaling_factor = 0.7;
    c.temporal_compression = 4;
    c.spatial_compression = 8;
    return c;
  }
  const std::vector<std::string> configs = ConfigPresetNames();
  if (std::find(configs.begin(), configs.end(), name) != configs.end()) {
    return VaePreset(VaePresetNameForConfig(name));
  }
  std::string known;
  for (const std::string& n : VaePresetNames()) known += " " + n;
  std::string known_configs;
  for (const std::string& n : configs) known_configs += " " + n;
  ThrowInputError(name, "unknown VAE preset (VAE presets:", known,
                  "; DiT config presets:", known_configs, ")");
}

std::vector<std::string> VaePresetNames() {
  return {"tiny", "cogvideox-5b-i2v"};
}

std::string VaePresetNameForConfig(const std::string& config) {
  // Every tiny DiT preset has 4 latent channels and 8x spatial / 4x temporal
  // compression: they share the tiny VAE.
  const DiTConfig c = ConfigPreset(config);  // InputError naming --config
  if (c.name == "cogvideox-5b-i2v") return "cogvideox-5b-i2v";
  if (c.name.rfind("tiny", 0) == 0) return "tiny";
  ThrowInputError("--config", "preset '", config, "' has no VAE preset");
}

std::vector<ParamSpec> VaeParamSpecs(const VaeConfig& c) {
  c.Check();
  std::vector<ParamSpec> out;
  const auto& ch = c.block_out_channels;
  const int nb = static_cast<int>(ch.size());
  const int64_t lat = c.latent_channels;
  // Encoder.
  AddConv(&out, "encoder.conv_in.conv", ch[0], c.in_channels, {3, 3, 3});
  int64_t prev = ch[0];
  for (int i = 0; i < nb; ++i) {
    const std::string b = "encoder.down_blocks." + std::to_string(i);
    for (int j = 0; j < c.layers_per_block; ++j) {
      AddResnet(&out, b + ".resnets." + std::to_string(j),
                j == 0 ? prev : ch[i], ch[i], 0);
    }
    if (i != nb - 1)
      AddConv(&out, b + ".downsamplers.0.conv", ch[i], ch[i], {3, 3});
    prev = ch[i];
  }
  for (int j = 0; j < 2; ++j) {
    AddResnet(&out, "encoder.mid_block.resnets." + std::to_string(j),
              ch[nb - 1], ch[nb - 1], 0);
  }
  AddGroupNorm(&out, "encoder.norm_out", ch[nb - 1]);
  AddConv(&out, "encoder.conv_out.conv", 2 * lat, ch[nb - 1], {3, 3, 3});
  // Decoder (reversed channels, spatial norms on the latent).
  AddConv(&out, "decoder.conv_in.conv", ch[nb - 1], lat, {3, 3, 3});
  for (int j = 0; j < 2; ++j) {
    AddResnet(&out, "decoder.mid_block.resnets." + std::to_string(j),
              ch[nb - 1], ch[nb - 1], lat);
  }
  prev = ch[nb - 1];
  for (int i = 0; i < nb; ++i) {
    const int64_t oc = ch[nb - 1 - i];
    const std::string b = "decoder.up_blocks." + std::to_string(i);
    for (int j = 0; j < c.layers_per_block + 1; ++j) {
      AddResnet(&out, b + ".resnets." + std::to_string(j), j == 0 ? prev : oc,
                oc, lat);
    }
    if (i != nb - 1) AddConv(&out, b + ".upsamplers.0.conv", oc, oc, {3, 3});
    prev = oc;
  }
  AddSpatialNorm(&out, "decoder.norm_out", ch[0], lat);
  AddConv(&out, "decoder.conv_out.conv", c.in_channels, ch[0], {3, 3, 3});
  return out;
}

}  // namespace diffusion
}  // namespace geodrive

#include "diffusion/config.h"

#include <algorithm>
#include <map>
#include <sstream>

#include "geometry/util/status.h"

namespace geodrive {
namespace diffusion {

void DiTConfig::Check() const {
  const std::string what = "diffusion config '" + name + "'";
  GEODRIVE_CHECK_INPUT(num_layers >= 1 && num_heads >= 1 && head_dim >= 1, what,
                       ": layers, heads and head_dim must be positive");
  GEODRIVE_CHECK_INPUT(out_channels >= 1 && in_channels >= out_channels, what,
                       ": in_channels must be >= out_channels >= 1");
  GEODRIVE_CHECK_INPUT(patch_size >= 1 && latent_height % patch_size == 0 &&
                           latent_width % patch_size == 0,
                       what, ": latent size ", latent_height, "x", latent_width,
                       " is not divisible by patch ", patch_size);
  GEODRIVE_CHECK_INPUT(
      latent_frames >= 1 && text_seq_len >= 1 && text_embed_dim >= 1 &&
          time_embed_dim >= 1 && ff_mult >= 1,
      what,
      ": frames, text length/dim, time_embed_dim and ff_mult must be >= 1");
  GEODRIVE_CHECK_INPUT(inner_dim() % 2 == 0, what,
                       ": inner dim must be even (time embedding)");
  GEODRIVE_CHECK_INPUT(!use_rotary || head_dim % 16 == 0, what,
                       ": 3D RoPE needs head_dim divisible by 16, got ",
                       head_dim);
  GEODRIVE_CHECK_INPUT(branch_layers >= 1 && branch_layers <= num_layers, what,
                       ": branch_layers must be in [1, num_layers]");
  GEODRIVE_CHECK_INPUT(branch_in_channels >= out_channels, what,
                       ": branch_in_channels must be >= out_channels");
  GEODRIVE_CHECK_INPUT(norm_eps > 0 && qk_norm_eps > 0, what,
                       ": eps must be positive");
}

DiTConfig ConfigPreset(const std::string& name) {
  DiTConfig c;
  if (name == "tiny") {
    c.name = "tiny";  // defaults above: 4 layers, 2 heads x 16, 4 latent
                      // channels, 3x4x6 latents
    return c;
  }
  if (name == "tiny-49") {
    // tiny with the real clip length: 49 pixel frames -> 13 latent frames
    // (training tests on padded 25 -> 49 frame pairs, as upstream).
    c.name = name;
    c.latent_frames = 13;
    return c;
  }
  if (name == "cogvideox-5b-i2v") {
    // THUDM/CogVideoX-5b-I2V transformer/config.json (reference notes §1.1) +
    // GeoDrive branch.
    c.name = name;
    c.num_layers = 42;
    c.num_heads = 48;
    c.head_dim = 64;
    c.in_channels = 32;
    c.out_channels = 16;
    c.patch_size = 2;
    c.time_embed_dim = 512;
    c.text_embed_dim = 4096;
    c.text_seq_len = 226;
    c.latent_frames = 13;  // 49 pixel frames, temporal compression 4
    c.latent_height = 60;
    c.latent_width = 90;
    c.ff_mult = 4;
    c.use_rotary = true;
    c.use_learned_pos = true;
    c.attention_bias = true;
    c.flip_sin_to_cos = true;
    c.freq_shift = 0;
    c.norm_eps = 1e-5;
    c.qk_norm_eps = 1e-6;
    c.branch_layers = 2;
    c.branch_in_channels = 32;
    c.conditioning_scale = 1.0;
    return c;
  }
  std::string known;
  for (const auto& n : ConfigPresetNames()) known += " " + n;
  ThrowInputError("--config", "unknown preset '", name, "' (known:", known,
                  ")");
}

std::vector<std::string> ConfigPresetNames() {
  return {"cogvideox-5b-i2v", "tiny", "tiny-49"};
}

int64_t NumElements(const std::vector<int64_t>& shape) {
  int64_t n = 1;
  for (int64_t d : shape) n *= d;
  return n;
}

int64_t NumElements(const std::vector<ParamSpec>& specs) {
  int64_t n = 0;
  for (const auto& s : specs) n += NumElements(s.shape);
  return n;
}

std::string ShapeToString(const std::vector<int64_t>& shape) {
  std::ostringstream os;
  os << "[";
  for (size_t i = 0; i < shape.size(); ++i) os << (i ? ", " : "") << shape[i];
  os << "]";
  return os.str();
}

namespace {

void AddLinear(std::vector<ParamSpec>* s,
               const std::string& name,
               int64_t out,
               int64_t in,
               bool bias = true) {
  s->push_back({name + ".weight", {out, in}});
  if (bias) s->push_back({name + ".bias", {out}});
}

void AddNorm(std::vector<ParamSpec>* s, const std::string& name, int64_t dim) {
  s->push_back({name + ".weight", {dim}});
  s->push_back({name + ".bias", {dim}});
}

std::vector<ParamSpec> TransformerSpecs(const DiTConfig& c,
                                        int layers,
                                        int in_channels) {
  const int64_t d = c.inner_dim();
  const int64_t p = c.patch_size;
  std::vector<ParamSpec> s;
  s.push_back({"patch_embed.proj.weight", {d, in_channels, p, p}});
  s.push_back({"patch_embed.proj.bias", {d}});
  AddLinear(&s, "patch_embed.text_proj", d, c.text_embed_dim);
  if (c.use_learned_pos)
    s.push_back({"patch_embed.pos_embedding", {1, c.seq_len(), d}});
  AddLinear(&s, "time_embedding.linear_1", c.time_embed_dim, d);
  AddLinear(&s, "time_embedding.linear_2", c.time_embed_dim, c.time_embed_dim);
  for (int i = 0; i < layers; ++i) {
    const std::string b = "transformer_blocks." + std::to_string(i) + ".";
    AddLinear(&s, b + "norm1.linear", 6 * d, c.time_embed_dim);
    AddNorm(&s, b + "norm1.norm", d);
    AddNorm(&s, b + "attn1.norm_q", c.head_dim);
    AddNorm(&s, b + "attn1.norm_k", c.head_dim);
    AddLinear(&s, b + "attn1.to_q", d, d, c.attention_bias);
    AddLinear(&s, b + "attn1.to_k", d, d, c.attention_bias);
    AddLinear(&s, b + "attn1.to_v", d, d, c.attention_bias);
    AddLinear(&s, b + "attn1.to_out.0", d, d);
    AddLinear(&s, b + "norm2.linear", 6 * d, c.time_embed_dim);
    AddNorm(&s, b + "norm2.norm", d);
    AddLinear(&s, b + "ff.net.0.proj", c.ff_mult * d, d);
    AddLinear(&s, b + "ff.net.2", d, c.ff_mult * d);
  }
  AddNorm(&s, "norm_final", d);
  AddLinear(&s, "norm_out.linear", 2 * d, c.time_embed_dim);
  AddNorm(&s, "norm_out.norm", d);
  AddLinear(&s, "proj_out", int64_t{p} * p * c.out_channels, d);
  return s;
}

}  // namespace

std::vector<ParamSpec> BackboneParamSpecs(const DiTConfig& config) {
  return TransformerSpecs(config, config.num_layers, config.in_channels);
}

std::vector<ParamSpec> BranchParamSpecs(const DiTConfig& config) {
  std::vector<ParamSpec> s =
      TransformerSpecs(config, config.branch_layers, config.branch_in_channels);
  const int64_t d = config.inner_dim();
  for (int k = 0; k < config.branch_layers; ++k) {
    AddLinear(&s, "branch_blocks." + std::to_string(k), d, d);
  }
  AddLinear(&s, "branch_x_embedder", d, config.branch_in_channels);
  return s;
}

bool IsUnusedBranchParam(const std::string& name) {
  for (const char* prefix :
       {"norm_final.", "norm_out.", "proj_out.", "branch_x_embedder."}) {
    if (name.rfind(prefix, 0) == 0) return true;
  }
  return false;
}

std::string LoadReport::BriefReport(size_t max_list) const {
  std::ostringstream os;
  os << source << ": " << matched << " tensors matched, " << missing.size()
     << " missing, " << unexpected.size() << " unexpected, "
     << mismatched.size() << " shape-mismatched";
  auto list = [&](const char* label, const std::vector<std::string>& names) {
    if (names.empty()) return;
    os << "\n  " << label << ":";
    for (size_t i = 0; i < names.size() && i < max_list; ++i)
      os << "\n    " << names[i];
    if (names.size() > max_list)
      os << "\n    ... (" << names.size() - max_list << " more)";
  };
  list("missing", missing);
  list("unexpected", unexpected);
  list("shape mismatch", mismatched);
  return os.str();
}

LoadReport CompareStateDict(const std::string& source,
                            const std::vector<ParamSpec>& expected,
                            const std::vector<ParamSpec>& file) {
  LoadReport r;
  r.source = source;
  std::map<std::string, const ParamSpec*> in_file;
  for (const auto& f : file) in_file[f.name] = &f;
  std::map<std::string, bool> wanted;
  for (const auto& e : expected) {
    wanted[e.name] = true;
    auto it = in_file.find(e.name);
    if (it == in_file.end()) {
      r.missing.push_back(e.name);
    } else if (it->second->shape != e.shape) {
      r.mismatched.push_back(e.name + ": file " +
                             ShapeToString(it->second->shape) + " vs model " +
                             ShapeToString(e.shape));
    } else {
      ++r.matched;
    }
  }
  for (const auto& f : file) {
    if (!wanted.count(f.name)) r.unexpected.push_back(f.name);
  }
  return r;
}

void CheckBranchLoadReport(const LoadReport& report) {
  for (const auto& name : report.missing) {
    if (!IsUnusedBranchParam(name)) {
      ThrowInputError(report.source, "encoder checkpoint lacks '", name, "' (",
                      report.missing.size(), " missing)");
    }
  }
  GEODRIVE_CHECK_INPUT(report.mismatched.empty(), report.source,
                       ": encoder shape mismatch: ",
                       report.mismatched.empty() ? "" : report.mismatched[0]);
}

}  // namespace diffusion
}  // namespace geodrive

#include "diffusion/model.h"

#include <ATen/ATen.h>
#include <ATen/CPUGeneratorImpl.h>
#include <c10/util/Exception.h>
#include <torch/version.h>

#include <algorithm>
#include <cmath>
#include <tuple>

#include "diffusion/runtime_torch.h"
#include "diffusion/safetensors.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace diffusion {

const at::Tensor& Weights::Get(const std::string& name) const {
  auto it = tensors.find(name);
  TORCH_CHECK(it != tensors.end(), "diffusion weights have no tensor '", name,
              "'");
  return it->second;
}

void Weights::Set(const std::string& name, at::Tensor t) {
  if (!tensors.count(name)) order.push_back(name);
  tensors[name] = std::move(t);
}

void Weights::SetRequiresGrad(bool requires_grad) {
  for (auto& [name, t] : tensors) t.set_requires_grad(requires_grad);
}

Weights Weights::Clone() const {
  Weights out;
  out.order = order;
  for (const auto& [name, t] : tensors) out.tensors[name] = t.detach().clone();
  return out;
}

Weights Weights::Subset(const std::string& prefix) const {
  Weights out;
  for (const auto& name : order) {
    if (name.compare(0, prefix.size(), prefix) == 0)
      out.Set(name, tensors.at(name));
  }
  return out;
}

Weights Weights::To(const at::TensorOptions& options) const {
  Weights out;
  out.order = order;
  for (const auto& [name, t] : tensors) {
    out.tensors[name] =
        t.to(options.device(), options.dtype().toScalarType(), true);
  }
  return out;
}

int64_t Weights::Bytes() const {
  int64_t n = 0;
  for (const auto& [name, t] : tensors) n += t.numel() * t.element_size();
  return n;
}

void ForwardOptions::Check() const {
  GEODRIVE_CHECK_INPUT(attention_chunk_bytes >= 4096,
                       "attention_chunk_bytes must be >= 4096");
  GEODRIVE_CHECK_INPUT(ff_token_chunk >= 1, "ff_token_chunk must be >= 1");
}

namespace {

bool StartsWith(const std::string& s, const std::string& prefix) {
  return s.rfind(prefix, 0) == 0;
}

bool IsLayerNormParam(const std::string& name) {
  for (const char* base : {".norm.", "norm_q.", "norm_k.", "norm_final."}) {
    if (name.find(base) != std::string::npos) return true;
  }
  return StartsWith(name, "norm_final.");
}

at::Tensor Linear(const Weights& w,
                  const std::string& name,
                  const at::Tensor& x) {
  const std::string bias = name + ".bias";
  return at::linear(
      x, w.Get(name + ".weight"),
      w.Has(bias) ? c10::optional<at::Tensor>(w.Get(bias)) : c10::nullopt);
}

at::Tensor LayerNorm(const Weights& w,
                     const std::string& name,
                     const at::Tensor& x,
                     double eps) {
  return at::layer_norm(x, {x.size(-1)}, w.Get(name + ".weight"),
                        w.Get(name + ".bias"), eps);
}

// x [B, H, Nv, hd]: out = x·cos + rot(x)·sin, rot maps interleaved pairs (a, b)
// -> (-b, a). In float32 and cast back, as diffusers' apply_rotary_emb; the
// tables are on x's device.
at::Tensor ApplyRotary(const at::Tensor& x, const RotaryTables& rope) {
  const at::Tensor xf = x.to(at::kFloat);
  auto sizes = xf.sizes().vec();
  sizes.back() /= 2;
  sizes.push_back(2);
  at::Tensor pairs = xf.reshape(sizes);
  at::Tensor re = pairs.select(-1, 0), im = pairs.select(-1, 1);
  at::Tensor rotated = at::stack({im.neg(), re}, -1).flatten(-2);
  return (xf * rope.cos + rotated * rope.sin).to(x.scalar_type());
}

// softmax(q kᵀ / √hd) v over [B, H, N, hd] with the scores of at most
// `chunk_bytes` materialised at a time (chunks of heads x queries).
at::Tensor ChunkedAttention(const at::Tensor& q_in,
                            const at::Tensor& k,
                            const at::Tensor& v,
                            int64_t chunk_bytes) {
  const int64_t B = q_in.size(0), H = q_in.size(1), N = q_in.size(2);
  const int64_t hd = q_in.size(3);
  const at::Tensor q = q_in * (1.0 / std::sqrt(static_cast<double>(hd)));
  const at::Tensor kt = k.transpose(-1, -2);
  // Chunk sizes: scores of one chunk are B x heads x queries x N elements.
  const int64_t row_bytes = B * N * q.element_size();
  const int64_t rows = std::max<int64_t>(1, chunk_bytes / row_bytes);
  const int64_t q_chunk = std::min(N, rows);
  const int64_t h_chunk = std::max<int64_t>(1, std::min(H, rows / q_chunk));
  std::vector<at::Tensor> head_out;
  for (int64_t h0 = 0; h0 < H; h0 += h_chunk) {
    const int64_t hn = std::min(h_chunk, H - h0);
    at::Tensor qh = q.narrow(1, h0, hn), kh = kt.narrow(1, h0, hn),
               vh = v.narrow(1, h0, hn);
    std::vector<at::Tensor> rows_out;
    for (int64_t q0 = 0; q0 < N; q0 += q_chunk) {
      const int64_t qn = std::min(q_chunk, N - q0);
      at::Tensor s = at::matmul(qh.narrow(2, q0, qn), kh);
      s = at::softmax(s, -1);
      rows_out.push_back(at::matmul(s, vh));
    }
    head_out.push_back(rows_out.size() == 1 ? rows_out[0]
                                            : at::cat(rows_out, 2));
  }
  return head_out.size() == 1 ? head_out[0] : at::cat(head_out, 1);
}

// The same through LibTorch's fused kernel (scale 1/√hd inside).
at::Tensor FusedAttention(const at::Tensor& q,
                          const at::Tensor& k,
                          const at::Tensor& v) {
#if TORCH_VERSION_MAJOR >= 2
  return at::scaled_dot_product_attention(q, k, v);
#else
  return std::get<0>(at::_scaled_dot_product_attention(q, k, v));
#endif
}

// Joint attention over x = [text; video] tokens [B, N, D]; returns [B, N, D]
// after to_out.0.
at::Tensor Attention(const DiTConfig& c,
                     const Weights& w,
                     const std::string& p,
                     const at::Tensor& x,
                     int64_t text_len,
                     const RotaryTables& rope,
                     const ForwardOptions& opt) {
  const int64_t B = x.size(0), N = x.size(1), H = c.num_heads, hd = c.head_dim;
  auto heads = [&](const std::string& name) {
    return Linear(w, p + name, x)
        .view({B, N, H, hd})
        .transpose(1, 2);  // [B, H, N, hd]
  };
  at::Tensor q = LayerNorm(w, p + "norm_q", heads("to_q"), c.qk_norm_eps);
  at::Tensor k = LayerNorm(w, p + "norm_k", heads("to_k"), c.qk_norm_eps);
  at::Tensor v = heads("to_v").contiguous();
  if (c.use_rotary) {
    q = at::cat({q.narrow(2, 0, text_len),
                 ApplyRotary(q.narrow(2, text_len, N - text_len), rope)},
                2);
    k = at::cat({k.narrow(2, 0, text_len),
                 ApplyRotary(k.narrow(2, text_len, N - text_len), rope)},
                2);
  }
  at::Tensor o =
      ResolveAttentionBackend(opt.attention) == AttentionBackend::kFused
          ? FusedAttention(q, k, v)
          : ChunkedAttention(q, k, v, opt.attention_chunk_bytes);
  o = o.transpose(1, 2).reshape({B, N, H * hd});
  return Linear(w, p + "to_out.0", o);
}

at::Tensor FeedForward(const Weights& w,
                       const std::string& p,
                       const at::Tensor& x,
                       const ForwardOptions& opt) {
  const int64_t N = x.size(1);
  std::vector<at::Tensor> parts;
  for (int64_t t0 = 0; t0 < N; t0 += opt.ff_token_chunk) {
    const int64_t tn = std::min(opt.ff_token_chunk, N - t0);
    at::Tensor h = Linear(w, p + "ff.net.0.proj", x.narrow(1, t0, tn));
    h = at::gelu(h, "tanh");
    parts.push_back(Linear(w, p + "ff.net.2", h));
  }
  return parts.size() == 1 ? parts[0] : at::cat(parts, 1);
}

// CogVideoXLayerNormZero: returns normed video, normed text, gate, text gate.
std::vector<at::Tensor> NormZero(const DiTConfig& c,
                                 const Weights& w,
                                 const std::string& name,
                                 const at::Tensor& temb,
                                 const at::Tensor& video,
                                 const at::Tensor& text) {
  std::vector<at::Tensor> m =
      Linear(w, name + ".linear", at::silu(temb)).chunk(6, 1);
  for (auto& t : m) t = t.unsqueeze(1);
  at::Tensor nv =
      LayerNorm(w, name + ".norm", video, c.norm_eps) * (1 + m[1]) + m[0];
  at::Tensor nt =
      LayerNorm(w, name + ".norm", text, c.norm_eps) * (1 + m[4]) + m[3];
  return {nv, nt, m[2], m[5]};
}

// Patch embedding + text projection + learned positional embedding -> (video,
// text) tokens.
void PatchEmbed(const DiTConfig& c,
                const Weights& w,
                const at::Tensor& latents,
                const at::Tensor& text_embeds,
                at::Tensor* video,
                at::Tensor* text) {
  const int64_t B = latents.size(0), F = latents.size(1), C = latents.size(2);
  const int64_t H = latents.size(3), W = latents.size(4), p = c.patch_size;
  const at::Tensor& pw = w.Get("patch_embed.proj.weight");
  GEODRIVE_CHECK_INPUT(C == pw.size(1), "latents have ", C,
                       " channels, the patch embedding of '", c.name,
                       "' expects ", pw.size(1));
  GEODRIVE_CHECK_INPUT(H % p == 0 && W % p == 0, "latent size ", H, "x", W,
                       " is not divisible by the patch size ", p);
  GEODRIVE_CHECK_INPUT(text_embeds.dim() == 3 && text_embeds.size(0) == B &&
                           text_embeds.size(2) == c.text_embed_dim,
                       "prompt embeddings must be [", B, ", L, ",
                       c.text_embed_dim, "], got ",
                       ShapeToString(text_embeds.sizes().vec()));
  const at::TensorOptions compute = pw.options();
  at::Tensor x = at::conv2d(latents.to(compute).reshape({B * F, C, H, W}), pw,
                            w.Get("patch_embed.proj.bias"), {p, p});
  const int64_t D = x.size(1), hw = x.size(2) * x.size(3);
  x = x.view({B, F, D, hw}).transpose(2, 3).reshape({B, F * hw, D});
  at::Tensor t = Linear(w, "patch_embed.text_proj", text_embeds.to(compute));
  at::Tensor emb = at::cat({t, x}, 1);
  if (c.use_learned_pos) {
    const at::Tensor& pos = w.Get("patch_embed.pos_embedding");
    GEODRIVE_CHECK_INPUT(pos.size(1) == emb.size(1),
                         "the learned positional embedding of '", c.name,
                         "' covers ", pos.size(1), " tokens (", c.text_seq_len,
                         " text + ", c.latent_frames, "x", c.latent_height, "x",
                         c.latent_width, " latents) but the input has ",
                         t.size(1), " text + ", x.size(1), " video tokens");
    emb = emb + pos;
  }
  const int64_t L = t.size(1);
  *text = emb.narrow(1, 0, L);
  *video = emb.narrow(1, L, emb.size(1) - L);
}

void CheckLatents(const at::Tensor& latents, const char* what) {
  GEODRIVE_CHECK_INPUT(latents.dim() == 5, what,
                       " must be [B, F, C, H, W], got ",
                       ShapeToString(latents.sizes().vec()));
}

}  // namespace

namespace {

// A tensor (CPU, any dtype) converted to the placement: pinned host memory for
// the offloaded blocks, else the compute device.
at::Tensor Place(const at::Tensor& t,
                 const std::string& name,
                 const WeightPlacement& placement) {
  at::Tensor out = t.to(ToScalarType(placement.dtype));
  const bool host = placement.host_blocks &&
                    StartsWith(name, "transformer_blocks.") &&
                    placement.device.is_cuda();
  if (host) return out.is_pinned() ? out : out.pin_memory();
  return out.to(ToTorchDevice(placement.device));
}

}  // namespace

Weights InitWeights(const std::vector<ParamSpec>& specs,
                    uint64_t seed,
                    const WeightPlacement& placement) {
  at::Generator gen = at::make_generator<at::CPUGeneratorImpl>(seed);
  Weights w;
  const auto opts = at::TensorOptions().dtype(at::kFloat);
  for (const auto& s : specs) {
    at::Tensor t;
    if (StartsWith(s.name, "branch_blocks.") ||
        StartsWith(s.name, "branch_x_embedder.")) {
      t = at::zeros(s.shape, opts);
    } else if (IsLayerNormParam(s.name)) {
      t = EndsWith(s.name, ".weight") ? at::ones(s.shape, opts)
                                      : at::zeros(s.shape, opts);
    } else if (EndsWith(s.name, "pos_embedding")) {
      t = at::randn(s.shape, gen, opts) * 0.02;
    } else if (s.shape.size() >= 2) {
      const int64_t fan_in = NumElements(s.shape) / s.shape[0];
      t = at::randn(s.shape, gen, opts) *
          (1.0 / std::sqrt(static_cast<double>(fan_in)));
    } else {
      t = at::randn(s.shape, gen, opts) * 0.02;
    }
    w.Set(s.name, Place(t, s.name, placement));
  }
  return w;
}

Weights InitBranchFromBackbone(const DiTConfig& c,
                               const Weights& backbone,
                               uint64_t seed) {
  // The encoder is placed like the backbone's non-block weights.
  const at::Tensor& ref = backbone.Get("patch_embed.proj.weight");
  Weights w = InitWeights(BranchParamSpecs(c), seed)
                  .To(at::TensorOptions()
                          .device(ref.device())
                          .dtype(ref.scalar_type()));
  for (const std::string& name : w.order) {
    bool copy = StartsWith(name, "time_embedding.");
    for (int k = 0; k < c.branch_layers; ++k) {
      copy |= StartsWith(name, "transformer_blocks." + std::to_string(k) + ".");
    }
    if (copy) w.Set(name, backbone.Get(name).detach().to(ref.device()).clone());
  }
  const at::Tensor& bw = backbone.Get("patch_embed.proj.weight");
  const int64_t lat = c.out_channels;
  at::Tensor pw = at::zeros_like(w.Get("patch_embed.proj.weight"));
  pw.narrow(1, 0, lat).copy_(bw.narrow(1, 0, lat));
  if (c.branch_in_channels >= 2 * lat)
    pw.narrow(1, lat, lat).copy_(bw.narrow(1, 0, lat));
  w.Set("patch_embed.proj.weight", pw);
  w.Set("patch_embed.proj.bias",
        backbone.Get("patch_embed.proj.bias").detach().clone());
  return w;
}

Weights LoadWeights(const std::string& path,
                    const std::vector<ParamSpec>& specs,
                    const std::string& prefix,
                    bool strict,
                    LoadReport* report,
                    const WeightPlacement& placement) {
  SafetensorsCheckpoint ckpt(path);
  std::vector<ParamSpec> in_file;
  for (const auto& e : ckpt.entries()) {
    if (!StartsWith(e.name, prefix)) continue;
    // In a combined file the encoder lives under "branch."; it is not part of
    // the backbone.
    if (prefix.empty() && StartsWith(e.name, "branch.")) continue;
    in_file.push_back({e.name.substr(prefix.size()), e.shape});
  }
  LoadReport r = CompareStateDict(
      path + (prefix.empty() ? "" : " [" + prefix + "*]"), specs, in_file);
  if (strict && !r.ok()) {
    std::string first = !r.missing.empty()
                            ? "first missing: " + r.missing[0]
                            : "first mismatch: " + r.mismatched[0];
    ThrowInputError(path, "checkpoint does not fit the model (",
                    r.missing.size(), " missing, ", r.mismatched.size(),
                    " shape-mismatched, ", r.unexpected.size(), " unexpected; ",
                    first, ")");
  }
  Weights w;
  for (const auto& s : specs) {
    const std::string stored = prefix + s.name;
    if (!ckpt.Has(stored) || ckpt.Entry(stored).shape != s.shape) continue;
    at::Tensor t = ckpt.Load(stored);
    if (!at::isFloatingType(t.scalar_type())) {
      ThrowInputError(path, "tensor '", stored, "' has non-float dtype ",
                      ckpt.Entry(stored).dtype);
    }
    // A NaN or Inf in a weight spreads to every output (a black video, a NaN
    // loss) without any other sign: refused here, naming the tensor.
    if (!at::isfinite(t).all().item<bool>()) {
      const int64_t bad = (~at::isfinite(t)).sum().item<int64_t>();
      ThrowInputError(path, "tensor '", stored, "' holds ", bad,
                      " NaN or Inf value(s)");
    }
    w.Set(s.name, Place(t, s.name, placement));
  }
  if (report != nullptr) *report = std::move(r);
  return w;
}

void AppendForSave(const Weights& weights,
                   const std::string& prefix,
                   std::vector<std::pair<std::string, at::Tensor>>* out) {
  for (const auto& name : weights.order)
    out->emplace_back(prefix + name, weights.Get(name));
}

RotaryTables Rotary3D(const DiTConfig& c,
                      int64_t frames,
                      int64_t gh,
                      int64_t gw) {
  const int dt = c.rope_dim_t(), dh = c.rope_dim_h(), dw = c.rope_dim_w();
  const int64_t hd = c.head_dim, n = frames * gh * gw;
  at::Tensor cos = at::empty({n, hd}, at::kFloat),
             sin = at::empty({n, hd}, at::kFloat);
  float* pc = cos.data_ptr<float>();
  float* ps = sin.data_ptr<float>();
  // get_1d_rotary_pos_embed(dim, pos, use_real, repeat_interleave_real): freq_k
  // = θ^(−2k/dim), cos/sin repeat-interleaved x2; the three axes are
  // concatenated in t, h, w order.
  auto fill = [&](float* dc, float* ds, int dim, int64_t pos) {
    for (int k = 0; k < dim / 2; ++k) {
      const double freq = 1.0 / std::pow(c.rope_theta, (2.0 * k) / dim);
      const double a = static_cast<double>(pos) * freq;
      dc[2 * k] = dc[2 * k + 1] = static_cast<float>(std::cos(a));
      ds[2 * k] = ds[2 * k + 1] = static_cast<float>(std::sin(a));
    }
  };
  int64_t i = 0;
  for (int64_t t = 0; t < frames; ++t) {
    for (int64_t y = 0; y < gh; ++y) {
      for (int64_t x = 0; x < gw; ++x, ++i) {
        float* rc = pc + i * hd;
        float* rs = ps + i * hd;
        fill(rc, rs, dt, t);
        fill(rc + dt, rs + dt, dh, y);
        fill(rc + dt + dh, rs + dt + dh, dw, x);
      }
    }
  }
  return {cos, sin};
}

at::Tensor TimeEmbedding(const DiTConfig& c,
                         const Weights& w,
                         const at::Tensor& timesteps) {
  const int64_t half = c.inner_dim() / 2;
  const at::Tensor& w1 = w.Get("time_embedding.linear_1.weight");
  const auto f32 = at::TensorOptions().device(w1.device()).dtype(at::kFloat);
  at::Tensor exponent =
      at::arange(half, f32) * static_cast<float>(-std::log(10000.0));
  exponent = exponent / static_cast<float>(half - c.freq_shift);
  at::Tensor args =
      timesteps.to(f32).unsqueeze(1) * at::exp(exponent).unsqueeze(0);
  at::Tensor emb = c.flip_sin_to_cos
                       ? at::cat({at::cos(args), at::sin(args)}, 1)
                       : at::cat({at::sin(args), at::cos(args)}, 1);
  // The sinusoid in float32, the MLP in the weights' dtype (diffusers casts
  // t_emb to the hidden states' dtype).
  emb = emb.to(w1.scalar_type());
  at::Tensor h = at::silu(Linear(w, "time_embedding.linear_1", emb));
  return Linear(w, "time_embedding.linear_2", h);
}

void BlockForward(const DiTConfig& c,
                  const Weights& w,
                  const std::string& p,
                  const at::Tensor& temb,
                  const RotaryTables& rope,
                  const ForwardOptions& opt,
                  at::Tensor* video,
                  at::Tensor* text) {
  const int64_t L = text->size(1);
  {
    std::vector<at::Tensor> n =
        NormZero(c, w, p + "norm1", temb, *video, *text);
    at::Tensor a =
        Attention(c, w, p + "attn1.", at::cat({n[1], n[0]}, 1), L, rope, opt);
    *video = *video + n[2] * a.narrow(1, L, a.size(1) - L);
    *text = *text + n[3] * a.narrow(1, 0, L);
  }
  std::vector<at::Tensor> n = NormZero(c, w, p + "norm2", temb, *video, *text);
  at::Tensor f = FeedForward(w, p, at::cat({n[1], n[0]}, 1), opt);
  *video = *video + n[2] * f.narrow(1, L, f.size(1) - L);
  *text = *text + n[3] * f.narrow(1, 0, L);
}

namespace {

// The RoPE tables on the device of `like` (float32).
RotaryTables RotaryOn(const RotaryTables& rope, const at::Tensor& like) {
  if (rope.cos.device() == like.device()) return rope;
  return {rope.cos.to(like.device()), rope.sin.to(like.device())};
}

// One backbone block: its weights copied to the compute device first when
// offloaded, through options.block_forward when set.
void RunBlock(const DiTConfig& c,
              const Weights& w,
              const std::string& prefix,
              const at::Tensor& temb,
              const RotaryTables& rope,
              const ForwardOptions& opt,
              at::Tensor* video,
              at::Tensor* text) {
  Weights on_device;
  const Weights* bw = &w;
  if (opt.offload_blocks &&
      w.Get(prefix + "norm1.linear.weight").device() != video->device()) {
    on_device = w.Subset(prefix).To(video->options());
    bw = &on_device;
  }
  if (opt.block_forward) {
    opt.block_forward(c, *bw, prefix, temb, rope, opt, video, text);
  } else {
    BlockForward(c, *bw, prefix, temb, rope, opt, video, text);
  }
}

}  // namespace

at::Tensor BackboneForward(const DiTConfig& c,
                           const Weights& w,
                           const at::Tensor& latents,
                           const at::Tensor& text_embeds,
                           const at::Tensor& timesteps,
                           const std::vector<at::Tensor>& branch,
                           const ForwardOptions& opt) {
  opt.Check();
  CheckLatents(latents, "latents");
  const int64_t B = latents.size(0), F = latents.size(1), H = latents.size(3),
                W = latents.size(4), p = c.patch_size;
  at::Tensor temb = TimeEmbedding(c, w, timesteps);
  at::Tensor video, text;
  PatchEmbed(c, w, latents, text_embeds, &video, &text);
  const RotaryTables rope = RotaryOn(Rotary3D(c, F, H / p, W / p), video);
  const int interval =
      branch.empty() ? 1
                     : static_cast<int>((c.num_layers + branch.size() - 1) /
                                        branch.size());
  for (int i = 0; i < c.num_layers; ++i) {
    const std::string prefix = "transformer_blocks." + std::to_string(i) + ".";
    RunBlock(c, w, prefix, temb, rope, opt, &video, &text);
    if (!branch.empty()) video = video + branch[i / interval];
  }
  video = LayerNorm(w, "norm_final", video, c.norm_eps);
  std::vector<at::Tensor> m =
      Linear(w, "norm_out.linear", at::silu(temb)).chunk(2, 1);
  video = LayerNorm(w, "norm_out.norm", video, c.norm_eps) *
              (1 + m[1].unsqueeze(1)) +
          m[0].unsqueeze(1);
  at::Tensor out = Linear(w, "proj_out", video);
  return out.reshape({B, F, H / p, W / p, c.out_channels, p, p})
      .permute({0, 1, 4, 2, 5, 3, 6})
      .reshape({B, F, c.out_channels, H, W});
}

std::vector<at::Tensor> BranchForward(const DiTConfig& c,
                                      const Weights& w,
                                      const at::Tensor& noisy,
                                      const at::Tensor& cond,
                                      const at::Tensor& text_embeds,
                                      const at::Tensor& timesteps,
                                      const ForwardOptions& opt) {
  opt.Check();
  CheckLatents(noisy, "noisy latents");
  CheckLatents(cond, "condition latents");
  GEODRIVE_CHECK_INPUT(
      noisy.size(0) == cond.size(0) && noisy.size(1) == cond.size(1) &&
          noisy.size(3) == cond.size(3) && noisy.size(4) == cond.size(4),
      "condition latents ", ShapeToString(cond.sizes().vec()),
      " do not match the noisy latents ", ShapeToString(noisy.sizes().vec()));
  const int64_t F = noisy.size(1), H = noisy.size(3), W = noisy.size(4),
                p = c.patch_size;
  at::Tensor temb = TimeEmbedding(c, w, timesteps);
  at::Tensor video, text;
  PatchEmbed(c, w, at::cat({noisy, cond}, 2), text_embeds, &video, &text);
  const RotaryTables rope = RotaryOn(Rotary3D(c, F, H / p, W / p), video);
  std::vector<at::Tensor> out;
  for (int k = 0; k < c.branch_layers; ++k) {
    const std::string b = std::to_string(k);
    BlockForward(c, w, "transformer_blocks." + b + ".", temb, rope, opt, &video,
                 &text);
    out.push_back(Linear(w, "branch_blocks." + b, video) *
                  c.conditioning_scale);
  }
  return out;
}

}  // namespace diffusion
}  // namespace geodrive

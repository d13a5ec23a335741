// Soft rendering of one frame (renderer.h, kSoft): PyTorch3D-style
// `PointsRasterizer` + `AlphaCompositor` over the points sorted by depth, with
// scalar and AVX2 compositing kernels that give the same bytes.

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <vector>

#include "render/internal/renderer_internal.h"
#include "render/renderer.h"

#ifdef GEODRIVE_HAVE_AVX2_PATH
#include <immintrin.h>
#endif

namespace geodrive {
namespace renderer_internal {
namespace {

// Squared NDC distance between pixel centre (c, j) and a projected point (u, v)
// (shifted pixel coordinates). Used both to select and to weight, so both see
// the same value.
inline float SoftD2(int c, int j, float u, float v, float inv_s2) {
  const float dx = static_cast<float>(c) - u;
  const float dy = static_cast<float>(j) - v;
  return (dx * dx + dy * dy) * inv_s2;
}

// Splat of points visited in (z, index) order, compositing on the fly: the
// first K points that reach a pixel ARE its K nearest, so each one is
// composited front to back as it arrives, with the operation order of
// PyTorch3D's CPU AlphaCompositor (acc += cum * w * c; cum *= 1 - w), where
// w = 1 - d² / r² and d² is the squared NDC distance (SoftD2). A point that
// reaches a full pixel (or one outside its disk) is applied with w = 0, which
// leaves acc and cum bitwise unchanged, so the update has no branch. Returns
// the number of points within the radius of at least one pixel. The scalar and
// AVX2 versions evaluate the same float operations (no FMA).
struct SoftSplatArgs {
  const float* pu;
  const float* pv;
  const float* colors01;
  const int32_t* order;
  size_t num;
  int w, h, k_max;
  float r_px_bound, inv_s2, r2, inv_r2;
  SoftState* state;
};

int64_t SoftSplatScalar(const SoftSplatArgs& a) {
  SoftState& st = *a.state;
  int64_t projected = 0;
  for (size_t e = 0; e < a.num; ++e) {
    const int32_t idx = a.order[e];
    const float u = a.pu[idx], v = a.pv[idx];
    const float* col = a.colors01 + 3 * static_cast<size_t>(idx);
    const int j0 = std::max(0, CeilI(v - a.r_px_bound));
    const int j1 = std::min(a.h - 1, FloorI(v + a.r_px_bound));
    const int i0 = std::max(0, CeilI(u - a.r_px_bound));
    const int i1 = std::min(a.w - 1, FloorI(u + a.r_px_bound));
    int hit = 0;
    for (int j = j0; j <= j1; ++j) {
      const size_t row = static_cast<size_t>(j) * a.w;
      for (int c = i0; c <= i1; ++c) {
        const float d2 = SoftD2(c, j, u, v, a.inv_s2);
        if (!(d2 < a.r2)) continue;
        hit = 1;
        const size_t p = row + c;
        if (st.count[p] >= a.k_max) continue;
        const float alpha = 1.0f - d2 * a.inv_r2;
        const float cum = st.cum[p];
        st.acc_r[p] += cum * alpha * col[0];
        st.acc_g[p] += cum * alpha * col[1];
        st.acc_b[p] += cum * alpha * col[2];
        st.cum[p] = cum * (1 - alpha);
        if (st.count[p] == 0) st.first[p] = idx;
        ++st.count[p];
      }
    }
    projected += hit;
  }
  return projected;
}

#ifdef GEODRIVE_HAVE_AVX2_PATH
// Eight pixels of a row at a time.
__attribute__((target("avx2"))) int64_t SoftSplatAvx2(const SoftSplatArgs& a) {
  SoftState& st = *a.state;
  float* acc_r = st.acc_r.data();
  float* acc_g = st.acc_g.data();
  float* acc_b = st.acc_b.data();
  float* cum_p = st.cum.data();
  int32_t* count_p = st.count.data();
  int32_t* first_p = st.first.data();
  int64_t projected = 0;
  const __m256 vr2 = _mm256_set1_ps(a.r2);
  const __m256 vinv = _mm256_set1_ps(a.inv_s2);
  const __m256 vinv_r2 = _mm256_set1_ps(a.inv_r2);
  const __m256 one = _mm256_set1_ps(1.0f);
  const __m256i vk = _mm256_set1_epi32(a.k_max);
  const __m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  for (size_t e = 0; e < a.num; ++e) {
    const int32_t idx = a.order[e];
    const float u = a.pu[idx], v = a.pv[idx];
    const float* col = a.colors01 + 3 * static_cast<size_t>(idx);
    const __m256 cr = _mm256_set1_ps(col[0]);
    const __m256 cg = _mm256_set1_ps(col[1]);
    const __m256 cb = _mm256_set1_ps(col[2]);
    const __m256i vidx = _mm256_set1_epi32(idx);
    const int j0 = std::max(0, CeilI(v - a.r_px_bound));
    const int j1 = std::min(a.h - 1, FloorI(v + a.r_px_bound));
    const int i0 = std::max(0, CeilI(u - a.r_px_bound));
    const int i1 = std::min(a.w - 1, FloorI(u + a.r_px_bound));
    const __m256 vu = _mm256_set1_ps(u);
    int hit = 0;
    for (int c0 = i0; c0 <= i1; c0 += 8) {
      const __m256i cols = _mm256_add_epi32(_mm256_set1_epi32(c0), lanes);
      const __m256 in_box = _mm256_castsi256_ps(
          _mm256_cmpgt_epi32(_mm256_set1_epi32(i1 + 1), cols));
      const __m256 dx = _mm256_sub_ps(_mm256_cvtepi32_ps(cols), vu);
      const __m256 dx2 = _mm256_mul_ps(dx, dx);
      for (int j = j0; j <= j1; ++j) {
        const float dy = static_cast<float>(j) - v;
        const __m256 d2 =
            _mm256_mul_ps(_mm256_add_ps(dx2, _mm256_set1_ps(dy * dy)), vinv);
        const __m256 in =
            _mm256_and_ps(_mm256_cmp_ps(d2, vr2, _CMP_LT_OQ), in_box);
        if (_mm256_movemask_ps(in) == 0) continue;
        hit = 1;
        const size_t p = static_cast<size_t>(j) * a.w + c0;
        const __m256i cnt =
            _mm256_loadu_si256(reinterpret_cast<const __m256i*>(count_p + p));
        const __m256 active =
            _mm256_and_ps(in, _mm256_castsi256_ps(_mm256_cmpgt_epi32(vk, cnt)));
        const __m256 alpha = _mm256_and_ps(
            _mm256_sub_ps(one, _mm256_mul_ps(d2, vinv_r2)), active);
        const __m256 cum = _mm256_loadu_ps(cum_p + p);
        const __m256 ca = _mm256_mul_ps(cum, alpha);
        _mm256_storeu_ps(acc_r + p, _mm256_add_ps(_mm256_loadu_ps(acc_r + p),
                                                  _mm256_mul_ps(ca, cr)));
        _mm256_storeu_ps(acc_g + p, _mm256_add_ps(_mm256_loadu_ps(acc_g + p),
                                                  _mm256_mul_ps(ca, cg)));
        _mm256_storeu_ps(acc_b + p, _mm256_add_ps(_mm256_loadu_ps(acc_b + p),
                                                  _mm256_mul_ps(ca, cb)));
        _mm256_storeu_ps(cum_p + p,
                         _mm256_mul_ps(cum, _mm256_sub_ps(one, alpha)));
        const __m256i act_i = _mm256_castps_si256(active);
        // count - (-1) where active.
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(count_p + p),
                            _mm256_sub_epi32(cnt, act_i));
        const __m256i is_first = _mm256_and_si256(
            act_i, _mm256_cmpeq_epi32(cnt, _mm256_setzero_si256()));
        const __m256i first =
            _mm256_loadu_si256(reinterpret_cast<const __m256i*>(first_p + p));
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(first_p + p),
                            _mm256_blendv_epi8(first, vidx, is_first));
      }
    }
    projected += hit;
  }
  return projected;
}
#endif

int64_t SoftSplat(const SoftSplatArgs& a) {
#ifdef GEODRIVE_HAVE_AVX2_PATH
  if (UseAvx2()) return SoftSplatAvx2(a);
#endif
  return SoftSplatScalar(a);
}

}  // namespace

// Soft mode (PyTorch3D rasteriser + alpha compositor). The points that can
// reach the image are sorted by (z, index) (a stable LSD radix sort of the
// positive float depth bits over index order); visiting them in that order,
// the first K candidates of a pixel ARE its K nearest, so the per-pixel lists
// only ever append. The distance is recomputed at compositing time from the
// projected (u, v).
GEODRIVE_HOT_CLONES
void RenderSoft(const PackedCloud& soa,
                const std::vector<ProjectedRange>& ranges,
                const RenderOptions& options,
                Scratch* scratch,
                RenderedFrame* frame) {
  const int w = options.width, h = options.height;
  const size_t npix = static_cast<size_t>(w) * h;
  const int k_max = options.points_per_pixel;
  const int n = static_cast<int>(soa.size());
  scratch->pu.resize(n);
  scratch->pv.resize(n);
  scratch->pz.resize(n);
  float* pu = scratch->pu.data();
  float* pv = scratch->pv.data();
  float* pz = scratch->pz.data();

  // Pixels per NDC unit: the short side spans 2 NDC.
  const double s = std::min(w, h) / 2.0;
  const float inv_s2 = static_cast<float>(1.0 / (s * s));
  const float r2 = static_cast<float>(options.radius_ndc * options.radius_ndc);
  const float r_px = static_cast<float>(options.radius_ndc * s);
  // Candidate rows/columns are bounded by a slightly larger pixel radius; the
  // exact test is d² < r² in NDC, as in PyTorch3D.
  const float r_px_bound = r_px * 1.0001f + 1e-4f;
  const float fw = static_cast<float>(w), fh = static_cast<float>(h);
  ProjectedBlock& blk = scratch->block;
  // Pass 1: project; keep the points that can reach the image.
  std::vector<int32_t>& cand = scratch->cand;
  std::vector<uint32_t>& zbits = scratch->zbits;
  cand.clear();
  zbits.clear();
  for (const ProjectedRange& range : ranges) {
    for (int base = range.begin; base < range.end; base += kBlock) {
      const int m = std::min(kBlock, range.end - base);
      ProjectBlock(soa, base, m, range.proj, &blk);
      std::memcpy(pu + base, blk.u, m * sizeof(float));
      std::memcpy(pv + base, blk.v, m * sizeof(float));
      std::memcpy(pz + base, blk.z, m * sizeof(float));
      for (int k = 0; k < m; ++k) {
        if (!blk.ok[k]) continue;
        const float u = blk.u[k], v = blk.v[k];
        if (!(u > -r_px - 1 && u < fw + r_px && v > -r_px - 1 && v < fh + r_px))
          continue;
        cand.push_back(base + k);
        zbits.push_back(FloatBits(blk.z[k]));
      }
    }
  }
  // Pass 2: stable radix sort by z bits (16 + 15 bits: z > 0, so bit 31 is
  // 0); ties keep index order.
  const size_t num = cand.size();
  std::vector<int32_t>& order = scratch->order;
  std::vector<int32_t>& tmp = scratch->order_tmp;
  std::vector<uint32_t>& tmp_bits = scratch->zbits_tmp;
  order.resize(num);
  tmp.resize(num);
  tmp_bits.resize(num);
  std::vector<uint32_t>& hist = scratch->hist;
  hist.assign(65536 + 32768, 0u);
  uint32_t* h0 = hist.data();
  uint32_t* h1 = hist.data() + 65536;
  for (size_t i = 0; i < num; ++i) {
    ++h0[zbits[i] & 0xffffu];
    ++h1[zbits[i] >> 16];
  }
  uint32_t sum0 = 0, sum1 = 0;
  for (int b = 0; b < 65536; ++b) {
    const uint32_t c = h0[b];
    h0[b] = sum0;
    sum0 += c;
  }
  for (int b = 0; b < 32768; ++b) {
    const uint32_t c = h1[b];
    h1[b] = sum1;
    sum1 += c;
  }
  for (size_t i = 0; i < num; ++i) {
    const uint32_t d = h0[zbits[i] & 0xffffu]++;
    tmp[d] = cand[i];
    tmp_bits[d] = zbits[i];
  }
  for (size_t i = 0; i < num; ++i) order[h1[tmp_bits[i] >> 16]++] = tmp[i];

  // Pass 3: splat and composite front to back.
  SoftState& state = scratch->soft;
  state.Reset(npix);
  const float inv_r2 = 1.0f / r2;
  SoftSplatArgs args{
      pu,    pv,    soa.colors01.data(), order.data(), num, w,
      h,     k_max, r_px_bound,          inv_s2,       r2,  inv_r2,
      &state};
  frame->num_projected = SoftSplat(args);

  // Resolve.
  std::vector<int32_t>& index = scratch->index;
  index.resize(npix);
  uint8_t* rgb = frame->rgb.ptr<uint8_t>();
  float* depth = frame->depth.ptr<float>();
  uint8_t* mask = frame->mask.ptr<uint8_t>();
  float* rgbf =
      options.output_float_rgb ? frame->rgb_float.ptr<float>() : nullptr;
  int64_t valid = 0;
  for (size_t p = 0; p < npix; ++p) {
    const int32_t first = state.first[p];
    const float acc[3] = {state.acc_r[p], state.acc_g[p], state.acc_b[p]};
    if (first < 0) {
      depth[p] = 0;
      mask[p] = kMaskInvalid;
    } else {
      depth[p] = pz[first];
      mask[p] = kMaskValid;
      ++valid;
    }
    index[p] = first;
    for (int ch = 0; ch < 3; ++ch) {
      const float val = std::min(255.0f, std::max(0.0f, acc[ch] * 255.0f));
      rgb[3 * p + ch] = static_cast<uint8_t>(val + 0.5f);
      if (rgbf) rgbf[3 * p + ch] = acc[ch];
    }
  }
  frame->num_valid = valid;
}

}  // namespace renderer_internal
}  // namespace geodrive

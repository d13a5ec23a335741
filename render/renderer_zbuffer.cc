// Z-buffer rendering of one frame (renderer.h, kZBuffer): point or disk splats
// into a per-pixel (depth, index) key buffer, the resolve to RGB / depth /
// mask / index, and hole filling. Scalar and AVX2 kernels give the same bytes.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "render/footprint.h"
#include "render/internal/renderer_internal.h"
#include "render/renderer.h"

#ifdef GEODRIVE_HAVE_AVX2_PATH
#include <immintrin.h>
#endif

namespace geodrive {
namespace renderer_internal {
namespace {

// Depth-ordered key of a point: for z > 0 the float bits are monotonic, so
// min(key) picks the nearest point and, among equal depths, the smallest
// index.
// Keys stay below 2^63 (z bits <= 0x7f800000), so they also order correctly as
// signed 64-bit integers (AVX2 has only a signed 64-bit compare).
constexpr uint64_t kEmptyKey = 0x7fffffffffffffffull;
inline uint64_t PackKey(float z, int index) {
  return (static_cast<uint64_t>(FloatBits(z)) << 32) |
         static_cast<uint32_t>(index);
}

// Radius 0: each point of a projected block takes min(key) at the single pixel
// that contains its projection; returns the number of such points. Pixel
// (i, j) covers [i - 0.5, i + 0.5) x [j - 0.5, j + 0.5) in shifted
// coordinates.
// Entries [0, packed) of `blk` hold the pixel and key of points known to be
// in the image, packed to the front (ProjectPixelsAvx2<true>); entries
// [checked, k0) hold a pixel (-1 outside) and a key (ProjectPixelsAvx2<false>;
// checked = k0 when there are none); entries [k0, m) are projected
// (ProjectBlock). Returns the number of points in the image among entries
// [checked, m).
inline int64_t SplatPoints(ProjectedBlock* blk,
                           int packed,
                           int checked,
                           int k0,
                           int m,
                           int base,
                           int w,
                           float fw,
                           float fh,
                           uint64_t* kb) {
  int32_t* pix = blk->ok;  // becomes the pixel index, -1 outside the image
  int64_t projected = 0;
  for (int k = k0; k < m; ++k) {
    // 0 <= fu < W and 0 <= fv < H from sign bits (vectorises; see
    // ProjectBlock).
    const float fu = blk->u[k] + 0.5f, fv = blk->v[k] + 0.5f;
    const int32_t in =
        pix[k] & static_cast<int32_t>((SignBit(fu) ^ 1u) & SignBit(fu - fw) &
                                      (SignBit(fv) ^ 1u) & SignBit(fv - fh));
    const float su = in ? fu : 0.0f, sv = in ? fv : 0.0f;
    const int32_t p = static_cast<int32_t>(sv) * w + static_cast<int32_t>(su);
    pix[k] = in ? p : -1;
    blk->key[k] = PackKey(blk->z[k], base + k);
    projected += in;
  }
  // The depth test is a branch-free min; packed points need no check.
#pragma GCC unroll 4
  for (int k = 0; k < packed; ++k) {
    uint64_t* slot = kb + pix[k];
    const uint64_t key = blk->key[k], old = *slot;
    *slot = key < old ? key : old;
  }
  // Points outside the image come in runs (a predictable branch).
  for (int k = checked; k < m; ++k) {
    if (pix[k] < 0) continue;
    uint64_t* slot = kb + pix[k];
    const uint64_t key = blk->key[k], old = *slot;
    *slot = key < old ? key : old;
  }
  return projected;
}

#ifdef GEODRIVE_HAVE_AVX2_PATH
#define GEODRIVE_AVX2 __attribute__((target("avx2")))

// Lane permutations that move the selected lanes of a vector to its front,
// in order (AVX2 has no compress instruction), one entry per 8-bit selection
// of eight points: for their pixels (8 x 32-bit lanes), for the keys of points
// 0-3 and of points 4-7 (4 x 64-bit lanes, as 8 x 32-bit), and how many of
// points 0-3 and of all eight are selected.
struct alignas(32) PackEntry {
  int32_t pixels[8];
  int32_t keys03[8];
  int32_t keys47[8];
  int32_t count03, count;
  int32_t unused[6];  // pads the entry to 128 bytes
};
struct PackTable {
  PackEntry entry[256];
  PackTable() : entry() {
    for (int bits = 0; bits < 256; ++bits) {
      PackEntry& e = entry[bits];
      int n = 0, n03 = 0, n47 = 0;
      for (int i = 0; i < 8; ++i) {
        if (!(bits >> i & 1)) continue;
        e.pixels[n++] = i;
        if (i < 4) {
          e.keys03[2 * n03] = 2 * i;
          e.keys03[2 * n03 + 1] = 2 * i + 1;
          ++n03;
        } else {
          e.keys47[2 * n47] = 2 * (i - 4);
          e.keys47[2 * n47 + 1] = 2 * (i - 4) + 1;
          ++n47;
        }
      }
      e.count03 = n03;
      e.count = n;
    }
  }
};
static_assert(sizeof(PackEntry) == 128, "one entry: 4 x 32 bytes");
// Built at start-up (GCC 12 rejects it as a constant expression).
const PackTable kPack;

// Radius 0, eight points at a time: ProjectBlock and the first pass of
// SplatPoints fused, with the same float operations in the same order (no
// FMA), so the pixels and keys are those of the scalar code. *k_done is set
// to m rounded down to a multiple of 8; returns how many of points [0,
// *k_done) are in the image. kPacked = false fills entries [0, *k_done) of
// blk->ok (pixel, -1 outside) and blk->key; kPacked = true writes only the
// points in the image, to entries [0, returned count), in point order.
template <bool kPacked>
GEODRIVE_AVX2 int64_t ProjectPixelsAvx2(const PackedCloud& soa,
                                        int base,
                                        int m,
                                        const FrameProjector& p,
                                        int w,
                                        float fw,
                                        float fh,
                                        ProjectedBlock* blk,
                                        int* k_done) {
  const __m256 r0 = _mm256_set1_ps(p.r[0]), r1 = _mm256_set1_ps(p.r[1]),
               r2 = _mm256_set1_ps(p.r[2]), r3 = _mm256_set1_ps(p.r[3]),
               r4 = _mm256_set1_ps(p.r[4]), r5 = _mm256_set1_ps(p.r[5]),
               r6 = _mm256_set1_ps(p.r[6]), r7 = _mm256_set1_ps(p.r[7]),
               r8 = _mm256_set1_ps(p.r[8]);
  const __m256 t0 = _mm256_set1_ps(p.t[0]), t1 = _mm256_set1_ps(p.t[1]),
               t2 = _mm256_set1_ps(p.t[2]);
  // Every constant in a local: the stores below could alias `p`, and the
  // compiler would load and broadcast it again in every iteration.
  const __m256 fx = _mm256_set1_ps(p.fx), fy = _mm256_set1_ps(p.fy),
               cx = _mm256_set1_ps(p.cx), cy = _mm256_set1_ps(p.cy),
               near = _mm256_set1_ps(p.near), far = _mm256_set1_ps(p.far),
               width = _mm256_set1_ps(fw), height = _mm256_set1_ps(fh),
               one = _mm256_set1_ps(1.0f), half = _mm256_set1_ps(0.5f);
  const __m256i row_stride = _mm256_set1_epi32(w),
                minus_one = _mm256_set1_epi32(-1);
  const float* px = soa.x.data() + base;
  const float* py = soa.y.data() + base;
  const float* pz = soa.z.data() + base;
  int32_t* const pix_out = blk->ok;
  uint64_t* const key_out = blk->key;
  __m256i idx = _mm256_add_epi32(_mm256_set1_epi32(base),
                                 _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
  const __m256i eight = _mm256_set1_epi32(8);
  int projected = 0;  // at most m <= kBlock
  int k = 0;
  for (; k + 8 <= m; k += 8, idx = _mm256_add_epi32(idx, eight)) {
    const __m256 x = _mm256_loadu_ps(px + k), y = _mm256_loadu_ps(py + k),
                 z = _mm256_loadu_ps(pz + k);
    // x_cam = R x + t, evaluated as ((r0 x + r1 y) + r2 z) + t0, as in C++.
    const __m256 zc = _mm256_add_ps(
        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(r6, x), _mm256_mul_ps(r7, y)),
                      _mm256_mul_ps(r8, z)),
        t2);
    const __m256 xc = _mm256_add_ps(
        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(r0, x), _mm256_mul_ps(r1, y)),
                      _mm256_mul_ps(r2, z)),
        t0);
    const __m256 yc = _mm256_add_ps(
        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(r3, x), _mm256_mul_ps(r4, y)),
                      _mm256_mul_ps(r5, z)),
        t1);
    const __m256 inv = _mm256_div_ps(one, zc);
    // fu = (fx * xc) * inv + cx + 0.5, likewise fv.
    const __m256 fu = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(fx, xc), inv), cx), half);
    const __m256 fv = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(fy, yc), inv), cy), half);
    // Sign bit set where near - zc < 0, zc - far < 0, fu >= 0, fu - W < 0,
    // fv >= 0 and fv - H < 0: the scalar code's SignBit tests.
    __m256 in = _mm256_and_ps(_mm256_sub_ps(near, zc), _mm256_sub_ps(zc, far));
    in = _mm256_and_ps(in, _mm256_andnot_ps(fu, _mm256_sub_ps(fu, width)));
    in = _mm256_and_ps(in, _mm256_andnot_ps(fv, _mm256_sub_ps(fv, height)));
    // pixel = int(fv) * W + int(fu) inside (lanes outside convert to
    // INT_MIN and are dropped below).
    const __m256i col = _mm256_cvttps_epi32(fu);
    const __m256i row = _mm256_cvttps_epi32(fv);
    const __m256i pix =
        _mm256_add_epi32(_mm256_mullo_epi32(row, row_stride), col);
    // key = z bits << 32 | point index: interleave the 32-bit halves, then
    // put the four 64-bit keys of each half back in point order.
    const __m256i zbits = _mm256_castps_si256(zc);
    const __m256i lo = _mm256_unpacklo_epi32(idx, zbits);  // points 0 1 | 4 5
    const __m256i hi = _mm256_unpackhi_epi32(idx, zbits);  // points 2 3 | 6 7
    const __m256i keys03 = _mm256_permute2x128_si256(lo, hi, 0x20);
    const __m256i keys47 = _mm256_permute2x128_si256(lo, hi, 0x31);
    const unsigned bits = static_cast<unsigned>(_mm256_movemask_ps(in));
    if (kPacked) {
      const PackEntry& e = kPack.entry[bits];
      _mm256_storeu_si256(
          reinterpret_cast<__m256i*>(pix_out + projected),
          _mm256_permutevar8x32_epi32(
              pix,
              _mm256_load_si256(reinterpret_cast<const __m256i*>(e.pixels))));
      uint64_t* const keys = key_out + projected;
      _mm256_storeu_si256(
          reinterpret_cast<__m256i*>(keys),
          _mm256_permutevar8x32_epi32(
              keys03,
              _mm256_load_si256(reinterpret_cast<const __m256i*>(e.keys03))));
      _mm256_storeu_si256(
          reinterpret_cast<__m256i*>(keys + e.count03),
          _mm256_permutevar8x32_epi32(
              keys47,
              _mm256_load_si256(reinterpret_cast<const __m256i*>(e.keys47))));
      projected += e.count;
    } else {
      _mm256_storeu_si256(
          reinterpret_cast<__m256i*>(pix_out + k),
          _mm256_castps_si256(_mm256_blendv_ps(_mm256_castsi256_ps(minus_one),
                                               _mm256_castsi256_ps(pix), in)));
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(key_out + k), keys03);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(key_out + k + 4), keys47);
      projected += __builtin_popcount(bits);
    }
  }
  *k_done = k;
  return projected;
}
#endif

// Disk splats of one projected block into the key buffer: every pixel of a
// point's bounding box whose centre is within the radius (d² <= r², float)
// takes min(key). Returns the number of points that hit at least one pixel.
// The scalar and AVX2 versions do the same float operations (no FMA) and
// exact integer minima, so their outputs are identical; min() also makes the
// result independent of the order in which points are visited.
int64_t SplatDisksScalar(const ProjectedBlock& blk,
                         int m,
                         int base,
                         float r,
                         int w,
                         int h,
                         uint64_t* kb) {
  const float fw = static_cast<float>(w), fh = static_cast<float>(h);
  const float r2 = r * r;
  int64_t projected = 0;
  for (int k = 0; k < m; ++k) {
    if (!blk.ok[k]) continue;
    const float u = blk.u[k], v = blk.v[k];
    if (!(u > -r - 1 && u < fw + r && v > -r - 1 && v < fh + r)) continue;
    const int j0 = std::max(0, CeilI(v - r));
    const int j1 = std::min(h - 1, FloorI(v + r));
    const int i0 = std::max(0, CeilI(u - r));
    const int i1 = std::min(w - 1, FloorI(u + r));
    const uint64_t key = PackKey(blk.z[k], base + k);
    uint32_t hit = 0;
    for (int j = j0; j <= j1; ++j) {
      const float dy = static_cast<float>(j) - v;
      const float dy2 = dy * dy;
      uint64_t* row = kb + static_cast<size_t>(j) * w;
      for (int c = i0; c <= i1; ++c) {
        const float dx = static_cast<float>(c) - u;
        const uint32_t in = (dx * dx + dy2) <= r2;
        const uint64_t cand = in ? key : kEmptyKey;
        row[c] = std::min(row[c], cand);
        hit |= in;
      }
    }
    projected += hit;
  }
  return projected;
}

#ifdef GEODRIVE_HAVE_AVX2_PATH
// Four columns at a time: a float distance test per lane, then a masked
// 64-bit load / signed compare / masked store.
__attribute__((target("avx2"))) int64_t SplatDisksAvx2(
    const ProjectedBlock& blk,
    int m,
    int base,
    float r,
    int w,
    int h,
    uint64_t* kb) {
  const float fw = static_cast<float>(w), fh = static_cast<float>(h);
  const float r2 = r * r;
  const __m128 vr2 = _mm_set1_ps(r2);
  const __m128i lanes = _mm_setr_epi32(0, 1, 2, 3);
  int64_t projected = 0;
  for (int k = 0; k < m; ++k) {
    if (!blk.ok[k]) continue;
    const float u = blk.u[k], v = blk.v[k];
    if (!(u > -r - 1 && u < fw + r && v > -r - 1 && v < fh + r)) continue;
    const int j0 = std::max(0, CeilI(v - r));
    const int j1 = std::min(h - 1, FloorI(v + r));
    const int i0 = std::max(0, CeilI(u - r));
    const int i1 = std::min(w - 1, FloorI(u + r));
    const __m256i vkey =
        _mm256_set1_epi64x(static_cast<long long>(PackKey(blk.z[k], base + k)));
    const __m128 vu = _mm_set1_ps(u);
    int hit = 0;
    for (int c0 = i0; c0 <= i1; c0 += 4) {
      const __m128i cols = _mm_add_epi32(_mm_set1_epi32(c0), lanes);
      const __m128i in_box = _mm_cmpgt_epi32(_mm_set1_epi32(i1 + 1), cols);
      const __m128 dx = _mm_sub_ps(_mm_cvtepi32_ps(cols), vu);
      const __m128 dx2 = _mm_mul_ps(dx, dx);
      for (int j = j0; j <= j1; ++j) {
        const float dy = static_cast<float>(j) - v;
        const __m128 d2 = _mm_add_ps(dx2, _mm_set1_ps(dy * dy));
        const __m128i in =
            _mm_and_si128(_mm_castps_si128(_mm_cmple_ps(d2, vr2)), in_box);
        const int bits = _mm_movemask_ps(_mm_castsi128_ps(in));
        if (bits == 0) continue;
        hit |= bits;
        const __m256i mask = _mm256_cvtepi32_epi64(in);
        long long* ptr =
            reinterpret_cast<long long*>(kb + static_cast<size_t>(j) * w + c0);
        const __m256i old = _mm256_maskload_epi64(ptr, mask);
        const __m256i upd =
            _mm256_and_si256(_mm256_cmpgt_epi64(old, vkey), mask);
        _mm256_maskstore_epi64(ptr, upd, vkey);
      }
    }
    projected += hit != 0;
  }
  return projected;
}
#endif

// min(key) over the pixels whose centres lie in [u - hx, u + hx] x
// [v - hy, v + hy]; returns whether any pixel was hit.
inline bool SplatBox(float u,
                     float v,
                     float hx,
                     float hy,
                     uint64_t key,
                     int w,
                     int h,
                     uint64_t* kb) {
  const int i0 = std::max(0, CeilI(u - hx));
  const int i1 = std::min(w - 1, FloorI(u + hx));
  const int j0 = std::max(0, CeilI(v - hy));
  const int j1 = std::min(h - 1, FloorI(v + hy));
  for (int j = j0; j <= j1; ++j) {
    uint64_t* row = kb + static_cast<size_t>(j) * w;
    for (int c = i0; c <= i1; ++c) row[c] = std::min(row[c], key);
  }
  return i0 <= i1 && j0 <= j1;
}

// min(key) over the pixels whose centres are within r of (u, v) (as
// SplatDisksScalar); returns whether any pixel was hit.
inline bool SplatDisk(
    float u, float v, float r, uint64_t key, int w, int h, uint64_t* kb) {
  const float r2 = r * r;
  const int j0 = std::max(0, CeilI(v - r));
  const int j1 = std::min(h - 1, FloorI(v + r));
  const int i0 = std::max(0, CeilI(u - r));
  const int i1 = std::min(w - 1, FloorI(u + r));
  uint32_t hit = 0;
  for (int j = j0; j <= j1; ++j) {
    const float dy = static_cast<float>(j) - v;
    const float dy2 = dy * dy;
    uint64_t* row = kb + static_cast<size_t>(j) * w;
    for (int c = i0; c <= i1; ++c) {
      const float dx = static_cast<float>(c) - u;
      const uint32_t in = (dx * dx + dy2) <= r2;
      row[c] = std::min(row[c], in ? key : kEmptyKey);
      hit |= in;
    }
  }
  return hit != 0;
}

// Camera-facing footprints without a minimum radius (the common case: every
// static cloud without surface axes, every moved object): the radius-0 path
// (ProjectPixelsAvx2 where available, then SplatPoints) for the points that
// are not magnified, and a box (SplatBox) for the magnified ones, whose
// projection is recomputed with ProjectBlock's operations. The magnification
// l = fp * scale * focal / z is computed as FootprintHalfExtent does, so the
// output equals SplatFootprints'. `magnified` holds kBlock entries.
int64_t SplatCameraFacingFootprints(const PackedCloud& soa,
                                    int base,
                                    int m,
                                    const ProjectedRange& range,
                                    float max_magnification,
                                    int w,
                                    int h,
                                    ProjectedBlock* blk,
                                    int* magnified,
                                    uint64_t* kb) {
  const FrameProjector& p = range.proj;
  const float fw = static_cast<float>(w), fh = static_cast<float>(h);
  const float* fp = soa.footprint.data() + base;
  const float scale = range.footprint_scale, focal = p.focal;
  const bool enabled = max_magnification > 1.0f;
  int64_t projected = 0;
  int k0 = 0;
#ifdef GEODRIVE_HAVE_AVX2_PATH
  if (UseAvx2())
    projected += ProjectPixelsAvx2<false>(soa, base, m, p, w, fw, fh, blk, &k0);
#endif
  ProjectBlock(soa, base, m, p, blk, k0);
  int num_magnified = 0;
  if (enabled) {
    // [0, k0): blk->ok is the pixel (-1 outside), the key holds z.
    for (int k = 0; k < k0; ++k) {
      const float z = BitsFloat(static_cast<uint32_t>(blk->key[k] >> 32));
      if (!(SignBit(p.near - z) & SignBit(z - p.far))) continue;
      if (!(fp[k] * scale * focal / z > 1.05f)) continue;
      magnified[num_magnified++] = k;
      if (blk->ok[k] >= 0) --projected;  // counted by ProjectPixelsAvx2
      blk->ok[k] = -1;
    }
    // [k0, m): ProjectBlock's u, v, z, ok.
    for (int k = k0; k < m; ++k) {
      if (!blk->ok[k] || !(fp[k] * scale * focal / blk->z[k] > 1.05f)) continue;
      magnified[num_magnified++] = k;
      blk->ok[k] = 0;
    }
  }
  projected += SplatPoints(blk, 0, 0, k0, m, base, w, fw, fh, kb);
  const float cap = 0.5f * max_magnification;
  const float* px = soa.x.data() + base;
  const float* py = soa.y.data() + base;
  const float* pz = soa.z.data() + base;
  for (int j = 0; j < num_magnified; ++j) {
    const int k = magnified[j];
    // ProjectBlock's operations, for this point.
    const float x = px[k], y = py[k], wz = pz[k];
    const float zc = p.r[6] * x + p.r[7] * y + p.r[8] * wz + p.t[2];
    const float xc = p.r[0] * x + p.r[1] * y + p.r[2] * wz + p.t[0];
    const float yc = p.r[3] * x + p.r[4] * y + p.r[5] * wz + p.t[1];
    const float inv = 1.0f / zc;
    const float u = p.fx * xc * inv + p.cx, v = p.fy * yc * inv + p.cy;
    const float l = fp[k] * scale * focal / zc;
    const float half = std::max(0.5f, std::min(0.5f * l, cap));
    if (!(u > -half - 1 && u < fw + half && v > -half - 1 && v < fh + half))
      continue;
    projected += SplatBox(u, v, half, half, PackKey(zc, base + k), w, h, kb);
  }
  return projected;
}

// Footprint splats of one projected block (render/footprint.h). Point k's
// half-extents come from its surface axes when it has them (fp_axes[6k..6k+5]
// not all zero: projected through the Jacobian of the projection at the
// point), otherwise from its camera-facing footprint fp[k] * scale. Unless
// magnified (a half-extent > 0.525) the point takes the single pixel that
// contains its projection (as SplatPoints), or the disk of radius r_min > 0
// (as SplatDisksScalar); magnified, the box of its half-extents capped at
// max_magnification / 2 (at least r_min). Scalar: magnified points are few
// next to the one-pixel majority.
int64_t SplatFootprints(const ProjectedBlock& blk,
                        int m,
                        int base,
                        const float* fp,
                        const float* fp_axes,
                        float scale,
                        const FrameProjector& proj,
                        float r_min,
                        float max_magnification,
                        int w,
                        int h,
                        uint64_t* kb) {
  const float fw = static_cast<float>(w), fh = static_cast<float>(h);
  const float cap = 0.5f * max_magnification;
  const bool enabled = max_magnification > 1.0f;
  const float* r = proj.r;
  int64_t projected = 0;
  for (int k = 0; k < m; ++k) {
    if (!blk.ok[k]) continue;
    const float u = blk.u[k], v = blk.v[k], z = blk.z[k];
    const uint64_t key = PackKey(z, base + k);
    float hx = 0, hy = 0;
    const float* e = fp_axes ? fp_axes + 6 * k : nullptr;
    if (e && (e[0] != 0 || e[1] != 0 || e[2] != 0 || e[3] != 0 || e[4] != 0 ||
              e[5] != 0)) {
      // Pixel vector of a displacement d (camera frame) at the point:
      // (fx d_x - (u - cx) d_z) / z, (fy d_y - (v - cy) d_z) / z.
      const float inv = 1.0f / z, du = u - proj.cx, dv = v - proj.cy;
      for (int a = 0; a < 2; ++a) {
        const float* d = e + 3 * a;
        const float cx_ = r[0] * d[0] + r[1] * d[1] + r[2] * d[2];
        const float cy_ = r[3] * d[0] + r[4] * d[1] + r[5] * d[2];
        const float cz_ = r[6] * d[0] + r[7] * d[1] + r[8] * d[2];
        hx += 0.5f * std::abs((proj.fx * cx_ - du * cz_) * inv);
        hy += 0.5f * std::abs((proj.fy * cy_ - dv * cz_) * inv);
      }
    } else {
      hx = hy =
          FootprintHalfExtent(fp[k] * scale, proj.focal, z, max_magnification);
    }
    if (!enabled || !(std::max(hx, hy) > 0.525f)) {
      if (r_min > 0) {
        if (u > -r_min - 1 && u < fw + r_min && v > -r_min - 1 &&
            v < fh + r_min)
          projected += SplatDisk(u, v, r_min, key, w, h, kb);
        continue;
      }
      const float fu = u + 0.5f, fv = v + 0.5f;
      if (!(fu >= 0 && fu < fw && fv >= 0 && fv < fh)) continue;
      uint64_t* slot =
          kb + static_cast<size_t>(fv) * w + static_cast<size_t>(fu);
      *slot = std::min(*slot, key);
      ++projected;
      continue;
    }
    // At least 0.5: the box holds the pixel centre nearest the projection.
    hx = std::max(std::max(r_min, 0.5f), std::min(hx, cap));
    hy = std::max(std::max(r_min, 0.5f), std::min(hy, cap));
    if (!(u > -hx - 1 && u < fw + hx && v > -hy - 1 && v < fh + hy)) continue;
    projected += SplatBox(u, v, hx, hy, key, w, h, kb);
  }
  return projected;
}

int64_t SplatDisks(const ProjectedBlock& blk,
                   int m,
                   int base,
                   float r,
                   int w,
                   int h,
                   uint64_t* kb) {
#ifdef GEODRIVE_HAVE_AVX2_PATH
  if (UseAvx2()) return SplatDisksAvx2(blk, m, base, r, w, h, kb);
#endif
  return SplatDisksScalar(blk, m, base, r, w, h, kb);
}

// Z-buffer resolve: key -> RGB, depth, mask and optionally the point index;
// every key is left empty. Colours are read at the key's low half + 1:
// point i's RGBX word is at [i + 1], and the empty key's low half (0xffffffff,
// -1 as a signed 32-bit index) reads [0], black, so no pixel needs a validity
// test to read its colour. Returns the number of valid pixels. The AVX2 version
// writes the same bytes.
struct ZResolveArgs {
  uint64_t* keys;
  size_t npix;
  const uint32_t* colors;  // RGBX words, black at [0], point i at [i + 1]
  uint8_t* rgb;
  uint32_t* depth;  // float bits
  uint8_t* mask;
  int32_t* index;  // nullptr: not wanted
};

inline uint32_t ColorOfKey(const uint32_t* colors, uint64_t key) {
  // The low half as a signed index from colors + 1: -1 for an empty key
  // (point indices are < 2^31), and x86 loads it sign-extended in one step.
  return (colors + 1)[static_cast<int32_t>(static_cast<uint32_t>(key))];
}

int64_t ResolveZScalar(const ZResolveArgs& a, size_t begin) {
  int64_t valid = 0;
  for (size_t p = begin; p < a.npix; ++p) {
    const uint64_t key = a.keys[p];
    a.keys[p] = kEmptyKey;
    const uint32_t is_valid = key != kEmptyKey;
    const uint32_t c = ColorOfKey(a.colors, key);
    // Bytes 0..2 of the little-endian RGBX word are R, G, B.
    a.rgb[3 * p] = static_cast<uint8_t>(c);
    a.rgb[3 * p + 1] = static_cast<uint8_t>(c >> 8);
    a.rgb[3 * p + 2] = static_cast<uint8_t>(c >> 16);
    a.depth[p] = is_valid ? static_cast<uint32_t>(key >> 32) : 0u;
    a.mask[p] = static_cast<uint8_t>(0u - is_valid);
    if (a.index) {
      a.index[p] = is_valid ? static_cast<int32_t>(key & 0xffffffffu) : -1;
    }
    valid += is_valid;
  }
  return valid;
}

#ifdef GEODRIVE_HAVE_AVX2_PATH
// Mask bytes of eight pixels for each 8-bit set of valid flags (bit i: pixel
// i is valid -> byte i is 0xff).
struct MaskByteTable {
  uint64_t bytes[256];
  constexpr MaskByteTable() : bytes() {
    for (int v = 0; v < 256; ++v) {
      for (int i = 0; i < 8; ++i)
        if (v >> i & 1) bytes[v] |= uint64_t{0xff} << (8 * i);
    }
  }
};
constexpr MaskByteTable kMaskBytes;

// Eight pixels: the keys split into index and depth halves for the depth,
// mask and index outputs (a group of eight empty pixels only writes zeros);
// the colours read per pixel (scalar loads: on AMD Zen 4/5 a vpgatherdd took
// 60 % of this loop) and stored as overlapping RGBX words, each X byte
// overwritten by the next pixel's R, so `rgb` must have 25 writable bytes.
// Every key is left empty. Returns the number of valid pixels.
__attribute__((target("avx2"))) inline int Resolve8Avx2(uint64_t* kp,
                                                        const uint32_t* colors,
                                                        uint8_t* rgb,
                                                        uint32_t* depth,
                                                        uint8_t* mask,
                                                        int32_t* index) {
  const __m256i even_odd = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
  const __m256i empty_hi = _mm256_set1_epi32(0x7fffffff);
  const __m256i k0 = _mm256_loadu_si256(reinterpret_cast<__m256i*>(kp));
  const __m256i k1 = _mm256_loadu_si256(reinterpret_cast<__m256i*>(kp + 4));
  const __m256i s0 = _mm256_permutevar8x32_epi32(k0, even_odd);
  const __m256i s1 = _mm256_permutevar8x32_epi32(k1, even_odd);
  const __m256i hi = _mm256_permute2x128_si256(s0, s1, 0x31);  // z bits
  const __m256i invalid = _mm256_cmpeq_epi32(hi, empty_hi);
  const unsigned valid_bits =
      ~static_cast<unsigned>(_mm256_movemask_ps(_mm256_castsi256_ps(invalid))) &
      0xffu;
  if (valid_bits == 0) {
    // Eight empty pixels (sky, gaps between sparse points): black, zero
    // depth and mask; their keys are already empty.
    const __m128i zero = _mm_setzero_si128();
    _mm_storeu_si128(reinterpret_cast<__m128i*>(rgb), zero);
    _mm_storel_epi64(reinterpret_cast<__m128i*>(rgb + 16), zero);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(depth),
                        _mm256_setzero_si256());
    _mm_storel_epi64(reinterpret_cast<__m128i*>(mask), zero);
    if (index) {
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(index), invalid);
    }
    return 0;
  }
  for (int i = 0; i < 8; ++i) {
    const uint32_t c = ColorOfKey(colors, kp[i]);
    std::memcpy(rgb + 3 * i, &c, 4);
  }
  const __m256i empty = _mm256_set1_epi64x(static_cast<long long>(kEmptyKey));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(kp), empty);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(kp + 4), empty);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(depth),
                      _mm256_andnot_si256(invalid, hi));
  if (index) {
    const __m256i lo = _mm256_permute2x128_si256(s0, s1, 0x20);  // indices
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(index),
                        _mm256_or_si256(lo, invalid));
  }
  // The eight mask bytes from the eight valid bits, through a table.
  std::memcpy(mask, &kMaskBytes.bytes[valid_bits], 8);
  return __builtin_popcount(valid_bits);
}

// Pixels per streamed block: a whole number of 64-byte lines of every output
// (RGB 192 bytes, depth 256, mask 64).
constexpr size_t kStreamBlock = 64;

// Copies `bytes` (a multiple of 32) from the aligned `src` to the aligned
// `dst` with streaming stores.
__attribute__((target("avx2"))) inline void StreamOut(void* dst,
                                                      const void* src,
                                                      size_t bytes) {
  for (size_t b = 0; b < bytes; b += 32) {
    _mm256_stream_si256(
        reinterpret_cast<__m256i*>(static_cast<uint8_t*>(dst) + b),
        _mm256_load_si256(reinterpret_cast<const __m256i*>(
            static_cast<const uint8_t*>(src) + b)));
  }
}

// The AVX2 resolve from pixel 0. With `stream`, blocks of kStreamBlock pixels
// are resolved into a staging block in L1 and written out in whole lines
// with streaming stores (the outputs must be 32-byte aligned; they then are at
// every block); the keys stay cached for the next frame. The bytes are those
// of the ordinary stores.
__attribute__((target("avx2"))) int64_t ResolveZAvx2(const ZResolveArgs& a,
                                                     bool stream) {
  // Locals, so that the byte stores below do not make the compiler reload
  // the arguments (uint8_t stores may alias anything).
  uint64_t* const keys = a.keys;
  const uint32_t* const colors = a.colors;
  uint8_t* const rgb_out = a.rgb;
  uint32_t* const depth_out = a.depth;
  uint8_t* const mask_out = a.mask;
  int32_t* const index_out = a.index;
  const size_t npix = a.npix;
  int64_t valid = 0;
  size_t p = 0;
  const auto aligned = [](const void* ptr) {
    return reinterpret_cast<uintptr_t>(ptr) % 32 == 0;
  };
  if (stream && aligned(rgb_out) && aligned(depth_out) && aligned(mask_out)) {
    alignas(32) uint8_t rgb_stage[3 * kStreamBlock + 32];
    alignas(32) uint32_t depth_stage[kStreamBlock];
    alignas(32) uint8_t mask_stage[kStreamBlock];
    for (; p + kStreamBlock <= npix; p += kStreamBlock) {
      for (size_t q = 0; q < kStreamBlock; q += 8) {
        valid += Resolve8Avx2(keys + p + q, colors, rgb_stage + 3 * q,
                              depth_stage + q, mask_stage + q,
                              index_out ? index_out + p + q : nullptr);
      }
      StreamOut(rgb_out + 3 * p, rgb_stage, 3 * kStreamBlock);
      StreamOut(depth_out + p, depth_stage, 4 * kStreamBlock);
      StreamOut(mask_out + p, mask_stage, kStreamBlock);
    }
    // Streaming stores are weakly ordered: make them visible before the
    // ordinary stores of the tail and before any other thread reads them.
    _mm_sfence();
  }
  // The last 4-byte RGB store reaches 1 byte past the 8 pixels: stop while 2
  // more pixels remain, the scalar tail does the rest.
  for (; p + 10 <= npix; p += 8) {
    valid += Resolve8Avx2(keys + p, colors, rgb_out + 3 * p, depth_out + p,
                          mask_out + p, index_out ? index_out + p : nullptr);
  }
  return valid + ResolveZScalar(a, p);
}
#endif

int64_t ResolveZBuffer(const ZResolveArgs& a, bool stream) {
#ifdef GEODRIVE_HAVE_AVX2_PATH
  if (UseAvx2()) return ResolveZAvx2(a, stream);
#endif
  return ResolveZScalar(a, 0);
}

// Calls fn(base, m) for consecutive blocks [base, base + m) of the range,
// m <= kBlock, that hold only points of groups `culled` does not mark
// (indexed from the range's first group; empty = none culled).
template <typename Fn>
void ForEachDrawnBlock(const ProjectedRange& range,
                       const std::vector<uint8_t>& culled,
                       Fn&& fn) {
  const int first_group = range.begin / kCullGroup;
  const auto is_culled = [&](int i) {
    return !culled.empty() && culled[i / kCullGroup - first_group];
  };
  int base = range.begin;
  while (base < range.end) {
    if (is_culled(base)) {
      base = std::min(range.end, (base / kCullGroup + 1) * kCullGroup);
      continue;
    }
    int end = base;
    while (end < range.end && end - base < kBlock && !is_culled(end))
      end = std::min(range.end, (end / kCullGroup + 1) * kCullGroup);
    const int m = std::min(end, base + kBlock) - base;
    fn(base, m);
    base += m;
  }
}

// Radius 0 over one range, a block of at most kBlock points at a time
// (ProjectPixelsAvx2 where available, ProjectBlock for the rest, then
// SplatPoints), skipping the groups of points that `culled` marks (indexed
// from the range's first group). Returns the number of points in the image.
int64_t SplatRangeRadiusZero(const PackedCloud& soa,
                             const ProjectedRange& range,
                             const std::vector<uint8_t>& culled,
                             int w,
                             int h,
                             ProjectedBlock* blk,
                             uint64_t* kb) {
  const float fw = static_cast<float>(w), fh = static_cast<float>(h);
  int64_t projected = 0;
  ForEachDrawnBlock(range, culled, [&](int base, int m) {
    int k0 = 0, packed = 0;
#ifdef GEODRIVE_HAVE_AVX2_PATH
    if (UseAvx2()) {
      packed = static_cast<int>(ProjectPixelsAvx2<true>(
          soa, base, m, range.proj, w, fw, fh, blk, &k0));
      projected += packed;
    }
#endif
    ProjectBlock(soa, base, m, range.proj, blk, k0);
    projected += SplatPoints(blk, packed, k0, k0, m, base, w, fw, fh, kb);
  });
  return projected;
}

}  // namespace

// Z-buffer. Each pixel keeps the minimum key (z, index), so among equal depths
// the smallest index wins, whatever the processing order or thread count.
GEODRIVE_HOT_CLONES
void RenderZBuffer(const PackedCloud& soa,
                   const std::vector<ProjectedRange>& ranges,
                   const RenderOptions& options,
                   bool stream_outputs,
                   Scratch* scratch,
                   RenderedFrame* frame) {
  const int w = options.width, h = options.height;
  const size_t npix = static_cast<size_t>(w) * h;
  // One 64-bit key per pixel (z bits << 32 | point index) and one spare slot
  // that absorbs the writes of points outside the image (branch-free splat).
  // The resolve pass below leaves every key empty again, so the buffer is
  // only cleared when its size changes.
  std::vector<uint64_t>& keys = scratch->zkeys;
  if (keys.size() != npix + 1) keys.assign(npix + 1, kEmptyKey);
  uint64_t* kb = keys.data();
  ProjectedBlock& blk = scratch->block;
  int64_t projected = 0;
  const float r = static_cast<float>(options.radius_px);
  const float max_magnification =
      static_cast<float>(options.max_footprint_magnification);
  std::vector<uint8_t>& culled = scratch->culled;
  for (const ProjectedRange& range : ranges) {
    const bool footprints = range.footprint_scale > 0 && !soa.footprint.empty();
    // The groups of this range that lie outside the view grown by the
    // largest half-extent a point of the path draws, plus one pixel: a disk
    // of radius r is drawn from u > -r - 1, a footprint box of half-extent
    // at most max(r, 0.5, max_magnification / 2) likewise.
    culled.clear();
    if (!soa.cull_box.empty() && UseCulling() && range.begin < range.end) {
      const double reach =
          footprints ? std::max({static_cast<double>(r), 0.5,
                                 0.5 * static_cast<double>(max_magnification)})
                     : static_cast<double>(r);
      const double margin = !footprints && r <= 0 ? 0.0 : reach + 1.0;
      const int g_begin = range.begin / kCullGroup,
                g_end = (range.end - 1) / kCullGroup + 1;
      culled.resize(g_end - g_begin);
      CullGroups(soa, MakeFrustumPlanes(range.proj, w, h, margin), g_begin,
                 g_end, culled.data());
    }
    if (!footprints && r <= 0) {
      projected += SplatRangeRadiusZero(soa, range, culled, w, h, &blk, kb);
      continue;
    }
    ForEachDrawnBlock(range, culled, [&](int base, int m) {
      if (footprints) {
        ProjectBlock(soa, base, m, range.proj, &blk);
        // Camera-facing footprints only (no surface axes) and no minimum
        // radius: the magnification of every point in one vectorised pass,
        // computed as FootprintHalfExtent does (same operations, so the
        // decisions are the per-point ones); the points that are not
        // magnified take their single pixel as in the radius-0 path, the
        // magnified ones (few) a box.
        bool any_axis = false;
        if (!soa.footprint_axes.empty()) {
          const float* e = soa.footprint_axes.data() + 6 * base;
          for (int k = 0; k < 6 * m; ++k) any_axis |= e[k] != 0.0f;
        }
        if (r <= 0 && !any_axis) {
          projected += SplatCameraFacingFootprints(
              soa, base, m, range, max_magnification, w, h, &blk,
              scratch->magnified.data(), kb);
          return;
        }
        projected += SplatFootprints(
            blk, m, base, soa.footprint.data() + base,
            soa.footprint_axes.empty() ? nullptr
                                       : soa.footprint_axes.data() + 6 * base,
            range.footprint_scale, range.proj, r, max_magnification, w, h, kb);
        return;
      }
      ProjectBlock(soa, base, m, range.proj, &blk);
      projected += SplatDisks(blk, m, base, r, w, h, kb);
    });
  }
  frame->num_projected = projected;

  // Resolve, and clear the keys for the next frame. The per-pixel point index
  // is kept only when something reads it.
  std::vector<int32_t>& index = scratch->index;
  const bool need_index =
      options.hole_fill || options.output_index || options.output_instance;
  if (need_index) index.resize(npix);
  ZResolveArgs args{kb,
                    npix,
                    soa.rgbx.data(),
                    frame->rgb.ptr<uint8_t>(),
                    reinterpret_cast<uint32_t*>(frame->depth.ptr<float>()),
                    frame->mask.ptr<uint8_t>(),
                    need_index ? index.data() : nullptr};
  frame->num_valid = ResolveZBuffer(args, stream_outputs);
}

// The outputs of the frames of one call, in bytes, from which the resolve
// writes them with streaming stores (RenderZBuffer). Ordinary stores first
// read each output line into the cache (read for ownership): on machine B
// of docs/PERFORMANCE.md (2-vCPU Xeon), 8.1 GB/s of 32-byte stores to a 69 MB
// buffer against 19-21 GB/s streamed. Below this size the outputs may still
// be in cache when the caller reads them, so they are stored normally.
constexpr uint64_t kStreamOutputBytes = uint64_t{32} << 20;

bool StreamOutputs(const RenderOptions& options, int num_frames) {
  // Hole filling and the float RGB output read the frame right after the
  // resolve: keep it in cache for them.
  return options.mode == RenderMode::kZBuffer && !options.hole_fill &&
         !options.output_float_rgb &&
         static_cast<uint64_t>(num_frames) * RenderedFrameBytes(options) >=
             kStreamOutputBytes;
}

// Why the margins are safe. The per-point test passes a point when, in
// float, near < zc < far, 0 <= fu < W and 0 <= fv < H, with
//   zc = ((r6 x + r7 y) + r8 z) + t2   (xc, yc likewise)
//   fu = ((fx xc) (1 / zc) + cx) + 0.5  (fv likewise).
// Each float sum or product there is within 4 eps (eps = 2^-24) of the exact
// value relative to the sum of its terms' magnitudes: |zc_float - zc| <=
// 4 eps Mz with Mz = |r6| |x| + |r7| |y| + |r8| |z| + |t2|. A passing point
// has zc_float > near >= 0, and for zc > 0, fu < 0 exactly when
//   L = fx xc + (cx + 0.5) zc < 0;
// the float fu differs from L / zc by at most about 9 eps (|fx| Mx + (|cx| +
// 0.5) Mz) / zc. L is linear in the point, so its maximum over a box is
//   b + sum_j (a_j ctr_j + |a_j| hw_j)   (centre ctr, half-widths hw),
// and Mx, Mz are at most sum_j |r_ij| (|ctr_j| + hw_j) + |t_i| over the box.
// A box whose maximum of L is below -1e-5 (|fx| Mx + (|cx| + 0.5) Mz), 20
// times the rounding, holds no point with fu >= 0. The near and far planes,
// the image's other sides (fu >= W: fx xc + (cx + 0.5 - W) zc >= 0) and the
// rows are alike. Each plane is one test: b + sum_j (a_j ctr_j + |a_j| hw_j +
// m_j (|ctr_j| + hw_j)) <= 0, the margin's weights m_j folded in, computed in
// double from the projector's floats.
FrustumPlanes MakeFrustumPlanes(const FrameProjector& p,
                                int w,
                                int h,
                                double margin_px) {
  constexpr double kMargin = 1e-5;
  FrustumPlanes out;
  const auto row = [&](int i, int j) { return double{p.r[3 * i + j]}; };
  const double t2 = p.t[2];
  int n = 0;
  // Sets plane n from the linear function a . X + b and the margin's weights
  // (margin = kMargin (m . |X| + m0)): a box is outside the view when, for
  // one plane, its maximum of a . X + b plus the margin is <= 0.
  const auto add = [&](const double* a, double b, const double* m, double m0) {
    for (int j = 0; j < 3; ++j) {
      out.a[n][j] = a[j];
      out.abs_a[n][j] = std::abs(a[j]);
      out.m[n][j] = kMargin * m[j];
    }
    out.b[n] = b + kMargin * m0;
    ++n;
  };
  double a[3], m[3];
  // Near: max(zc) - near + margin <= 0. Far: far - min(zc) + margin <= 0.
  for (int j = 0; j < 3; ++j) {
    a[j] = row(2, j);
    m[j] = std::abs(row(2, j));
  }
  add(a, t2 - p.near, m, std::abs(t2));
  for (double& v : a) v = -v;
  add(a, p.far - t2, m, std::abs(t2));
  // Columns (axis 0: fx, cx, W) and rows (axis 1: fy, cy, H), the image
  // grown by `margin_px` (M) on every side. Side 0, before the first pixel:
  // f x + (c + 0.5 + M) z < 0; side 1, past the last one:
  // f x + (c + 0.5 - size - M) z >= 0.
  for (int axis = 0; axis < 2; ++axis) {
    const double f = axis == 0 ? p.fx : p.fy;
    const double c = axis == 0 ? p.cx : p.cy;
    const double size = axis == 0 ? w : h;
    const double t = p.t[axis];
    for (int side = 0; side < 2; ++side) {
      const double shift = c + 0.5 + (side ? -size - margin_px : margin_px);
      const double weight = std::abs(c) + 0.5 + margin_px + (side ? size : 0.0);
      const double sign = side ? -1.0 : 1.0;
      for (int j = 0; j < 3; ++j) {
        a[j] = sign * (f * row(axis, j) + shift * row(2, j));
        m[j] =
            std::abs(f) * std::abs(row(axis, j)) + weight * std::abs(row(2, j));
      }
      add(a, sign * (f * t + shift * t2), m,
          std::abs(f) * std::abs(t) + weight * std::abs(t2));
    }
  }
  return out;
}

GEODRIVE_HOT_CLONES
void CullGroups(const PackedCloud& soa,
                const FrustumPlanes& planes,
                int g_begin,
                int g_end,
                uint8_t* culled) {
  const size_t groups = soa.cull_box.size() / 9;
  const double* box = soa.cull_box.data();
  const double* ctr[3] = {box, box + 2 * groups, box + 4 * groups};
  const double* hw[3] = {box + groups, box + 3 * groups, box + 5 * groups};
  const double* mag[3] = {box + 6 * groups, box + 7 * groups, box + 8 * groups};
  const int count = g_end - g_begin;
  for (int k = 0; k < count; ++k) culled[k] = 0;
  // Plane by plane, all groups at a time (the inner loop vectorises).
  for (int n = 0; n < 6; ++n) {
    const double b = planes.b[n];
    const double* a = planes.a[n];
    const double* abs_a = planes.abs_a[n];
    const double* m = planes.m[n];
    for (int k = 0; k < count; ++k) {
      const int g = g_begin + k;
      double s = b;
      for (int j = 0; j < 3; ++j)
        s += a[j] * ctr[j][g] + abs_a[j] * hw[j][g] + m[j] * mag[j][g];
      culled[k] |= static_cast<uint8_t>(s <= 0);
    }
  }
}

// One hole-filling pass; returns the number of pixels filled.
int64_t HoleFillPass(const RenderOptions& options,
                     std::vector<int32_t>* index,
                     RenderedFrame* frame) {
  const int w = options.width, h = options.height;
  const cv::Mat mask0 = frame->mask.clone();
  const cv::Mat depth0 = frame->depth.clone();
  const cv::Mat rgb0 = frame->rgb.clone();
  const std::vector<int32_t> index0 = *index;
  int64_t filled = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (mask0.at<uint8_t>(y, x) != kMaskInvalid) continue;
      int count = 0, best_x = -1, best_y = -1;
      float best_z = 0;
      int32_t best_idx = 0;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = x + dx, ny = y + dy;
          if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= w || ny >= h)
            continue;
          if (mask0.at<uint8_t>(ny, nx) == kMaskInvalid) continue;
          ++count;
          const float z = depth0.at<float>(ny, nx);
          const int32_t idx = index0[static_cast<size_t>(ny) * w + nx];
          if (best_x < 0 || z < best_z || (z == best_z && idx < best_idx)) {
            best_x = nx, best_y = ny, best_z = z, best_idx = idx;
          }
        }
      }
      if (count < options.hole_fill_min_neighbors) continue;
      frame->rgb.at<cv::Vec3b>(y, x) = rgb0.at<cv::Vec3b>(best_y, best_x);
      frame->depth.at<float>(y, x) = best_z;
      frame->mask.at<uint8_t>(y, x) = kMaskFilled;
      (*index)[static_cast<size_t>(y) * w + x] = best_idx;
      ++filled;
    }
  }
  return filled;
}

}  // namespace renderer_internal
}  // namespace geodrive

#include "render/renderer.h"

#include <omp.h>

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <sstream>

#include "geometry/util/status.h"

namespace geodrive {
namespace {

constexpr int kMaxImageSide = 16384;
constexpr int kMaxPointsPerPixel = 32;
// The per-frame camera in float, with the pixel-centre offset folded into cx,
// cy so that pixel (i, j) has its centre at (i, j) in the shifted coordinates.
struct FrameProjector {
  float r[9];
  float t[3];
  float fx, fy, cx, cy;
  float near, far;

  FrameProjector(const PinholeCamera& camera,
                 const Rigid3d& cam_from_world,
                 const RenderOptions& options)
      : FrameProjector(camera,
                       cam_from_world.rotation.normalized().toRotationMatrix(),
                       cam_from_world.translation,
                       options) {}
  // x_cam = linear * x + translation (a rotation, or a rotation times a scale
  // for moving point sets).
  FrameProjector(const PinholeCamera& camera,
                 const Eigen::Matrix3d& linear,
                 const Eigen::Vector3d& translation,
                 const RenderOptions& options) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j)
        r[3 * i + j] = static_cast<float>(linear(i, j));
      t[i] = static_cast<float>(translation[i]);
    }
    const double offset =
        options.pixel_convention == PixelConvention::kPixelCenter ? 0.5 : 0.0;
    fx = static_cast<float>(camera.fx);
    fy = static_cast<float>(camera.fy);
    cx = static_cast<float>(camera.cx - offset);
    cy = static_cast<float>(camera.cy - offset);
    near = static_cast<float>(std::max(options.near, 0.0));
    far = static_cast<float>(
        std::min<double>(options.far, std::numeric_limits<float>::max()));
  }
};

// A run of packed points [begin, end) seen through one projector: the static
// cloud through the camera, a moving set through camera * world_from_set.
struct ProjectedRange {
  int begin = 0, end = 0;
  FrameProjector proj;
};

// Points are projected in blocks into small arrays (a loop the compiler
// vectorises), then splatted in index order.
constexpr int kBlock = 512;
struct ProjectedBlock {
  alignas(64) float u[kBlock];
  alignas(64) float v[kBlock];
  alignas(64) float z[kBlock];
  alignas(64) int32_t ok[kBlock];
};

// Bits of a float; for positive floats they are monotonic in the value.
inline uint32_t FloatBits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, sizeof(u));
  return u;
}
inline float BitsFloat(uint32_t u) {
  float f;
  std::memcpy(&f, &u, sizeof(f));
  return f;
}

// floor/ceil to int for |x| < 2^20 (all callers: pixel coordinates within a few
// hundred pixels of an image of at most 16384): truncation of a positive
// double, no libm call (baseline x86-64 has no roundss).
constexpr double kFloorOffset = 1048576.0;
inline int FloorI(float x) {
  return static_cast<int>(static_cast<double>(x) + kFloorOffset) - 1048576;
}
inline int CeilI(float x) {
  return 1048576 - static_cast<int>(kFloorOffset - static_cast<double>(x));
}

inline uint32_t SignBit(float f) {
  uint32_t u;
  std::memcpy(&u, &f, sizeof(u));
  return u >> 31;
}

const Color3u8 kDefaultColor(200, 200, 200);

// The cloud as the kernels read it: positions as structure of arrays, colours
// in the form the mode needs, instance ids when asked for. Built once per
// RenderFramesInto / RenderFramesWithMovingSets call.
struct PackedCloud {
  std::vector<float> x, y, z;
  std::vector<uint32_t> rgbx;     // zbuffer: RGBX words + black sentinel at [n]
  std::vector<float> colors01;    // soft: RGB in [0, 1]
  std::vector<int32_t> instance;  // output_instance: id per point (-1 = none)
                                  // + sentinel -1 at [n]
  size_t size() const { return x.size(); }

  // Capacity for n points (avoids re-allocating when sets are appended).
  void Reserve(size_t n, const RenderOptions& options) {
    x.reserve(n);
    y.reserve(n);
    z.reserve(n);
    if (options.mode == RenderMode::kZBuffer)
      rgbx.reserve(n + 1);
    else
      colors01.reserve(3 * n);
    if (options.output_instance) instance.reserve(n + 1);
  }

  // Makes points [offset, offset + cloud.size()) the given cloud's, dropping
  // anything after them.
  void Assign(size_t offset,
              const PointCloud& cloud,
              const RenderOptions& options) {
    const size_t m = cloud.size(), n = offset + m;
    x.resize(n);
    y.resize(n);
    z.resize(n);
    for (size_t i = 0; i < m; ++i) {
      x[offset + i] = cloud.positions[i][0];
      y[offset + i] = cloud.positions[i][1];
      z[offset + i] = cloud.positions[i][2];
    }
    const bool has_colors = cloud.HasColors();
    if (options.mode == RenderMode::kZBuffer) {
      rgbx.resize(n + 1);
      for (size_t i = 0; i < m; ++i) {
        const Color3u8& c = has_colors ? cloud.colors[i] : kDefaultColor;
        rgbx[offset + i] =
            uint32_t{c[0]} | (uint32_t{c[1]} << 8) | (uint32_t{c[2]} << 16);
      }
      rgbx[n] = 0;  // little-endian RGBX black: empty pixels read it
    } else {
      colors01.resize(3 * n);
      for (size_t i = 0; i < m; ++i) {
        const Color3u8& c = has_colors ? cloud.colors[i] : kDefaultColor;
        for (int ch = 0; ch < 3; ++ch)
          colors01[3 * (offset + i) + ch] = c[ch] / 255.0f;
      }
    }
    if (options.output_instance) {
      instance.resize(n + 1);
      const bool has_ids = cloud.HasInstanceIds();
      for (size_t i = 0; i < m; ++i)
        instance[offset + i] = has_ids ? cloud.instance_ids[i] : -1;
      instance[n] = -1;  // sentinel: pixels without a point
    }
  }
};

// Projects points [base, base + n) to shifted pixel coordinates; ok = near < z
// < far.
inline void ProjectBlock(const PackedCloud& soa,
                         int base,
                         int n,
                         const FrameProjector& p,
                         ProjectedBlock* out) {
  const float* __restrict px = soa.x.data() + base;
  const float* __restrict py = soa.y.data() + base;
  const float* __restrict pz = soa.z.data() + base;
  float* __restrict ou = out->u;
  float* __restrict ov = out->v;
  float* __restrict oz = out->z;
  int32_t* __restrict ook = out->ok;
  const float r0 = p.r[0], r1 = p.r[1], r2 = p.r[2], r3 = p.r[3], r4 = p.r[4],
              r5 = p.r[5];
  const float r6 = p.r[6], r7 = p.r[7], r8 = p.r[8], t0 = p.t[0], t1 = p.t[1],
              t2 = p.t[2];
  const float fx = p.fx, fy = p.fy, cx = p.cx, cy = p.cy, near = p.near,
              far = p.far;
  for (int k = 0; k < n; ++k) {
    const float x = px[k], y = py[k], w = pz[k];
    const float zc = r6 * x + r7 * y + r8 * w + t2;
    const float xc = r0 * x + r1 * y + r2 * w + t0;
    const float yc = r3 * x + r4 * y + r5 * w + t1;
    // near < zc < far from the sign bits of (near - zc) and (zc - far): no
    // float compares, so the loop vectorises without -fno-trapping-math. inv
    // may be inf/NaN where !ok (unused).
    const int32_t ok =
        static_cast<int32_t>((SignBit(near - zc) & SignBit(zc - far)));
    const float inv = 1.0f / zc;
    ou[k] = fx * xc * inv + cx;
    ov[k] = fy * yc * inv + cy;
    oz[k] = zc;
    ook[k] = ok;
  }
}

// Soft-mode compositing state, one entry per pixel (structure of arrays,
// padded by 8 so that 8-wide rows never leave the buffers).
struct SoftState {
  std::vector<float> acc_r, acc_g, acc_b;  // Σ_k w_k Π_{j<k} (1 - w_j) c_k
  std::vector<float> cum;                  // Π_j (1 - w_j), 1 when empty
  std::vector<int32_t> count;              // points composited so far (<= K)
  std::vector<int32_t> first;              // front-most point, -1 = none
  void Reset(size_t npix) {
    const size_t n = npix + 8;
    acc_r.assign(n, 0.0f);
    acc_g.assign(n, 0.0f);
    acc_b.assign(n, 0.0f);
    cum.assign(n, 1.0f);
    count.assign(n, 0);
    first.assign(n, -1);
  }
};

// Scratch memory reused across the frames a thread renders.
struct Scratch {
  ProjectedBlock block;
  SoftState soft;                 // soft: compositing state per pixel
  std::vector<uint64_t> zkeys;    // zbuffer: min key per pixel (+1 spare slot)
  std::vector<float> pu, pv, pz;  // soft: projected coordinates per point
  std::vector<int32_t> cand, order, order_tmp;   // soft: visible points
  std::vector<uint32_t> zbits, zbits_tmp, hist;  // soft: radix sort
  std::vector<int32_t> index;  // resolved point index per pixel (-1 = none)
};

void AllocateOutputs(const RenderOptions& options, RenderedFrame* frame) {
  const int h = options.height, w = options.width;
  frame->rgb.create(h, w, CV_8UC3);
  frame->depth.create(h, w, CV_32F);
  frame->mask.create(h, w, CV_8U);
  if (options.output_index) frame->index.create(h, w, CV_32S);
  if (options.output_instance) frame->instance.create(h, w, CV_32S);
  if (options.output_float_rgb) frame->rgb_float.create(h, w, CV_32FC3);
  frame->num_valid = frame->num_filled = frame->num_projected = 0;
}

// Writes the optional per-pixel index / instance outputs from scratch.index.
void WriteIndexOutputs(const PackedCloud& cloud,
                       const RenderOptions& options,
                       const std::vector<int32_t>& index,
                       RenderedFrame* frame) {
  const int n = options.width * options.height;
  if (options.output_index)
    std::memcpy(frame->index.ptr<int32_t>(), index.data(), n * 4);
  if (options.output_instance) {
    // Branch-free: index -1 maps to the sentinel slot (id -1) after the points.
    int32_t* out = frame->instance.ptr<int32_t>();
    const int32_t* ids = cloud.instance.data();
    const uint32_t sentinel = static_cast<uint32_t>(cloud.size());
    for (int i = 0; i < n; ++i)
      out[i] = ids[std::min(static_cast<uint32_t>(index[i]), sentinel)];
  }
}

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

#if defined(__GNUC__) && defined(__x86_64__)
#define GEODRIVE_HAVE_AVX2_PATH 1
std::atomic<bool> g_simd_enabled{true};
bool UseAvx2() {
  static const bool has_avx2 = __builtin_cpu_supports("avx2");
  return has_avx2 && g_simd_enabled.load(std::memory_order_relaxed);
}
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

// Z-buffer resolve: key -> RGB (empty pixels read the black sentinel colour
// at index n), depth, mask and optionally the point index; every key is reset
// to empty. Returns the number of valid pixels. The AVX2 version writes the
// same bytes.
struct ZResolveArgs {
  uint64_t* keys;
  size_t npix;
  const uint32_t* colors;  // RGBX words, black sentinel at [sentinel]
  uint32_t sentinel;
  uint8_t* rgb;
  uint32_t* depth;  // float bits
  uint8_t* mask;
  int32_t* index;  // nullptr: not wanted
};

int64_t ResolveZScalar(const ZResolveArgs& a, size_t begin) {
  int64_t valid = 0;
  for (size_t p = begin; p < a.npix; ++p) {
    const uint64_t key = a.keys[p];
    a.keys[p] = kEmptyKey;
    const uint32_t is_valid = key != kEmptyKey;
    const uint32_t idx =
        is_valid ? static_cast<uint32_t>(key & 0xffffffffu) : a.sentinel;
    const uint32_t c = a.colors[idx];
    // Bytes 0..2 of the little-endian RGBX word are R, G, B.
    a.rgb[3 * p] = static_cast<uint8_t>(c);
    a.rgb[3 * p + 1] = static_cast<uint8_t>(c >> 8);
    a.rgb[3 * p + 2] = static_cast<uint8_t>(c >> 16);
    a.depth[p] = is_valid ? static_cast<uint32_t>(key >> 32) : 0u;
    a.mask[p] = static_cast<uint8_t>(0u - is_valid);
    if (a.index) a.index[p] = is_valid ? static_cast<int32_t>(idx) : -1;
    valid += is_valid;
  }
  return valid;
}

#ifdef GEODRIVE_HAVE_AVX2_PATH
// Eight pixels at a time: split the keys into index and depth halves, gather
// the colours, shuffle RGBX to RGB.
__attribute__((target("avx2"))) int64_t ResolveZAvx2(const ZResolveArgs& a) {
  const __m256i empty = _mm256_set1_epi64x(static_cast<long long>(kEmptyKey));
  const __m256i even_odd = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
  const __m256i empty_hi = _mm256_set1_epi32(0x7fffffff);
  const __m256i sentinel = _mm256_set1_epi32(static_cast<int>(a.sentinel));
  // Per 128-bit lane: RGBX x 4 -> RGB x 4 (12 bytes), and byte 0 of each
  // 32-bit word -> 4 bytes.
  const __m256i rgb_shuffle =
      _mm256_setr_epi8(0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1, -1,
                       0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1, -1);
  const __m256i byte0_shuffle = _mm256_setr_epi8(
      0, 4, 8, 12, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, 0, 4, 8, 12,
      -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1);
  int64_t valid = 0;
  size_t p = 0;
  // The second 16-byte RGB store reaches 4 bytes past the 8 pixels: stop
  // while 2 more pixels remain, the scalar tail does the rest.
  for (; p + 10 <= a.npix; p += 8) {
    __m256i* kp = reinterpret_cast<__m256i*>(a.keys + p);
    const __m256i k0 = _mm256_loadu_si256(kp);
    const __m256i k1 = _mm256_loadu_si256(kp + 1);
    _mm256_storeu_si256(kp, empty);
    _mm256_storeu_si256(kp + 1, empty);
    const __m256i s0 = _mm256_permutevar8x32_epi32(k0, even_odd);
    const __m256i s1 = _mm256_permutevar8x32_epi32(k1, even_odd);
    const __m256i lo = _mm256_permute2x128_si256(s0, s1, 0x20);  // indices
    const __m256i hi = _mm256_permute2x128_si256(s0, s1, 0x31);  // z bits
    const __m256i invalid = _mm256_cmpeq_epi32(hi, empty_hi);
    const __m256i idx = _mm256_blendv_epi8(lo, sentinel, invalid);
    const __m256i col =
        _mm256_i32gather_epi32(reinterpret_cast<const int*>(a.colors), idx, 4);
    const __m256i rgb = _mm256_shuffle_epi8(col, rgb_shuffle);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(a.rgb + 3 * p),
                     _mm256_castsi256_si128(rgb));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(a.rgb + 3 * p + 12),
                     _mm256_extracti128_si256(rgb, 1));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(a.depth + p),
                        _mm256_andnot_si256(invalid, hi));
    if (a.index) {
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(a.index + p),
                          _mm256_or_si256(lo, invalid));
    }
    const __m256i m = _mm256_shuffle_epi8(
        _mm256_andnot_si256(invalid, _mm256_set1_epi32(0xff)), byte0_shuffle);
    const uint64_t mask8 = static_cast<uint32_t>(_mm256_extract_epi32(m, 0)) |
                           (static_cast<uint64_t>(static_cast<uint32_t>(
                                _mm256_extract_epi32(m, 4)))
                            << 32);
    std::memcpy(a.mask + p, &mask8, 8);
    valid += 8 - __builtin_popcount(static_cast<unsigned>(
                     _mm256_movemask_ps(_mm256_castsi256_ps(invalid))));
  }
  return valid + ResolveZScalar(a, p);
}
#endif

int64_t ResolveZBuffer(const ZResolveArgs& a) {
#ifdef GEODRIVE_HAVE_AVX2_PATH
  if (UseAvx2()) return ResolveZAvx2(a);
#endif
  return ResolveZScalar(a, 0);
}

// Z-buffer. Each pixel keeps the minimum key (z, index), so among equal depths
// the smallest index wins, whatever the processing order or thread count.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && \
    defined(__linux__)
// An AVX2 clone is picked at run time where available (no FMA: results are
// identical to the baseline clone, -ffp-contract=off under -std=c++17).
#define GEODRIVE_HOT_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define GEODRIVE_HOT_CLONES
#endif

GEODRIVE_HOT_CLONES
void RenderZBuffer(const PackedCloud& soa,
                   const std::vector<ProjectedRange>& ranges,
                   const RenderOptions& options,
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
  const int n = static_cast<int>(soa.size());
  const float fw = static_cast<float>(w), fh = static_cast<float>(h);
  int64_t projected = 0;
  const float r = static_cast<float>(options.radius_px);
  for (const ProjectedRange& range : ranges) {
    for (int base = range.begin; base < range.end; base += kBlock) {
      const int m = std::min(kBlock, range.end - base);
      ProjectBlock(soa, base, m, range.proj, &blk);
      if (r <= 0) {
        // Pixel (i, j) covers [i - 0.5, i + 0.5) x [j - 0.5, j + 0.5) in
        // shifted coordinates.
        for (int k = 0; k < m; ++k) {
          // 0 <= fu < W and 0 <= fv < H from sign bits (vectorises; see
          // ProjectBlock).
          const float fu = blk.u[k] + 0.5f, fv = blk.v[k] + 0.5f;
          const int32_t in =
              blk.ok[k] &
              static_cast<int32_t>((SignBit(fu) ^ 1u) & SignBit(fu - fw) &
                                   (SignBit(fv) ^ 1u) & SignBit(fv - fh));
          const float su = in ? fu : 0.0f, sv = in ? fv : 0.0f;
          const int32_t pix =
              static_cast<int32_t>(sv) * w + static_cast<int32_t>(su);
          blk.ok[k] = in ? pix : static_cast<int32_t>(npix);
          projected += in;
        }
        for (int k = 0; k < m; ++k) {
          uint64_t* slot = kb + blk.ok[k];
          const uint64_t key = PackKey(blk.z[k], base + k);
          if (key < *slot) *slot = key;
        }
        continue;
      }
      projected += SplatDisks(blk, m, base, r, w, h, kb);
    }
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
                    static_cast<uint32_t>(n),
                    frame->rgb.ptr<uint8_t>(),
                    reinterpret_cast<uint32_t*>(frame->depth.ptr<float>()),
                    frame->mask.ptr<uint8_t>(),
                    need_index ? index.data() : nullptr};
  frame->num_valid = ResolveZBuffer(args);
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

void CheckCloud(const PointCloud& cloud) {
  GEODRIVE_CHECK_INPUT(!cloud.empty(), "render: the point cloud is empty");
  GEODRIVE_CHECK_INPUT(cloud.size() < (1ull << 31),
                       "render: the point cloud has ", cloud.size(),
                       " points (at most 2^31 - 1 supported)");
  cloud.Check("render: point cloud");
}

PinholeCamera FrameCamera(const PinholeCamera& camera,
                          const RenderOptions& options,
                          const std::string& what) {
  camera.Check(what);
  if (camera.width == options.width && camera.height == options.height)
    return camera;
  return ResizeCamera(camera, options.width, options.height,
                      options.pixel_convention);
}

void RenderOne(const PackedCloud& cloud,
               const std::vector<ProjectedRange>& ranges,
               const RenderOptions& options,
               Scratch* scratch,
               RenderedFrame* frame) {
  AllocateOutputs(options, frame);
  if (options.mode == RenderMode::kZBuffer) {
    RenderZBuffer(cloud, ranges, options, scratch, frame);
    if (options.hole_fill) {
      for (int it = 0; it < options.hole_fill_iterations; ++it) {
        const int64_t filled = HoleFillPass(options, &scratch->index, frame);
        frame->num_filled += filled;
        if (filled == 0) break;
      }
    }
    if (options.output_float_rgb)
      frame->rgb.convertTo(frame->rgb_float, CV_32FC3, 1.0 / 255);
  } else {
    RenderSoft(cloud, ranges, options, scratch, frame);
  }
  WriteIndexOutputs(cloud, options, scratch->index, frame);
}

}  // namespace

bool SetRendererSimdEnabled(bool enabled) {
#ifdef GEODRIVE_HAVE_AVX2_PATH
  return g_simd_enabled.exchange(enabled);
#else
  (void)enabled;
  return false;
#endif
}

std::string ToString(RenderMode mode) {
  return mode == RenderMode::kZBuffer ? "zbuffer" : "soft";
}

RenderMode ParseRenderMode(const std::string& text) {
  if (text == "zbuffer") return RenderMode::kZBuffer;
  if (text == "soft") return RenderMode::kSoft;
  ThrowInputError("render mode", "'", text, "' is not one of zbuffer, soft");
}

void RenderOptions::Check() const {
  GEODRIVE_CHECK_INPUT(width > 0 && height > 0 && width <= kMaxImageSide &&
                           height <= kMaxImageSide,
                       "render options: output size ", width, "x", height,
                       " (W x H) must be in 1..", kMaxImageSide);
  GEODRIVE_CHECK_INPUT(
      std::isfinite(near) && near >= 0 && !std::isnan(far) && far > near,
      "render options: need 0 <= near < far, got near ", near, " far ", far);
  GEODRIVE_CHECK_INPUT(
      std::isfinite(radius_px) && radius_px >= 0 && radius_px <= 256,
      "render options: radius_px ", radius_px, " must be in [0, 256]");
  GEODRIVE_CHECK_INPUT(
      std::isfinite(radius_ndc) && radius_ndc > 0 && radius_ndc <= 2,
      "render options: radius_ndc ", radius_ndc, " must be in (0, 2]");
  GEODRIVE_CHECK_INPUT(
      points_per_pixel >= 1 && points_per_pixel <= kMaxPointsPerPixel,
      "render options: points_per_pixel ", points_per_pixel, " must be in 1..",
      kMaxPointsPerPixel);
  GEODRIVE_CHECK_INPUT(hole_fill_iterations >= 0 && hole_fill_iterations <= 64,
                       "render options: hole_fill_iterations must be in 0..64");
  GEODRIVE_CHECK_INPUT(
      hole_fill_min_neighbors >= 1 && hole_fill_min_neighbors <= 8,
      "render options: hole_fill_min_neighbors must be in 1..8");
  GEODRIVE_CHECK_INPUT(num_threads >= 0,
                       "render options: num_threads must be >= 0");
}

double RenderedFrame::coverage() const {
  const double n = static_cast<double>(mask.total());
  return n > 0 ? num_valid / n : 0.0;
}

std::string RenderSummary::BriefReport() const {
  std::ostringstream os;
  os << "rendered " << num_frames << " frames from " << num_points
     << " points in " << seconds << " s; coverage mean " << mean_coverage
     << " min " << min_coverage << " max " << max_coverage;
  if (!empty_frames.empty()) {
    os << "; " << empty_frames.size() << " all-invalid frame(s):";
    for (int f : empty_frames) os << " " << f;
  }
  return os.str();
}

void CheckPose(const Rigid3d& pose, const std::string& what, double tol) {
  const Eigen::Vector4d q = pose.rotation.coeffs();
  GEODRIVE_CHECK_INPUT(q.allFinite() && pose.translation.allFinite(), what,
                       ": pose has NaN or Inf values");
  GEODRIVE_CHECK_INPUT(std::abs(q.norm() - 1.0) <= tol, what,
                       ": rotation is not orthonormal (quaternion norm ",
                       q.norm(), ")");
}

RenderedFrame RenderFrame(const PointCloud& cloud_in_world,
                          const PinholeCamera& camera,
                          const Rigid3d& cam_from_world,
                          const RenderOptions& options) {
  RenderResult result =
      RenderFrames(cloud_in_world, {camera}, {cam_from_world}, options);
  return std::move(result.frames[0]);
}

RenderResult RenderFrames(const PointCloud& cloud_in_world,
                          const std::vector<PinholeCamera>& cameras,
                          const std::vector<Rigid3d>& cam_from_world,
                          const RenderOptions& options) {
  RenderResult result;
  RenderFramesInto(cloud_in_world, cameras, cam_from_world, options, &result);
  return result;
}

namespace {

// Checks the options, poses and cameras shared by the RenderFrames* entry
// points; returns the per-frame cameras at the output size.
std::vector<PinholeCamera> CheckFrames(
    const std::vector<PinholeCamera>& cameras,
    const std::vector<Rigid3d>& cam_from_world,
    const RenderOptions& options) {
  options.Check();
  GEODRIVE_CHECK_INPUT(!cam_from_world.empty(),
                       "render: no camera poses given");
  GEODRIVE_CHECK_INPUT(
      cameras.size() == 1 || cameras.size() == cam_from_world.size(),
      "render: ", cameras.size(), " cameras for ", cam_from_world.size(),
      " poses (need 1 or one per pose)");
  if (options.mode == RenderMode::kSoft) {
    const double bytes =
        static_cast<double>(options.width) * options.height * sizeof(float) * 7;
    GEODRIVE_CHECK_INPUT(bytes <= 8.0 * (1ull << 30),
                         "render options: soft mode at ", options.width, "x",
                         options.height, " needs ", bytes / (1ull << 30),
                         " GiB of scratch per thread (limit 8 GiB)");
  }
  const int num_frames = static_cast<int>(cam_from_world.size());
  std::vector<PinholeCamera> frame_cameras(num_frames);
  for (int f = 0; f < num_frames; ++f) {
    const std::string what = "render: frame " + std::to_string(f);
    CheckPose(cam_from_world[f], what);
    frame_cameras[f] = FrameCamera(cameras[cameras.size() == 1 ? 0 : f],
                                   options, what + " camera");
  }
  return frame_cameras;
}

void Summarise(int64_t num_points,
               std::chrono::steady_clock::time_point start,
               RenderResult* result) {
  RenderSummary& s = result->summary;
  s = RenderSummary();
  const int num_frames = static_cast<int>(result->frames.size());
  s.num_frames = num_frames;
  s.num_points = num_points;
  s.min_coverage = 1.0;
  s.max_coverage = 0.0;
  double sum = 0;
  for (int f = 0; f < num_frames; ++f) {
    const double c = result->frames[f].coverage();
    sum += c;
    s.min_coverage = std::min(s.min_coverage, c);
    s.max_coverage = std::max(s.max_coverage, c);
    if (result->frames[f].num_valid == 0) s.empty_frames.push_back(f);
  }
  s.mean_coverage = num_frames > 0 ? sum / num_frames : 0.0;
  s.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
}

}  // namespace

namespace {

// RenderFramesInto and RenderFramesWithMovingSets after their static-cloud
// check: validates the sets and hidden indices, packs everything once and
// renders the frames.
void RenderCheckedScene(const PointCloud& static_cloud,
                        const std::vector<MovingPointSet>& sets,
                        const std::vector<size_t>& hidden_static,
                        const std::vector<PinholeCamera>& frame_cameras,
                        const std::vector<Rigid3d>& cam_from_world,
                        const RenderOptions& options,
                        std::chrono::steady_clock::time_point start,
                        RenderResult* result_out) {
  const int num_frames = static_cast<int>(cam_from_world.size());
  // The static points drawn, as runs [begin, end) between hidden points.
  std::vector<std::pair<int, int>> static_runs;
  {
    size_t begin = 0;
    for (size_t k = 0; k < hidden_static.size(); ++k) {
      const size_t h = hidden_static[k];
      GEODRIVE_CHECK_INPUT(
          h < static_cloud.size() && (k == 0 || h > hidden_static[k - 1]),
          "render: hidden static point ", k, " (", h,
          ") is out of range or not in ascending order");
      if (h > begin) static_runs.emplace_back(begin, h);
      begin = h + 1;
    }
    if (static_cloud.size() > begin)
      static_runs.emplace_back(begin, static_cloud.size());
  }
  size_t total = static_cloud.size();
  for (size_t k = 0; k < sets.size(); ++k) {
    const MovingPointSet& set = sets[k];
    const std::string what = "render: moving point set " + std::to_string(k);
    set.points.Check(what);
    GEODRIVE_CHECK_INPUT(
        set.world_from_set.size() == static_cast<size_t>(num_frames), what,
        " has ", set.world_from_set.size(), " poses for ", num_frames,
        " frames");
    for (int f = 0; f < num_frames; ++f) {
      if (set.world_from_set[f]) {
        GEODRIVE_CHECK_INPUT(set.world_from_set[f]->allFinite(), what,
                             ": frame ", f, " transform has NaN or Inf");
      }
    }
    total += set.points.size();
  }
  GEODRIVE_CHECK_INPUT(total < (1ull << 31), "render: ", total,
                       " static and moving points (at most 2^31 - 1 "
                       "supported)");
  // Packed once: static points, then each set's points in its own frame.
  PackedCloud packed;
  packed.Reserve(total, options);
  packed.Assign(0, static_cloud, options);
  std::vector<int> offsets(sets.size());
  for (size_t k = 0; k < sets.size(); ++k) {
    offsets[k] = static_cast<int>(packed.size());
    packed.Assign(offsets[k], sets[k].points, options);
    if (options.output_instance) {
      std::fill(packed.instance.begin() + offsets[k],
                packed.instance.begin() + offsets[k] + sets[k].points.size(),
                sets[k].instance_id);
    }
  }
  RenderResult& result = *result_out;
  result.frames.resize(num_frames);
  const int threads =
      options.num_threads > 0 ? options.num_threads : omp_get_max_threads();
#pragma omp parallel num_threads(std::min(threads, num_frames))
  {
    // Scratch buffers persist per thread across calls (OpenMP reuses its
    // threads), so rendering many clips does not pay for fresh allocations and
    // page faults every time.
    thread_local Scratch scratch;
    std::vector<ProjectedRange> ranges;
#pragma omp for schedule(dynamic, 1)
    for (int f = 0; f < num_frames; ++f) {
      const Eigen::Matrix3d cam_r =
          cam_from_world[f].rotation.normalized().toRotationMatrix();
      const Eigen::Vector3d& cam_t = cam_from_world[f].translation;
      ranges.clear();
      const FrameProjector camera_proj(frame_cameras[f], cam_r, cam_t, options);
      for (const std::pair<int, int>& run : static_runs)
        ranges.push_back(ProjectedRange{run.first, run.second, camera_proj});
      for (size_t k = 0; k < sets.size(); ++k) {
        const std::optional<Matrix3x4d>& a = sets[k].world_from_set[f];
        if (!a || sets[k].points.empty()) continue;
        // cam_from_set = cam_from_world * world_from_set.
        ranges.push_back(ProjectedRange{
            offsets[k], offsets[k] + static_cast<int>(sets[k].points.size()),
            FrameProjector(frame_cameras[f], cam_r * a->leftCols<3>(),
                           cam_r * a->col(3) + cam_t, options)});
      }
      RenderOne(packed, ranges, options, &scratch, &result.frames[f]);
    }
  }
  Summarise(static_cast<int64_t>(total - hidden_static.size()), start, &result);
}

}  // namespace

void RenderFramesInto(const PointCloud& cloud_in_world,
                      const std::vector<PinholeCamera>& cameras,
                      const std::vector<Rigid3d>& cam_from_world,
                      const RenderOptions& options,
                      RenderResult* result_out) {
  const auto start = std::chrono::steady_clock::now();
  const std::vector<PinholeCamera> frame_cameras =
      CheckFrames(cameras, cam_from_world, options);
  CheckCloud(cloud_in_world);
  RenderCheckedScene(cloud_in_world, {}, {}, frame_cameras, cam_from_world,
                     options, start, result_out);
}

void RenderFramesWithMovingSets(const PointCloud& static_cloud,
                                const std::vector<MovingPointSet>& sets,
                                const std::vector<PinholeCamera>& cameras,
                                const std::vector<Rigid3d>& cam_from_world,
                                const RenderOptions& options,
                                RenderResult* result_out,
                                const std::vector<size_t>& hidden_static) {
  const auto start = std::chrono::steady_clock::now();
  const std::vector<PinholeCamera> frame_cameras =
      CheckFrames(cameras, cam_from_world, options);
  static_cloud.Check("render: static point cloud");
  RenderCheckedScene(static_cloud, sets, hidden_static, frame_cameras,
                     cam_from_world, options, start, result_out);
}

}  // namespace geodrive

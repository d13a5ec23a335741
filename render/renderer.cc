#include "render/renderer.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#include "geometry/status.h"

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
                 const RenderOptions& options) {
    const Eigen::Matrix3d rot =
        cam_from_world.rotation.normalized().toRotationMatrix();
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) r[3 * i + j] = static_cast<float>(rot(i, j));
      t[i] = static_cast<float>(cam_from_world.translation[i]);
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

// The cloud's positions as structure-of-arrays (built once per RenderFrames
// call).
struct SoaPositions {
  std::vector<float> x, y, z;
  explicit SoaPositions(const PointCloud& cloud) {
    const size_t n = cloud.size();
    x.resize(n);
    y.resize(n);
    z.resize(n);
    for (size_t i = 0; i < n; ++i) {
      x[i] = cloud.positions[i][0];
      y[i] = cloud.positions[i][1];
      z[i] = cloud.positions[i][2];
    }
  }
};

// Projects points [base, base + n) to shifted pixel coordinates; ok = near < z
// < far.
inline void ProjectBlock(const SoaPositions& soa,
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

// Scratch memory reused across the frames a thread renders.
struct Scratch {
  ProjectedBlock block;
  std::vector<float> zbuf;      // zbuffer: nearest z per pixel (+inf = empty)
  std::vector<uint8_t> counts;  // soft: entries per pixel
  std::vector<uint64_t>
      keys;  // soft: K per pixel, sorted (z bits << 32 | point index)
  std::vector<float> pu, pv;   // soft: projected coordinates per point
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
void WriteIndexOutputs(const PointCloud& cloud,
                       const RenderOptions& options,
                       const std::vector<int32_t>& index,
                       RenderedFrame* frame) {
  const int n = options.width * options.height;
  if (options.output_index)
    std::memcpy(frame->index.ptr<int32_t>(), index.data(), n * 4);
  if (options.output_instance) {
    int32_t* out = frame->instance.ptr<int32_t>();
    const bool has = cloud.HasInstanceIds();
    for (int i = 0; i < n; ++i)
      out[i] = (index[i] >= 0 && has) ? cloud.instance_ids[index[i]] : -1;
  }
}

const Color3u8 kDefaultColor(200, 200, 200);
constexpr float kInf = std::numeric_limits<float>::infinity();

// Z-buffer. Points are visited in increasing index order and a pixel is taken
// only by a STRICTLY nearer point, so among equal depths the smallest index
// wins, whatever the thread count.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && \
    defined(__linux__)
// An AVX2 clone is picked at run time where available (no FMA: results are
// identical to the baseline clone, -ffp-contract=off under -std=c++17).
#define GEODRIVE_HOT_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define GEODRIVE_HOT_CLONES
#endif

GEODRIVE_HOT_CLONES
void RenderZBuffer(const PointCloud& cloud,
                   const SoaPositions& soa,
                   const FrameProjector& proj,
                   const RenderOptions& options,
                   Scratch* scratch,
                   RenderedFrame* frame) {
  const int w = options.width, h = options.height;
  const size_t npix = static_cast<size_t>(w) * h;
  std::vector<float>& zbuf = scratch->zbuf;
  std::vector<int32_t>& index = scratch->index;
  zbuf.assign(npix, kInf);
  index.resize(npix);
  float* zb = zbuf.data();
  int32_t* ib = index.data();
  ProjectedBlock& blk = scratch->block;
  const int n = static_cast<int>(cloud.size());
  const float fw = static_cast<float>(w), fh = static_cast<float>(h);
  int64_t projected = 0;
  const float r = static_cast<float>(options.radius_px);
  const float r2 = r * r;
  for (int base = 0; base < n; base += kBlock) {
    const int m = std::min(kBlock, n - base);
    ProjectBlock(soa, base, m, proj, &blk);
    if (r <= 0) {
      // Pixel (i, j) covers [i - 0.5, i + 0.5) x [j - 0.5, j + 0.5) in shifted
      // coordinates.
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
        blk.ok[k] = in ? pix : -1;
      }
      for (int k = 0; k < m; ++k) {
        const int32_t pix = blk.ok[k];
        if (pix < 0) continue;
        ++projected;
        const float z = blk.z[k];
        if (z < zb[pix]) {
          zb[pix] = z;
          ib[pix] = base + k;
        }
      }
      continue;
    }
    for (int k = 0; k < m; ++k) {
      if (!blk.ok[k]) continue;
      const float u = blk.u[k], v = blk.v[k], z = blk.z[k];
      if (!(u > -r - 1 && u < fw + r && v > -r - 1 && v < fh + r)) continue;
      const int j0 = std::max(0, CeilI(v - r));
      const int j1 = std::min(h - 1, FloorI(v + r));
      bool hit = false;
      for (int j = j0; j <= j1; ++j) {
        const float dy = static_cast<float>(j) - v;
        const float hw2 = r2 - dy * dy;
        if (hw2 < 0) continue;
        const float hw = std::sqrt(hw2);
        const int i0 = std::max(0, CeilI(u - hw));
        const int i1 = std::min(w - 1, FloorI(u + hw));
        float* zrow = zb + static_cast<size_t>(j) * w;
        int32_t* irow = ib + static_cast<size_t>(j) * w;
        for (int c = i0; c <= i1; ++c) {
          if (z < zrow[c]) {
            zrow[c] = z;
            irow[c] = base + k;
          }
        }
        hit |= i0 <= i1;
      }
      projected += hit;
    }
  }
  frame->num_projected = projected;

  // Resolve.
  const bool has_colors = cloud.HasColors();
  const Color3u8* colors = has_colors ? cloud.colors.data() : nullptr;
  uint8_t* rgb = frame->rgb.ptr<uint8_t>();
  float* depth = frame->depth.ptr<float>();
  uint8_t* mask = frame->mask.ptr<uint8_t>();
  int64_t valid = 0;
  for (size_t p = 0; p < npix; ++p) {
    const float z = zb[p];
    if (z == kInf) {
      rgb[3 * p] = rgb[3 * p + 1] = rgb[3 * p + 2] = 0;
      depth[p] = 0;
      mask[p] = kMaskInvalid;
      ib[p] = -1;
      continue;
    }
    const Color3u8& c = has_colors ? colors[ib[p]] : kDefaultColor;
    rgb[3 * p] = c[0];
    rgb[3 * p + 1] = c[1];
    rgb[3 * p + 2] = c[2];
    depth[p] = z;
    mask[p] = kMaskValid;
    ++valid;
  }
  frame->num_valid = valid;
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

// Soft mode. Each pixel keeps a sorted array of at most K keys (z bits << 32 |
// point index): one integer compare orders by (z, index), as PyTorch3D's
// rasteriser does (z > 0, so the float bits are monotonic). The distance is
// recomputed at compositing time from the projected (u, v).
GEODRIVE_HOT_CLONES
void RenderSoft(const PointCloud& cloud,
                const SoaPositions& soa,
                const std::vector<float>& colors01,
                const FrameProjector& proj,
                const RenderOptions& options,
                Scratch* scratch,
                RenderedFrame* frame) {
  const int w = options.width, h = options.height;
  const size_t npix = static_cast<size_t>(w) * h;
  const int k_max = options.points_per_pixel;
  const int n = static_cast<int>(cloud.size());
  scratch->counts.assign(npix, 0);
  scratch->keys.resize(npix * k_max);
  scratch->pu.resize(n);
  scratch->pv.resize(n);
  uint8_t* counts = scratch->counts.data();
  uint64_t* keys = scratch->keys.data();
  float* pu = scratch->pu.data();
  float* pv = scratch->pv.data();

  // Pixels per NDC unit: the short side spans 2 NDC.
  const double s = std::min(w, h) / 2.0;
  const float inv_s2 = static_cast<float>(1.0 / (s * s));
  const float r2 = static_cast<float>(options.radius_ndc * options.radius_ndc);
  const float r_px = static_cast<float>(options.radius_ndc * s);
  // Candidate rows/columns are bounded by a slightly larger pixel radius; the
  // exact test is d² < r² in NDC, as in PyTorch3D.
  const float r_px_bound = r_px * 1.0001f + 1e-4f;
  const float r2_px_bound = r_px_bound * r_px_bound;
  const float fw = static_cast<float>(w), fh = static_cast<float>(h);
  ProjectedBlock& blk = scratch->block;
  int64_t projected = 0;
  for (int base = 0; base < n; base += kBlock) {
    const int m = std::min(kBlock, n - base);
    ProjectBlock(soa, base, m, proj, &blk);
    std::memcpy(pu + base, blk.u, m * sizeof(float));
    std::memcpy(pv + base, blk.v, m * sizeof(float));
    for (int k = 0; k < m; ++k) {
      if (!blk.ok[k]) continue;
      const float u = blk.u[k], v = blk.v[k], z = blk.z[k];
      if (!(u > -r_px - 1 && u < fw + r_px && v > -r_px - 1 && v < fh + r_px))
        continue;
      const int j0 = std::max(0, CeilI(v - r_px_bound));
      const int j1 = std::min(h - 1, FloorI(v + r_px_bound));
      bool hit = false;
      const uint64_t key = (static_cast<uint64_t>(FloatBits(z)) << 32) |
                           static_cast<uint64_t>(base + k);
      for (int j = j0; j <= j1; ++j) {
        const float dy = static_cast<float>(j) - v;
        const float hw2 = r2_px_bound - dy * dy;
        if (hw2 < 0) continue;
        const float hw = std::sqrt(hw2);
        const int i0 = std::max(0, CeilI(u - hw));
        const int i1 = std::min(w - 1, FloorI(u + hw));
        const size_t row = static_cast<size_t>(j) * w;
        for (int c = i0; c <= i1; ++c) {
          if (!(SoftD2(c, j, u, v, inv_s2) < r2)) continue;
          hit = true;
          const size_t pix = row + c;
          uint64_t* arr = keys + pix * k_max;
          const int cnt = counts[pix];
          int pos_k;
          if (cnt == k_max) {
            if (key >= arr[k_max - 1]) continue;
            pos_k = k_max - 1;
          } else {
            pos_k = cnt;
            counts[pix] = static_cast<uint8_t>(cnt + 1);
          }
          while (pos_k > 0 && key < arr[pos_k - 1]) {
            arr[pos_k] = arr[pos_k - 1];
            --pos_k;
          }
          arr[pos_k] = key;
        }
      }
      projected += hit;
    }
  }
  frame->num_projected = projected;

  // Composite front to back (the operation order of PyTorch3D's CPU
  // AlphaCompositor).
  std::vector<int32_t>& index = scratch->index;
  index.resize(npix);
  const float inv_r2 = 1.0f / r2;
  uint8_t* rgb = frame->rgb.ptr<uint8_t>();
  float* depth = frame->depth.ptr<float>();
  uint8_t* mask = frame->mask.ptr<uint8_t>();
  float* rgbf =
      options.output_float_rgb ? frame->rgb_float.ptr<float>() : nullptr;
  int64_t valid = 0;
  for (int j = 0; j < h; ++j) {
    for (int c = 0; c < w; ++c) {
      const size_t p = static_cast<size_t>(j) * w + c;
      const int cnt = counts[p];
      float acc[3] = {0, 0, 0};
      if (cnt == 0) {
        depth[p] = 0;
        mask[p] = kMaskInvalid;
        index[p] = -1;
      } else {
        const uint64_t* arr = keys + p * k_max;
        float cum = 1.0f;
        for (int k = 0; k < cnt; ++k) {
          const uint32_t idx = static_cast<uint32_t>(arr[k] & 0xffffffffu);
          const float alpha =
              1.0f - SoftD2(c, j, pu[idx], pv[idx], inv_s2) * inv_r2;
          const float* col = colors01.data() + 3 * static_cast<size_t>(idx);
          acc[0] += cum * alpha * col[0];
          acc[1] += cum * alpha * col[1];
          acc[2] += cum * alpha * col[2];
          cum = cum * (1 - alpha);
        }
        depth[p] = BitsFloat(static_cast<uint32_t>(arr[0] >> 32));
        mask[p] = kMaskValid;
        index[p] = static_cast<int32_t>(arr[0] & 0xffffffffu);
        ++valid;
      }
      for (int ch = 0; ch < 3; ++ch) {
        const float val = std::min(255.0f, std::max(0.0f, acc[ch] * 255.0f));
        rgb[3 * p + ch] = static_cast<uint8_t>(val + 0.5f);
        if (rgbf) rgbf[3 * p + ch] = acc[ch];
      }
    }
  }
  frame->num_valid = valid;
}

std::vector<float> Colors01(const PointCloud& cloud) {
  std::vector<float> out(3 * cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    const Color3u8& c = cloud.HasColors() ? cloud.colors[i] : kDefaultColor;
    for (int ch = 0; ch < 3; ++ch) out[3 * i + ch] = c[ch] / 255.0f;
  }
  return out;
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

void RenderOne(const PointCloud& cloud,
               const SoaPositions& soa,
               const std::vector<float>& colors01,
               const PinholeCamera& camera,
               const Rigid3d& cam_from_world,
               const RenderOptions& options,
               Scratch* scratch,
               RenderedFrame* frame) {
  const FrameProjector proj(camera, cam_from_world, options);
  AllocateOutputs(options, frame);
  if (options.mode == RenderMode::kZBuffer) {
    RenderZBuffer(cloud, soa, proj, options, scratch, frame);
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
    RenderSoft(cloud, soa, colors01, proj, options, scratch, frame);
  }
  WriteIndexOutputs(cloud, options, scratch->index, frame);
}

}  // namespace

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

void RenderFramesInto(const PointCloud& cloud_in_world,
                      const std::vector<PinholeCamera>& cameras,
                      const std::vector<Rigid3d>& cam_from_world,
                      const RenderOptions& options,
                      RenderResult* result_out) {
  const auto start = std::chrono::steady_clock::now();
  options.Check();
  CheckCloud(cloud_in_world);
  GEODRIVE_CHECK_INPUT(!cam_from_world.empty(),
                       "render: no camera poses given");
  GEODRIVE_CHECK_INPUT(
      cameras.size() == 1 || cameras.size() == cam_from_world.size(),
      "render: ", cameras.size(), " cameras for ", cam_from_world.size(),
      " poses (need 1 or one per pose)");
  const int num_frames = static_cast<int>(cam_from_world.size());
  if (options.mode == RenderMode::kSoft) {
    const double bytes = static_cast<double>(options.width) * options.height *
                         options.points_per_pixel * sizeof(uint64_t);
    GEODRIVE_CHECK_INPUT(bytes <= 8.0 * (1ull << 30),
                         "render options: soft mode at ", options.width, "x",
                         options.height, " with K = ", options.points_per_pixel,
                         " needs ", bytes / (1ull << 30),
                         " GiB of scratch per thread (limit 8 GiB)");
  }
  std::vector<PinholeCamera> frame_cameras(num_frames);
  for (int f = 0; f < num_frames; ++f) {
    const std::string what = "render: frame " + std::to_string(f);
    CheckPose(cam_from_world[f], what);
    frame_cameras[f] = FrameCamera(cameras[cameras.size() == 1 ? 0 : f],
                                   options, what + " camera");
  }
  const std::vector<float> colors01 = options.mode == RenderMode::kSoft
                                          ? Colors01(cloud_in_world)
                                          : std::vector<float>();

  const SoaPositions soa(cloud_in_world);
  RenderResult& result = *result_out;
  result.frames.resize(num_frames);
  result.summary = RenderSummary();
  const int threads =
      options.num_threads > 0 ? options.num_threads : omp_get_max_threads();
#pragma omp parallel num_threads(std::min(threads, num_frames))
  {
    // Scratch buffers persist per thread across calls (OpenMP reuses its
    // threads), so rendering many clips does not pay for fresh allocations and
    // page faults every time.
    thread_local Scratch scratch;
#pragma omp for schedule(dynamic, 1)
    for (int f = 0; f < num_frames; ++f) {
      RenderOne(cloud_in_world, soa, colors01, frame_cameras[f],
                cam_from_world[f], options, &scratch, &result.frames[f]);
    }
  }

  RenderSummary& s = result.summary;
  s.num_frames = num_frames;
  s.num_points = static_cast<int64_t>(cloud_in_world.size());
  s.min_coverage = 1.0;
  s.max_coverage = 0.0;
  double sum = 0;
  for (int f = 0; f < num_frames; ++f) {
    const double c = result.frames[f].coverage();
    sum += c;
    s.min_coverage = std::min(s.min_coverage, c);
    s.max_coverage = std::max(s.max_coverage, c);
    if (result.frames[f].num_valid == 0) s.empty_frames.push_back(f);
  }
  s.mean_coverage = sum / num_frames;
  s.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
}

}  // namespace geodrive

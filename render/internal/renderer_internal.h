#pragma once
// Internal to geodrive_render (not installed; include only from render/*.cc):
// the pieces the renderer's translation units share. renderer.cc packs the
// cloud and runs the frame loop; renderer_zbuffer.cc (z-buffer splatting, hole
// filling) and renderer_soft.cc (PyTorch3D-style soft compositing) render one
// frame from the packed cloud.

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "geometry/camera.h"
#include "geometry/point_cloud.h"
#include "geometry/rigid3.h"
#include "render/renderer.h"

#if defined(__GNUC__) && defined(__x86_64__)
#define GEODRIVE_HAVE_AVX2_PATH 1
#endif

// Marks the per-frame kernels RenderZBuffer and RenderSoft.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && \
    defined(__linux__)
// An AVX2 clone is picked at run time where available (no FMA: results are
// identical to the baseline clone, -ffp-contract=off under -std=c++17).
#define GEODRIVE_HOT_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define GEODRIVE_HOT_CLONES
#endif

namespace geodrive {
namespace renderer_internal {

// The per-frame camera in float, with the pixel-centre offset folded into cx,
// cy so that pixel (i, j) has its centre at (i, j) in the shifted coordinates.
struct FrameProjector {
  float r[9];
  float t[3];
  float fx, fy, cx, cy;
  float focal;  // sqrt(fx fy), for footprint splats
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
    focal = static_cast<float>(std::sqrt(camera.fx * camera.fy));
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
  // Footprint splats: > 0 multiplies the packed camera-facing footprints (a
  // moving set's largest axis scale; 1 for the static cloud; surface axes go
  // through proj's linear part instead); 0 = fixed radius.
  float footprint_scale = 0;
};

// Points are projected in blocks into small arrays (a loop the compiler
// vectorises), then splatted in index order.
constexpr int kBlock = 512;
struct ProjectedBlock {
  alignas(64) float u[kBlock];
  alignas(64) float v[kBlock];
  alignas(64) float z[kBlock];
  alignas(64) int32_t ok[kBlock];
  alignas(64) uint64_t key[kBlock];  // zbuffer radius 0: depth-ordered keys
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

// The cloud as the kernels read it: positions as structure of arrays, colours
// in the form the mode needs, instance ids when asked for. Built once per
// RenderFramesInto / RenderFramesWithMovingSets call.
struct PackedCloud {
  std::vector<float> x, y, z;
  std::vector<uint32_t> rgbx;     // zbuffer: black RGBX word at [0], then
                                  // point i's at [i + 1]
  std::vector<float> colors01;    // soft: RGB in [0, 1]
  std::vector<int32_t> instance;  // output_instance: id per point (-1 = none)
                                  // + sentinel -1 at [n]
  std::vector<float> footprint;   // capture footprints (0 = none); empty when
                                  // no packed cloud carries any
  std::vector<float> footprint_axes;  // 6 per point: footprint_u, footprint_v
                                      // (zeros = none); empty when no packed
                                      // cloud carries them
  // Frustum culling (radius 0 without footprints): per group of kCullGroup
  // points, the bounding box of their positions as nine arrays of one double
  // per group (structure of arrays, so the plane tests vectorise): centre x,
  // half-width x, centre y, half-width y, centre z, half-width z (exact in
  // double), then |centre| + half-width for x, y, z. A group may hold points
  // of two ranges in different coordinate frames: its box then holds both,
  // so it is culled for a range only when that range's own points in it are
  // all outside. Empty: no culling.
  std::vector<double> cull_box;
  size_t size() const { return x.size(); }

  // Capacity for n points (avoids re-allocating when sets are appended).
  void Reserve(size_t n, const RenderOptions& options);

  // Makes points [offset, offset + cloud.size()) the given cloud's, dropping
  // anything after them; its footprints are packed when `with_footprints`.
  // Returns whether every coordinate copied is finite.
  bool Assign(size_t offset,
              const PointCloud& cloud,
              const RenderOptions& options,
              bool with_footprints = false);
};

// Frustum culling of the radius-0 z-buffer path: groups of kCullGroup
// consecutive packed points whose bounding box lies outside the view are not
// projected. Consecutive points of pointmaps and LiDAR sweeps are neighbours in
// space, so whole groups fall behind the camera or beside the image.
constexpr int kCullGroup = 256;

// Fills soa->cull_box (sized by the caller) for groups [g_begin, g_end).
void ComputeCullBoxes(size_t g_begin, size_t g_end, PackedCloud* soa);

// The view of a projector and a w x h image grown by `margin_px` pixels on
// every side as six plane tests on a box (MakeFrustumPlanes,
// renderer_zbuffer.cc): near, far, before the first and past the last
// column, likewise rows.
struct FrustumPlanes {
  double a[6][3], abs_a[6][3], m[6][3], b[6];
};
FrustumPlanes MakeFrustumPlanes(const FrameProjector& p,
                                int w,
                                int h,
                                double margin_px = 0.0);

// Sets culled[g - g_begin] for groups [g_begin, g_end) of soa: 1 when no
// point of the group's box can pass the per-point test of a path whose
// splats reach at most margin_px - 1 pixels from the projection (0: the
// radius-0 path's single pixel), as all of it lies before the near plane,
// beyond the far plane or beyond one side of the grown image by a margin
// (1e-5 of the magnitudes involved) at least 20x the float rounding of the
// per-point computation. Culling therefore never changes the output.
void CullGroups(const PackedCloud& soa,
                const FrustumPlanes& planes,
                int g_begin,
                int g_end,
                uint8_t* culled);

// Whether RenderZBuffer culls (SetRendererCullingEnabled).
bool UseCulling();

// Projects points [base + k0, base + n) to shifted pixel coordinates (entries
// k0..n-1 of `out`); ok = near < z < far.
inline void ProjectBlock(const PackedCloud& soa,
                         int base,
                         int n,
                         const FrameProjector& p,
                         ProjectedBlock* out,
                         int k0 = 0) {
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
  for (int k = k0; k < n; ++k) {
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
  std::vector<int32_t> index;   // resolved point index per pixel (-1 = none)
  std::vector<uint8_t> culled;  // zbuffer radius 0: groups outside the view
  // zbuffer, footprint splats: per point of a block its magnification, and
  // the magnified points' entries.
  std::array<float, kBlock> magnification;
  std::array<int, kBlock> magnified;
};

// Whether a call that renders `num_frames` frames writes their z-buffer
// outputs with streaming stores: when together they exceed the caches
// (32 MiB), so that the stores do not first read each output line
// (renderer_zbuffer.cc, ResolveZAvx2). The bytes are the same either way.
bool StreamOutputs(const RenderOptions& options, int num_frames);

#ifdef GEODRIVE_HAVE_AVX2_PATH
// Whether the AVX2 kernels run: the CPU has AVX2 and SetRendererSimdEnabled
// has not turned them off.
bool UseAvx2();
#endif

// Renders one frame of `soa` (the points of `ranges`, each through its
// projector) into `frame`, whose outputs are allocated. The z-buffer keeps the
// per-pixel point index in scratch->index when hole filling or an index /
// instance output needs it (renderer_zbuffer.cc). With `stream_outputs`
// (StreamOutputs) the resolve writes the outputs with streaming stores.
void RenderZBuffer(const PackedCloud& soa,
                   const std::vector<ProjectedRange>& ranges,
                   const RenderOptions& options,
                   bool stream_outputs,
                   Scratch* scratch,
                   RenderedFrame* frame);

// One hole-filling pass; returns the number of pixels filled
// (renderer_zbuffer.cc).
int64_t HoleFillPass(const RenderOptions& options,
                     std::vector<int32_t>* index,
                     RenderedFrame* frame);

// Soft mode (PyTorch3D rasteriser + alpha compositor); always fills
// scratch->index (renderer_soft.cc).
void RenderSoft(const PackedCloud& soa,
                const std::vector<ProjectedRange>& ranges,
                const RenderOptions& options,
                Scratch* scratch,
                RenderedFrame* frame);

}  // namespace renderer_internal
}  // namespace geodrive

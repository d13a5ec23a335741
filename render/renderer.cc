// The point splatting renderer (renderer.h): options, checks, the packed cloud
// the kernels read, and the frame loop that renders every frame of a static
// cloud plus moving point sets. The per-frame kernels are in
// renderer_zbuffer.cc and renderer_soft.cc.

#include "render/renderer.h"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <exception>
#include <sstream>

#ifdef __SSE2__
#include <immintrin.h>
#endif

#include "geometry/util/status.h"
#include "render/footprint.h"
#include "render/internal/renderer_internal.h"

namespace geodrive {
namespace {

constexpr int kMaxImageSide = 16384;
constexpr int kMaxPointsPerPixel = 32;

const Color3u8 kDefaultColor(200, 200, 200);

#ifdef GEODRIVE_HAVE_AVX2_PATH
std::atomic<bool> g_simd_enabled{true};
#endif
std::atomic<bool> g_culling_enabled{true};

}  // namespace

namespace renderer_internal {

void PackedCloud::Reserve(size_t n, const RenderOptions& options) {
  x.reserve(n);
  y.reserve(n);
  z.reserve(n);
  if (options.mode == RenderMode::kZBuffer)
    rgbx.reserve(n + 1);
  else
    colors01.reserve(3 * n);
  if (options.output_instance) instance.reserve(n + 1);
}

#ifdef GEODRIVE_HAVE_AVX2_PATH
namespace {
// Packs the first of m points eight at a time while at least two more
// follow (the colour loads read 4 bytes past the eighth colour): positions
// from x y z triples to the x, y, z arrays, and with `colors` (else nullptr)
// RGB triples to RGBX words. Returns how many points were packed (a multiple
// of 8); *not_finite is nonzero when one of their coordinates is NaN or
// infinite.
__attribute__((target("avx2"))) size_t PackAvx2(const float* xyz,
                                                const uint8_t* colors,
                                                size_t m,
                                                float* x,
                                                float* y,
                                                float* z,
                                                uint32_t* rgbx,
                                                uint32_t* not_finite) {
  // Of three vectors a, b, c holding points 0-7's 24 coordinates, each lane
  // holds one x (and one y, one z) in exactly one of them: blend them, then
  // put the lanes in point order.
  const __m256i x_order = _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5);
  const __m256i y_order = _mm256_setr_epi32(1, 4, 7, 2, 5, 0, 3, 6);
  const __m256i z_order = _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7);
  const __m256 exponent = _mm256_castsi256_ps(_mm256_set1_epi32(0x7f800000));
  const __m256i rgb_to_rgbx =
      _mm256_setr_epi8(0, 1, 2, -1, 3, 4, 5, -1, 6, 7, 8, -1, 9, 10, 11, -1, 0,
                       1, 2, -1, 3, 4, 5, -1, 6, 7, 8, -1, 9, 10, 11, -1);
  __m256 bad = _mm256_setzero_ps();
  size_t i = 0;
  for (; i + 10 <= m; i += 8) {
    const float* p = xyz + 3 * i;
    const __m256 a = _mm256_loadu_ps(p), b = _mm256_loadu_ps(p + 8),
                 c = _mm256_loadu_ps(p + 16);
    // Lanes of x: a 0 3 6, b 1 4 7, c 2 5; y: c 0 3 6, a 1 4 7, b 2 5;
    // z: b 0 3 6, c 1 4 7, a 2 5.
    const __m256 xs = _mm256_blend_ps(_mm256_blend_ps(a, b, 0x92), c, 0x24);
    const __m256 ys = _mm256_blend_ps(_mm256_blend_ps(a, b, 0x24), c, 0x49);
    const __m256 zs = _mm256_blend_ps(_mm256_blend_ps(a, b, 0x49), c, 0x92);
    // Where each point's coordinate now is: x of point k in lane x_order[k]
    // (lane 0 holds x0, lane 1 x3, lane 2 x6, ...).
    _mm256_storeu_ps(x + i, _mm256_permutevar8x32_ps(xs, x_order));
    _mm256_storeu_ps(y + i, _mm256_permutevar8x32_ps(ys, y_order));
    _mm256_storeu_ps(z + i, _mm256_permutevar8x32_ps(zs, z_order));
    // NaN or infinite: all exponent bits set.
    for (const __m256 v : {a, b, c}) {
      bad =
          _mm256_or_ps(bad, _mm256_castsi256_ps(_mm256_cmpeq_epi32(
                                _mm256_castps_si256(_mm256_and_ps(v, exponent)),
                                _mm256_castps_si256(exponent))));
    }
    if (colors) {
      // Colours 0-3 from bytes 0-11, colours 4-7 from bytes 12-23.
      const uint8_t* q = colors + 3 * i;
      const __m256i rgb = _mm256_inserti128_si256(
          _mm256_castsi128_si256(
              _mm_loadu_si128(reinterpret_cast<const __m128i*>(q))),
          _mm_loadu_si128(reinterpret_cast<const __m128i*>(q + 12)), 1);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(rgbx + i),
                          _mm256_shuffle_epi8(rgb, rgb_to_rgbx));
    }
  }
  *not_finite = static_cast<uint32_t>(_mm256_movemask_ps(bad));
  return i;
}
}  // namespace
#endif

bool PackedCloud::Assign(size_t offset,
                         const PointCloud& cloud,
                         const RenderOptions& options,
                         bool with_footprints) {
  const size_t m = cloud.size(), n = offset + m;
  if ((with_footprints && cloud.HasFootprints()) || !footprint.empty()) {
    footprint.resize(n, 0.0f);
    if (with_footprints && cloud.HasFootprints())
      std::copy(cloud.footprints.begin(), cloud.footprints.end(),
                footprint.begin() + offset);
    else
      std::fill(footprint.begin() + offset, footprint.end(), 0.0f);
  }
  const bool axes = with_footprints && !cloud.footprint_u.empty();
  if (axes || !footprint_axes.empty()) {
    footprint_axes.resize(6 * n, 0.0f);
    float* out = footprint_axes.data() + 6 * offset;
    for (size_t i = 0; i < m; ++i, out += 6) {
      if (axes) {
        std::copy_n(cloud.footprint_u[i].data(), 3, out);
        std::copy_n(cloud.footprint_v[i].data(), 3, out + 3);
      } else {
        std::fill_n(out, 6, 0.0f);
      }
    }
  }
  x.resize(n);
  y.resize(n);
  z.resize(n);
  const bool has_colors = cloud.HasColors();
  const bool rgbx_words = options.mode == RenderMode::kZBuffer;
  if (rgbx_words) {
    rgbx.resize(n + 1);
    rgbx[0] = 0;  // little-endian RGBX black: empty pixels read it
  }
  // The finiteness test rides on the copy, so the positions are read once.
  uint32_t not_finite = 0;
  size_t first = 0;  // points [0, first) packed by PackAvx2
  static_assert(sizeof(Eigen::Vector3f) == 12 && sizeof(Color3u8) == 3,
                "packed x y z floats and RGB bytes");
#ifdef GEODRIVE_HAVE_AVX2_PATH
  if (UseAvx2() && m > 0) {
    first =
        PackAvx2(cloud.positions[0].data(),
                 rgbx_words && has_colors ? cloud.colors[0].data() : nullptr, m,
                 x.data() + offset, y.data() + offset, z.data() + offset,
                 rgbx_words ? rgbx.data() + 1 + offset : nullptr, &not_finite);
  }
#endif
  // Without colours every point takes the default one, below.
  const size_t first_color = rgbx_words && has_colors ? first : 0;
  for (size_t i = first; i < m; ++i) {
    const float px = cloud.positions[i][0], py = cloud.positions[i][1],
                pz = cloud.positions[i][2];
    x[offset + i] = px;
    y[offset + i] = py;
    z[offset + i] = pz;
    not_finite |= NotFiniteBit(px) | NotFiniteBit(py) | NotFiniteBit(pz);
  }
  if (rgbx_words) {
    for (size_t i = first_color; i < m; ++i) {
      const Color3u8& c = has_colors ? cloud.colors[i] : kDefaultColor;
      rgbx[1 + offset + i] =
          uint32_t{c[0]} | (uint32_t{c[1]} << 8) | (uint32_t{c[2]} << 16);
    }
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
  return not_finite == 0;
}

bool UseCulling() { return g_culling_enabled.load(std::memory_order_relaxed); }

void ComputeCullBoxes(size_t g_begin, size_t g_end, PackedCloud* soa) {
  const size_t n = soa->size();
  const size_t groups = (n + kCullGroup - 1) / kCullGroup;
  for (size_t g = g_begin; g < g_end; ++g) {
    const size_t begin = g * kCullGroup,
                 end = std::min(n, begin + size_t{kCullGroup});
    const float* const coords[3] = {soa->x.data(), soa->y.data(),
                                    soa->z.data()};
    for (int c = 0; c < 3; ++c) {
      const float* v = coords[c];
      float lo = v[begin], hi = v[begin];
      size_t i = begin;
#ifdef __SSE2__
      // Four running minima and maxima (x86-64 always has SSE; GCC does not
      // vectorise a float min reduction without -ffast-math).
      __m128 lo4 = _mm_set1_ps(lo), hi4 = lo4;
      for (; i + 4 <= end; i += 4) {
        const __m128 x = _mm_loadu_ps(v + i);
        lo4 = _mm_min_ps(lo4, x);
        hi4 = _mm_max_ps(hi4, x);
      }
      float l4[4], h4[4];
      _mm_storeu_ps(l4, lo4);
      _mm_storeu_ps(h4, hi4);
      for (int l = 0; l < 4; ++l) {
        lo = std::min(lo, l4[l]);
        hi = std::max(hi, h4[l]);
      }
#endif
      for (; i < end; ++i) {
        lo = std::min(lo, v[i]);
        hi = std::max(hi, v[i]);
      }
      // Centre and half-width, exact in double.
      const double mid = 0.5 * (double{lo} + double{hi});
      const double half = 0.5 * (double{hi} - double{lo});
      soa->cull_box[(2 * c) * groups + g] = mid;
      soa->cull_box[(2 * c + 1) * groups + g] = half;
      soa->cull_box[(6 + c) * groups + g] = std::abs(mid) + half;
    }
  }
}

#ifdef GEODRIVE_HAVE_AVX2_PATH
bool UseAvx2() {
  static const bool has_avx2 = __builtin_cpu_supports("avx2");
  return has_avx2 && g_simd_enabled.load(std::memory_order_relaxed);
}
#endif

}  // namespace renderer_internal

namespace {

using renderer_internal::ComputeCullBoxes;
using renderer_internal::FrameProjector;
using renderer_internal::HoleFillPass;
using renderer_internal::kCullGroup;
using renderer_internal::PackedCloud;
using renderer_internal::ProjectedRange;
using renderer_internal::RenderSoft;
using renderer_internal::RenderZBuffer;
using renderer_internal::Scratch;
using renderer_internal::UseCulling;

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

void CheckCloud(const PointCloud& cloud) {
  GEODRIVE_CHECK_INPUT(!cloud.empty(), "render: the point cloud is empty");
  GEODRIVE_CHECK_INPUT(cloud.size() < (1ull << 31),
                       "render: the point cloud has ", cloud.size(),
                       " points (at most 2^31 - 1 supported)");
  // The positions are tested for finiteness as they are packed
  // (RenderCheckedScene).
  cloud.CheckAttributes("render: point cloud");
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
               bool stream_outputs,
               Scratch* scratch,
               RenderedFrame* frame) {
  AllocateOutputs(options, frame);
  if (options.mode == RenderMode::kZBuffer) {
    RenderZBuffer(cloud, ranges, options, stream_outputs, scratch, frame);
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

bool SetRendererCullingEnabled(bool enabled) {
  return g_culling_enabled.exchange(enabled);
}

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

std::string ToString(SplatSize size) {
  return size == SplatSize::kFixed ? "fixed" : "footprint";
}

SplatSize ParseSplatSize(const std::string& text) {
  if (text == "fixed") return SplatSize::kFixed;
  if (text == "footprint") return SplatSize::kFootprint;
  ThrowInputError("splat size", "'", text, "' is not one of fixed, footprint");
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
  GEODRIVE_CHECK_INPUT(std::isfinite(max_footprint_magnification) &&
                           max_footprint_magnification >= 1 &&
                           max_footprint_magnification <= 16,
                       "render options: max_footprint_magnification ",
                       max_footprint_magnification, " must be in [1, 16]");
  GEODRIVE_CHECK_INPUT(
      splat_size == SplatSize::kFixed || mode == RenderMode::kZBuffer,
      "render options: footprint splats need the zbuffer mode");
  GEODRIVE_CHECK_INPUT(
      splat_size == SplatSize::kFixed || radius_px == 0,
      "render options: footprint splats size every point from its footprint: "
      "radius_px must be 0 (got ",
      radius_px, ")");
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
  GEODRIVE_CHECK_INPUT(num_threads >= 0 && num_threads <= 256,
                       "render options: num_threads must be in 0..256");
}

double RenderedFrame::coverage() const {
  const double n = static_cast<double>(mask.total());
  return n > 0 ? num_valid / n : 0.0;
}

uint64_t RenderedFrameBytes(const RenderOptions& options) {
  // rgb (3) + depth (4) + mask (1), plus the optional outputs.
  uint64_t per_pixel = 3 + 4 + 1;
  if (options.output_index) per_pixel += 4;
  if (options.output_instance) per_pixel += 4;
  if (options.output_float_rgb || options.mode == RenderMode::kSoft)
    per_pixel += 12;
  return per_pixel * static_cast<uint64_t>(options.width) * options.height;
}

uint64_t EstimateRenderBytes(const RenderOptions& options,
                             int64_t num_points,
                             int frames_held,
                             int threads) {
  const uint64_t pixels = static_cast<uint64_t>(options.width) * options.height;
  // Scratch per thread: z-buffer keys (8) and point indices (4) per pixel;
  // soft mode keeps 7 floats of compositing state per pixel, and per point
  // the projected coordinates, candidate lists and radix-sort buffers.
  const uint64_t scratch_per_pixel =
      options.mode == RenderMode::kSoft ? 7 * 4 + 4 : 8 + 4;
  const uint64_t scratch_per_point =
      options.mode == RenderMode::kSoft ? 3 * 4 + 3 * 4 + 2 * 4 : 16;
  const uint64_t points =
      static_cast<uint64_t>(std::max<int64_t>(num_points, 0));
  const uint64_t per_thread =
      scratch_per_pixel * pixels + scratch_per_point * points;
  // The packed cloud: positions (12), colour (3), instance (4), padding.
  const uint64_t packed = 24 * points;
  return static_cast<uint64_t>(std::max(frames_held, 0)) *
             RenderedFrameBytes(options) +
         static_cast<uint64_t>(std::max(threads, 1)) * per_thread + packed;
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

// RenderFramesInto and RenderFramesWithMovingSets after the check of their
// static cloud's attributes (CheckAttributes): validates the sets and hidden
// indices, packs everything once, testing the static positions as they are
// packed (errors name the cloud `static_what`), and renders the frames.
void RenderCheckedScene(const PointCloud& static_cloud,
                        const std::string& static_what,
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
  // Footprints: the static cloud's with SplatSize::kFootprint (frame 0's
  // camera as the capture when it has none), every set's that has them.
  const bool zbuffer = options.mode == RenderMode::kZBuffer;
  const bool static_footprints =
      zbuffer && options.splat_size == SplatSize::kFootprint;
  PackedCloud packed;
  packed.Reserve(total, options);
  bool finite;
  if (static_footprints && !static_cloud.HasFootprints()) {
    static_cloud.Check(static_what);  // before the footprints
    PointCloud with_footprints = static_cloud;
    SetCaptureFootprints(frame_cameras[0], cam_from_world[0], &with_footprints);
    finite = packed.Assign(0, with_footprints, options, true);
  } else {
    finite = packed.Assign(0, static_cloud, options, static_footprints);
  }
  // The positions are checked here, as they were packed: Check names the
  // first point that is not finite.
  if (!finite) static_cloud.Check(static_what);
  std::vector<int> offsets(sets.size());
  for (size_t k = 0; k < sets.size(); ++k) {
    offsets[k] = static_cast<int>(packed.size());
    packed.Assign(offsets[k], sets[k].points, options, zbuffer);
    if (options.output_instance) {
      std::fill(packed.instance.begin() + offsets[k],
                packed.instance.begin() + offsets[k] + sets[k].points.size(),
                sets[k].instance_id);
    }
  }
  // Frustum culling boxes (renderer_internal.h) for every z-buffer path:
  // single pixels, disks and footprints, each culled with its reach.
  const bool cull = zbuffer && UseCulling();
  const size_t num_groups = (packed.size() + kCullGroup - 1) / kCullGroup;
  if (cull) packed.cull_box.resize(9 * num_groups);
  RenderResult& result = *result_out;
  result.frames.resize(num_frames);
  const int threads =
      options.num_threads > 0 ? options.num_threads : omp_get_max_threads();
  const bool stream_outputs =
      renderer_internal::StreamOutputs(options, num_frames);
#pragma omp parallel num_threads(std::min(threads, num_frames))
  {
    if (cull) {
      // 64 groups a chunk; the loop's barrier makes every box ready.
      const int64_t chunks = static_cast<int64_t>((num_groups + 63) / 64);
#pragma omp for schedule(static)
      for (int64_t c = 0; c < chunks; ++c) {
        ComputeCullBoxes(64 * c,
                         std::min(num_groups, static_cast<size_t>(64 * c + 64)),
                         &packed);
      }
    }
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
        ranges.push_back(ProjectedRange{run.first, run.second, camera_proj,
                                        static_footprints ? 1.0f : 0.0f});
      for (size_t k = 0; k < sets.size(); ++k) {
        const std::optional<Matrix3x4d>& a = sets[k].world_from_set[f];
        if (!a || sets[k].points.empty()) continue;
        // cam_from_set = cam_from_world * world_from_set.
        // A set's footprints grow with its largest axis scale.
        const float footprint_scale =
            zbuffer && sets[k].points.HasFootprints()
                ? static_cast<float>(
                      a->leftCols<3>().colwise().norm().maxCoeff())
                : 0.0f;
        ranges.push_back(ProjectedRange{
            offsets[k], offsets[k] + static_cast<int>(sets[k].points.size()),
            FrameProjector(frame_cameras[f], cam_r * a->leftCols<3>(),
                           cam_r * a->col(3) + cam_t, options),
            footprint_scale});
      }
      RenderOne(packed, ranges, options, stream_outputs, &scratch,
                &result.frames[f]);
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
  RenderCheckedScene(cloud_in_world, "render: point cloud", {}, {},
                     frame_cameras, cam_from_world, options, start, result_out);
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
  static_cloud.CheckAttributes("render: static point cloud");
  RenderCheckedScene(static_cloud, "render: static point cloud", sets,
                     hidden_static, frame_cameras, cam_from_world, options,
                     start, result_out);
}

}  // namespace geodrive

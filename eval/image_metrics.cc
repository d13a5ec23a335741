#include "eval/image_metrics.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <type_traits>

#include "geometry/util/simd.h"
#include "geometry/util/status.h"

// The PSNR sum of squares is compiled three times on x86-64 GCC (x86-64-v4 =
// AVX-512, x86-64-v3 = AVX2 + FMA, and baseline) and the loader picks the clone
// the CPU supports (GCC function multiversioning through an ifunc). The fused
// SSIM kernel has its own AVX-512 / AVX2 / baseline variants (different vector
// widths, see SelectFusedSsim5). Helpers are force-inlined into them: a helper
// that is only `inline` is compiled once, for the baseline target, and the
// variants would just call it.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && \
    defined(__linux__)
#define GEODRIVE_SIMD_CLONES \
  __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define GEODRIVE_SIMD_CLONES
#endif

namespace geodrive {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string TypeName(const cv::Mat& m) {
  std::ostringstream os;
  os << (m.depth() == CV_8U    ? "uint8"
         : m.depth() == CV_64F ? "float64"
                               : "other depth")
     << " x " << m.channels();
  return os.str();
}

void CheckPair(const cv::Mat& a, const cv::Mat& b, const std::string& what) {
  GEODRIVE_CHECK_INPUT(!a.empty() && !b.empty(), what, ": empty image");
  GEODRIVE_CHECK_INPUT(a.size() == b.size(), what, ": image sizes differ (",
                       a.cols, "x", a.rows, " vs ", b.cols, "x", b.rows, ")");
  GEODRIVE_CHECK_INPUT(a.type() == b.type(), what, ": image types differ (",
                       TypeName(a), " vs ", TypeName(b), ")");
  GEODRIVE_CHECK_INPUT((a.depth() == CV_8U || a.depth() == CV_64F) &&
                           (a.channels() == 1 || a.channels() == 3),
                       what, ": unsupported image type ", TypeName(a),
                       " (expected uint8 or float64 with 1 or 3 channels)");
}

// Normalised Gaussian taps w[0..radius] (w[0] = centre) exactly as
// scipy.ndimage's _gaussian_kernel1d: exp(-0.5 x^2 / sigma^2) / sum.
std::vector<double> GaussianTaps(double sigma, int radius) {
  std::vector<double> w(radius + 1);
  double sum = 0;
  for (int x = -radius; x <= radius; ++x)
    sum += std::exp(-0.5 * x * x / (sigma * sigma));
  for (int x = 0; x <= radius; ++x)
    w[x] = std::exp(-0.5 * x * x / (sigma * sigma)) / sum;
  return w;
}

// ---- Fused SSIM, radius 5 (the Wang et al. window) ----
//
// Horizontal pass first, in column strips of kStrip interleaved outputs so
// that the 11-row ring of filtered rows stays in L1. Per input row of a strip:
// the four per-element maps x, y, x^2 + y^2 and xy (float64; exact for uint8
// input) are filtered horizontally (11 symmetric taps, step `channels`) into
// the ring slot of that row; once 11 rows are in the ring, the vertical pass,
// the SSIM element and the accumulation into per-element column sums run in
// one loop. Each input row is converted and filtered once per strip. Only four
// maps are needed because SSIM uses sigma_x^2 + sigma_y^2 (= E[x^2 + y^2] -
// mu_x^2 - mu_y^2) and sigma_xy. Everything is float64: float32, even with
// the input centred at 128, misses the 1e-9 agreement with skimage that the
// tests hold (docs/PERFORMANCE.md, "Evaluation metrics").
constexpr int kStrip = 96;  // interleaved outputs per strip (ring: 33 KiB)

template <typename T, int C>
GEODRIVE_FORCE_INLINE void ConvertStripRow(const T* __restrict a,
                                           const T* __restrict b,
                                           int n,
                                           double* __restrict tx,
                                           double* __restrict ty,
                                           double* __restrict tp,
                                           double* __restrict tq) {
  for (int i = 0; i < n; ++i) {
    const double x = a[i], y = b[i];
    tx[i] = x;
    ty[i] = y;
    tp[i] = x * x + y * y;
    tq[i] = x * y;
  }
}

// d[j] = sum_k w_|k| s[j + C (5 + k)], k = -5..5, j < n.
template <int C>
GEODRIVE_FORCE_INLINE void HorizontalPass5(const double* __restrict s,
                                           double* __restrict d,
                                           int n,
                                           const double* w) {
  const double w0 = w[0], w1 = w[1], w2 = w[2], w3 = w[3], w4 = w[4], w5 = w[5];
  for (int j = 0; j < n; ++j) {
    const double* p = s + j + 5 * C;
    d[j] = w0 * p[0] + w1 * (p[-C] + p[C]) + w2 * (p[-2 * C] + p[2 * C]) +
           w3 * (p[-3 * C] + p[3 * C]) + w4 * (p[-4 * C] + p[4 * C]) +
           w5 * (p[-5 * C] + p[5 * C]);
  }
}

// W doubles (and W floats) as GCC vectors; each ISA variant of the kernel uses
// its register width (W = 8 for AVX-512, 4 for AVX2, 2 for SSE2). The vertical
// pass is written with them because the auto-vectoriser gives each of its 44
// loads its own pointer, which spill.
// The helpers taking and returning these vectors are always inlined, so the
// ABI note GCC gives for wide vector arguments does not apply.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif
template <int W>
struct Vec {
  typedef double D __attribute__((vector_size(8 * W)));
  typedef float F __attribute__((vector_size(4 * W)));
};

template <int W>
GEODRIVE_FORCE_INLINE typename Vec<W>::D LoadVec(const double* p) {
  typename Vec<W>::D v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}

// SSIM of one element (V = double, F = float) or of a vector (V = Vec<W>::D,
// F = Vec<W>::F) from the four filtered maps. kFastDivide: the division is a
// float32 reciprocal refined by one Newton step in float64 (relative error <=
// ~1e-14; only where the denominator is known to be a normal float, see
// FusedSsim5).
template <bool kFastDivide, typename V, typename F>
GEODRIVE_FORCE_INLINE V
SsimElement(V ux, V uy, V ep, V eq, double c1, double c2) {
  const V uxy = ux * uy, uu = ux * ux + uy * uy;
  const V num = (2 * uxy + c1) * (2 * (eq - uxy) + c2);
  const V den = (uu + c1) * (ep - uu + c2);
  if constexpr (kFastDivide) {
    V r0;
    if constexpr (std::is_same_v<V, double>) {
      r0 = static_cast<double>(1.0f / static_cast<float>(den));
    } else {
      r0 = __builtin_convertvector(1.0f / __builtin_convertvector(den, F), V);
    }
    const V r1 = r0 + r0 * (1.0 - den * r0);
    return num * r1;
  } else {
    return num / den;
  }
}

// Vertical pass over the 11 ring slots (slot s at ring + s * 4 * kStrip holds
// [mu_x | mu_y | E[x^2+y^2] | E[xy]], each kStrip long, of the input row whose
// vertical weight is ws[s]), SSIM per element, acc[j] += ssim. Rotating the
// weights instead of the slots keeps every address a constant offset from one
// pointer.
template <bool kFastDivide, int W>
GEODRIVE_FORCE_INLINE void VerticalSsim5(const double* __restrict ring,
                                         const double* ws,
                                         int n,
                                         double c1,
                                         double c2,
                                         double* __restrict acc) {
  const double v0 = ws[0], v1 = ws[1], v2 = ws[2], v3 = ws[3], v4 = ws[4],
               v5 = ws[5], v6 = ws[6], v7 = ws[7], v8 = ws[8], v9 = ws[9],
               v10 = ws[10];
  constexpr int S = kStrip, L = 4 * kStrip;
#define GEODRIVE_V5(LD, p)                                              \
  (v0 * LD(p) + v1 * LD((p) + L) + v2 * LD((p) + 2 * L) +               \
   v3 * LD((p) + 3 * L) + v4 * LD((p) + 4 * L) + v5 * LD((p) + 5 * L) + \
   v6 * LD((p) + 6 * L) + v7 * LD((p) + 7 * L) + v8 * LD((p) + 8 * L) + \
   v9 * LD((p) + 9 * L) + v10 * LD((p) + 10 * L))
#define GEODRIVE_DEREF(p) (*(p))
  typedef typename Vec<W>::D V;
  typedef typename Vec<W>::F F;
  int j = 0;
  for (; j + W <= n; j += W) {
    const double* p = ring + j;
    const V s = SsimElement<kFastDivide, V, F>(
        GEODRIVE_V5(LoadVec<W>, p), GEODRIVE_V5(LoadVec<W>, p + S),
        GEODRIVE_V5(LoadVec<W>, p + 2 * S), GEODRIVE_V5(LoadVec<W>, p + 3 * S),
        c1, c2);
    const V sum = LoadVec<W>(acc + j) + s;
    std::memcpy(acc + j, &sum, sizeof(sum));
  }
  for (; j < n; ++j) {
    const double* p = ring + j;
    acc[j] += SsimElement<kFastDivide, double, float>(
        GEODRIVE_V5(GEODRIVE_DEREF, p), GEODRIVE_V5(GEODRIVE_DEREF, p + S),
        GEODRIVE_V5(GEODRIVE_DEREF, p + 2 * S),
        GEODRIVE_V5(GEODRIVE_DEREF, p + 3 * S), c1, c2);
  }
#undef GEODRIVE_DEREF
#undef GEODRIVE_V5
}

template <typename T, int C, int W>
GEODRIVE_FORCE_INLINE void FusedSsim5(const cv::Mat& a,
                                      const cv::Mat& b,
                                      const double* w,
                                      double c1,
                                      double c2,
                                      double* channel_means) {
  const int rows = a.rows, cols = a.cols;
  const int len = cols * C;        // interleaved row length
  const int nv = (cols - 10) * C;  // valid interleaved outputs per row
  // Converted input per strip row, rounded up to whole 16-lane vectors.
  constexpr int kIn = (kStrip + 10 * C + 15) / 16 * 16;
  std::vector<double> buffer(static_cast<size_t>(nv) + 4 * kIn +
                             11 * 4 * kStrip);
  double* acc = buffer.data();  // column sums of the SSIM map
  double* tx = acc + nv;
  double* ty = tx + kIn;
  double* tp = ty + kIn;
  double* tq = tp + kIn;
  double* ring = tq + kIn;
  // The float32 reciprocal needs the denominator, which lies in [c1 c2,
  // (2 max^2 + c1)(2 max^2 + c2)], to be a normal float: bounded for uint8.
  const double top = 2.0 * 255 * 255;
  const bool fast_divide = std::is_same_v<T, uint8_t> && c1 * c2 > 1e-30 &&
                           (top + c1) * (top + c2) < 1e30;
  for (int j0 = 0; j0 < nv; j0 += kStrip) {
    const int n = std::min(kStrip, nv - j0);
    const int n_in = std::min(kIn, len - j0);
    for (int r = 0; r < rows; ++r) {
      // Rows are 720 * 3 bytes apart, beyond the hardware stride prefetcher's
      // reach: fetch the strip of the row two ahead explicitly.
      if (r + 2 < rows) {
        const char* pa = reinterpret_cast<const char*>(a.ptr<T>(r + 2) + j0);
        const char* pb = reinterpret_cast<const char*>(b.ptr<T>(r + 2) + j0);
        const size_t last = n_in * sizeof(T) - 1;
        for (size_t o = 0; o < last; o += 64) {
          __builtin_prefetch(pa + o);
          __builtin_prefetch(pb + o);
        }
        __builtin_prefetch(pa + last);
        __builtin_prefetch(pb + last);
      }
      ConvertStripRow<T, C>(a.ptr<T>(r) + j0, b.ptr<T>(r) + j0, n_in, tx, ty,
                            tp, tq);
      double* slot = ring + (r % 11) * 4 * kStrip;
      HorizontalPass5<C>(tx, slot, n, w);
      HorizontalPass5<C>(ty, slot + kStrip, n, w);
      HorizontalPass5<C>(tp, slot + 2 * kStrip, n, w);
      HorizontalPass5<C>(tq, slot + 3 * kStrip, n, w);
      if (r < 10) continue;
      // Slot s holds input row r - 10 + k, k = (s - (r - 10)) mod 11, whose
      // weight is w[|k - 5|].
      double ws[11];
      const int first = (r - 10) % 11;
      for (int s = 0; s < 11; ++s)
        ws[s] = w[std::abs((s - first + 11) % 11 - 5)];
      if (fast_divide) {
        VerticalSsim5<true, W>(ring, ws, n, c1, c2, acc + j0);
      } else {
        VerticalSsim5<false, W>(ring, ws, n, c1, c2, acc + j0);
      }
    }
  }
  // Per-channel sums (float64, like skimage's mean(dtype=float64) up to
  // summation order).
  double sums[C] = {};
  for (int j = 0; j < nv; j += C) {
    for (int c = 0; c < C; ++c) sums[c] += acc[j + c];
  }
  const double count = static_cast<double>(rows - 10) * (cols - 10);
  for (int c = 0; c < C; ++c) channel_means[c] = sums[c] / count;
}

// The kernel for each (type, channels) in three ISA variants: AVX-512 (8-wide
// vectors), AVX2 + FMA (4-wide) and baseline (2-wide), picked at run time.
typedef void (*FusedSsimFn)(
    const cv::Mat&, const cv::Mat&, const double*, double, double, double*);

template <typename T, int C>
void FusedSsim5Baseline(const cv::Mat& a,
                        const cv::Mat& b,
                        const double* w,
                        double c1,
                        double c2,
                        double* out) {
  FusedSsim5<T, C, 2>(a, b, w, c1, c2, out);
}

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define GEODRIVE_ISA_VARIANTS 1
template <typename T, int C>
__attribute__((target("avx512f,avx512dq,avx512bw,avx512vl,avx2,fma"))) void
FusedSsim5Avx512(const cv::Mat& a,
                 const cv::Mat& b,
                 const double* w,
                 double c1,
                 double c2,
                 double* out) {
  FusedSsim5<T, C, 8>(a, b, w, c1, c2, out);
}

template <typename T, int C>
__attribute__((target("avx2,fma"))) void FusedSsim5Avx2(const cv::Mat& a,
                                                        const cv::Mat& b,
                                                        const double* w,
                                                        double c1,
                                                        double c2,
                                                        double* out) {
  FusedSsim5<T, C, 4>(a, b, w, c1, c2, out);
}

// 2 = AVX-512 (the features the variant is compiled for), 1 = AVX2 + FMA,
// 0 = baseline.
int CpuLevel() {
  static const int level = [] {
    __builtin_cpu_init();
    const bool avx2 =
        __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    const bool avx512 = avx2 && __builtin_cpu_supports("avx512f") &&
                        __builtin_cpu_supports("avx512dq") &&
                        __builtin_cpu_supports("avx512bw") &&
                        __builtin_cpu_supports("avx512vl");
    return avx512 ? 2 : avx2 ? 1 : 0;
  }();
  return level;
}
#endif

template <typename T, int C>
FusedSsimFn SelectFusedSsim5() {
#ifdef GEODRIVE_ISA_VARIANTS
  switch (CpuLevel()) {
    case 2:
      return FusedSsim5Avx512<T, C>;
    case 1:
      return FusedSsim5Avx2<T, C>;
    default:
      break;
  }
#endif
  return FusedSsim5Baseline<T, C>;
}

// Exact sum of (a[i] - b[i])^2 over uint8 data: 32-bit partial sums over
// blocks of 65536 elements (65536 * 255^2 < 2^32), which vectorise.
GEODRIVE_SIMD_CLONES uint64_t SumSquaredDifferencesU8(const uint8_t* a,
                                                      const uint8_t* b,
                                                      int n) {
  uint64_t total = 0;
  for (int i0 = 0; i0 < n; i0 += 65536) {
    const int end = std::min(n, i0 + 65536);
    uint32_t block = 0;
    for (int i = i0; i < end; ++i) {
      const int d = static_cast<int>(a[i]) - static_cast<int>(b[i]);
      block += static_cast<uint32_t>(d * d);
    }
    total += block;
  }
  return total;
}

// ---- Generic SSIM (any radius): skimage's five filtered maps through
// cv::sepFilter2D ---- scipy's mode='reflect' (d c b a | a b c d) is OpenCV's
// BORDER_REFLECT; the border only affects the cropped band anyway.
double GenericSsimChannel(const cv::Mat& x,
                          const cv::Mat& y,
                          const std::vector<double>& taps,
                          double c1,
                          double c2) {
  const int radius = static_cast<int>(taps.size()) - 1;
  cv::Mat kernel(2 * radius + 1, 1, CV_64F);
  for (int i = -radius; i <= radius; ++i)
    kernel.at<double>(i + radius) = taps[std::abs(i)];
  auto filter = [&](const cv::Mat& in) {
    cv::Mat out;
    cv::sepFilter2D(in, out, CV_64F, kernel, kernel, cv::Point(-1, -1), 0,
                    cv::BORDER_REFLECT);
    return out;
  };
  const cv::Mat ux = filter(x), uy = filter(y);
  const cv::Mat uxx = filter(x.mul(x)), uyy = filter(y.mul(y)),
                uxy = filter(x.mul(y));
  double sum = 0;
  for (int r = radius; r < x.rows - radius; ++r) {
    for (int c = radius; c < x.cols - radius; ++c) {
      const double mx = ux.at<double>(r, c), my = uy.at<double>(r, c);
      const double vx = uxx.at<double>(r, c) - mx * mx;
      const double vy = uyy.at<double>(r, c) - my * my;
      const double vxy = uxy.at<double>(r, c) - mx * my;
      sum += ((2 * mx * my + c1) * (2 * vxy + c2)) /
             ((mx * mx + my * my + c1) * (vx + vy + c2));
    }
  }
  return sum /
         (static_cast<double>(x.rows - 2 * radius) * (x.cols - 2 * radius));
}

}  // namespace

void PsnrOptions::Check() const {
  GEODRIVE_CHECK_INPUT(std::isfinite(data_range) && data_range > 0,
                       "psnr: data_range must be > 0, got ", data_range);
  GEODRIVE_CHECK_INPUT(std::isfinite(max_db), "psnr: max_db must be finite");
}

void SsimOptions::Check() const {
  GEODRIVE_CHECK_INPUT(std::isfinite(data_range) && data_range > 0,
                       "ssim: data_range must be > 0, got ", data_range);
  GEODRIVE_CHECK_INPUT(sigma > 0 && sigma < 50,
                       "ssim: sigma must be in (0, 50), got ", sigma);
  GEODRIVE_CHECK_INPUT(truncate > 0 && truncate < 10,
                       "ssim: truncate must be in (0, 10), got ", truncate);
  GEODRIVE_CHECK_INPUT(k1 > 0 && k2 > 0, "ssim: k1 and k2 must be > 0");
}

int SsimOptions::Radius() const {
  return static_cast<int>(truncate * sigma + 0.5);
}

double MeanSquaredError(const cv::Mat& a, const cv::Mat& b) {
  CheckPair(a, b, "mse");
  const int n = a.cols * a.channels();
  double total = 0;
  for (int r = 0; r < a.rows; ++r) {
    if (a.depth() == CV_8U) {
      const uint8_t* pa = a.ptr<uint8_t>(r);
      const uint8_t* pb = b.ptr<uint8_t>(r);
      total += static_cast<double>(SumSquaredDifferencesU8(pa, pb, n));
    } else {
      const double* pa = a.ptr<double>(r);
      const double* pb = b.ptr<double>(r);
      double row = 0;
      for (int j = 0; j < n; ++j) row += (pa[j] - pb[j]) * (pa[j] - pb[j]);
      total += row;
    }
  }
  return total / (static_cast<double>(a.rows) * n);
}

double Psnr(const cv::Mat& a,
            const cv::Mat& b,
            const PsnrOptions& options,
            const std::string& what) {
  options.Check();
  CheckPair(a, b, what);
  const double mse = MeanSquaredError(a, b);
  const double r2 = options.data_range * options.data_range;
  if (mse / r2 < 1e-10) return options.max_db;
  return 10.0 * std::log10(r2 / mse);
}

std::vector<double> SsimPerChannel(const cv::Mat& a,
                                   const cv::Mat& b,
                                   const SsimOptions& options,
                                   const std::string& what) {
  options.Check();
  CheckPair(a, b, what);
  const int radius = options.Radius();
  const int win = 2 * radius + 1;
  GEODRIVE_CHECK_INPUT(a.rows >= win && a.cols >= win, what, ": image ", a.cols,
                       "x", a.rows, " is smaller than the ", win, "x", win,
                       " SSIM window");
  const std::vector<double> taps = GaussianTaps(options.sigma, radius);
  const double c1 = std::pow(options.k1 * options.data_range, 2);
  const double c2 = std::pow(options.k2 * options.data_range, 2);
  const int channels = a.channels();
  std::vector<double> result(channels);
  if (radius == 5 && options.fused_kernel) {
    const bool u8 = a.depth() == CV_8U;
    const FusedSsimFn kernel = channels == 1
                                   ? (u8 ? SelectFusedSsim5<uint8_t, 1>()
                                         : SelectFusedSsim5<double, 1>())
                                   : (u8 ? SelectFusedSsim5<uint8_t, 3>()
                                         : SelectFusedSsim5<double, 3>());
    kernel(a, b, taps.data(), c1, c2, result.data());
    return result;
  }
  cv::Mat fa, fb;
  a.convertTo(fa, CV_64F);
  b.convertTo(fb, CV_64F);
  std::vector<cv::Mat> ca, cb;
  cv::split(fa, ca);
  cv::split(fb, cb);
  for (int c = 0; c < channels; ++c)
    result[c] = GenericSsimChannel(ca[c], cb[c], taps, c1, c2);
  return result;
}

double Ssim(const cv::Mat& a,
            const cv::Mat& b,
            const SsimOptions& options,
            const std::string& what) {
  const std::vector<double> per_channel = SsimPerChannel(a, b, options, what);
  double sum = 0;
  for (double v : per_channel) sum += v;
  return sum / static_cast<double>(per_channel.size());
}

cv::Mat LumaBt601(const cv::Mat& rgb) {
  GEODRIVE_CHECK_INPUT(
      !rgb.empty() && rgb.channels() == 3 &&
          (rgb.depth() == CV_8U || rgb.depth() == CV_64F),
      "luma: expected an RGB image (uint8 or float64 x 3), got ",
      TypeName(rgb));
  cv::Mat y(rgb.size(), CV_64FC1);
  for (int r = 0; r < rgb.rows; ++r) {
    double* out = y.ptr<double>(r);
    if (rgb.depth() == CV_8U) {
      const uint8_t* p = rgb.ptr<uint8_t>(r);
      for (int c = 0; c < rgb.cols; ++c) {
        out[c] = 0.299 * p[3 * c] + 0.587 * p[3 * c + 1] + 0.114 * p[3 * c + 2];
      }
    } else {
      const double* p = rgb.ptr<double>(r);
      for (int c = 0; c < rgb.cols; ++c) {
        out[c] = 0.299 * p[3 * c] + 0.587 * p[3 * c + 1] + 0.114 * p[3 * c + 2];
      }
    }
  }
  return y;
}

void FrameMetricsOptions::Check() const {
  GEODRIVE_CHECK_INPUT(psnr || ssim,
                       "frame metrics: neither psnr nor ssim requested");
  psnr_options.Check();
  ssim_options.Check();
  GEODRIVE_CHECK_INPUT(num_threads >= 0,
                       "frame metrics: num_threads must be >= 0");
}

std::string VideoScores::BriefReport() const {
  std::ostringstream os;
  os << frames.size() << " frames " << width << "x" << height << ": PSNR "
     << mean.psnr_rgb << " dB, SSIM " << mean.ssim_rgb;
  if (!std::isnan(mean.psnr_y) || !std::isnan(mean.ssim_y)) {
    os << ", PSNR-Y " << mean.psnr_y << " dB, SSIM-Y " << mean.ssim_y;
  }
  return os.str();
}

VideoScores CompareVideos(const std::vector<cv::Mat>& pred,
                          const std::vector<cv::Mat>& gt,
                          const FrameMetricsOptions& options,
                          const std::string& what,
                          int64_t first_frame) {
  options.Check();
  GEODRIVE_CHECK_INPUT(!pred.empty(), what,
                       ": the predicted video has no frames");
  GEODRIVE_CHECK_INPUT(!gt.empty(), what,
                       ": the ground-truth video has no frames");
  GEODRIVE_CHECK_INPUT(pred.size() == gt.size(), what,
                       ": frame counts differ (predicted ", pred.size(),
                       ", ground truth ", gt.size(), ")");
  for (size_t i = 0; i < pred.size(); ++i) {
    const std::string frame =
        what + " frame " + std::to_string(first_frame + int64_t(i));
    CheckPair(pred[i], gt[i], frame);
    GEODRIVE_CHECK_INPUT(pred[i].size() == pred[0].size(), frame, ": size ",
                         pred[i].cols, "x", pred[i].rows,
                         " differs from frame 0 (", pred[0].cols, "x",
                         pred[0].rows, ")");
    if (options.luma) {
      GEODRIVE_CHECK_INPUT(pred[i].channels() == 3, frame,
                           ": luma metrics need RGB frames");
    }
  }
  VideoScores scores;
  scores.width = gt[0].cols;
  scores.height = gt[0].rows;
  scores.frames.resize(pred.size());
  const int n = static_cast<int>(pred.size());
  const int threads =
      options.num_threads > 0 ? options.num_threads : omp_get_max_threads();
  std::string error;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (int i = 0; i < n; ++i) {
    try {
      FrameScores& f = scores.frames[i];
      const std::string frame =
          what + " frame " + std::to_string(first_frame + i);
      f.psnr_rgb = options.psnr
                       ? Psnr(pred[i], gt[i], options.psnr_options, frame)
                       : kNaN;
      f.ssim_rgb = options.ssim
                       ? Ssim(pred[i], gt[i], options.ssim_options, frame)
                       : kNaN;
      f.psnr_y = f.ssim_y = kNaN;
      if (options.luma) {
        const cv::Mat yp = LumaBt601(pred[i]), yg = LumaBt601(gt[i]);
        if (options.psnr) f.psnr_y = Psnr(yp, yg, options.psnr_options, frame);
        if (options.ssim) f.ssim_y = Ssim(yp, yg, options.ssim_options, frame);
      }
    } catch (const std::exception& e) {
#pragma omp critical
      if (error.empty()) error = e.what();
    }
  }
  if (!error.empty()) throw InputError(error);
  scores.mean = MeanOfFrames(scores.frames);
  return scores;
}

FrameScores MeanOfFrames(const std::vector<FrameScores>& frames) {
  FrameScores m{0, 0, 0, 0};
  const int n = static_cast<int>(frames.size());
  for (const FrameScores& f : frames) {
    m.psnr_rgb += f.psnr_rgb / n;
    m.ssim_rgb += f.ssim_rgb / n;
    m.psnr_y += f.psnr_y / n;
    m.ssim_y += f.ssim_y / n;
  }
  return m;
}

}  // namespace geodrive

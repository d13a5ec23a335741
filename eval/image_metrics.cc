#include "eval/image_metrics.h"

#include <omp.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <type_traits>

#include "geometry/status.h"

// The fused SSIM kernel is compiled twice on x86-64 GCC (AVX2+FMA and baseline)
// and the loader picks the clone the CPU supports (GCC function multiversioning
// through an ifunc).
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && \
    defined(__linux__)
#define GEODRIVE_SIMD_CLONES \
  __attribute__((target_clones("avx2,fma", "default")))
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
// For every valid output row: vertical 11-tap pass over the interleaved input
// rows (all channels at once) producing the four maps mu_x, mu_y, E[x^2 + y^2],
// E[xy]; horizontal 11-tap pass with a step of `channels`; SSIM per element;
// per-channel sums. Only four filtered maps are needed because SSIM uses
// sigma_x^2 + sigma_y^2 (= E[x^2 + y^2] - mu_x^2 - mu_y^2) and sigma_xy.
// Everything is float64; for uint8 input the symmetric pair sums are exact
// integers.
template <typename T>
inline void VerticalPass5(const T* const* xr,
                          const T* const* yr,
                          int n,
                          const double* w,
                          double* __restrict vx,
                          double* __restrict vy,
                          double* __restrict vp,
                          double* __restrict vq) {
  using Acc = std::conditional_t<std::is_same_v<T, uint8_t>, int, double>;
  const double w0 = w[0], w1 = w[1], w2 = w[2], w3 = w[3], w4 = w[4], w5 = w[5];
  const T* __restrict x0 = xr[0];
  const T* __restrict x1 = xr[1];
  const T* __restrict x2 = xr[2];
  const T* __restrict x3 = xr[3];
  const T* __restrict x4 = xr[4];
  const T* __restrict x5 = xr[5];
  const T* __restrict x6 = xr[6];
  const T* __restrict x7 = xr[7];
  const T* __restrict x8 = xr[8];
  const T* __restrict x9 = xr[9];
  const T* __restrict x10 = xr[10];
  const T* __restrict y0 = yr[0];
  const T* __restrict y1 = yr[1];
  const T* __restrict y2 = yr[2];
  const T* __restrict y3 = yr[3];
  const T* __restrict y4 = yr[4];
  const T* __restrict y5 = yr[5];
  const T* __restrict y6 = yr[6];
  const T* __restrict y7 = yr[7];
  const T* __restrict y8 = yr[8];
  const T* __restrict y9 = yr[9];
  const T* __restrict y10 = yr[10];
  for (int j = 0; j < n; ++j) {
    const Acc a0 = x0[j], a1 = x1[j], a2 = x2[j], a3 = x3[j], a4 = x4[j],
              a5 = x5[j], a6 = x6[j], a7 = x7[j], a8 = x8[j], a9 = x9[j],
              a10 = x10[j];
    const Acc b0 = y0[j], b1 = y1[j], b2 = y2[j], b3 = y3[j], b4 = y4[j],
              b5 = y5[j], b6 = y6[j], b7 = y7[j], b8 = y8[j], b9 = y9[j],
              b10 = y10[j];
    vx[j] = w0 * a5 + w1 * (a4 + a6) + w2 * (a3 + a7) + w3 * (a2 + a8) +
            w4 * (a1 + a9) + w5 * (a0 + a10);
    vy[j] = w0 * b5 + w1 * (b4 + b6) + w2 * (b3 + b7) + w3 * (b2 + b8) +
            w4 * (b1 + b9) + w5 * (b0 + b10);
    vp[j] = w0 * (a5 * a5 + b5 * b5) +
            w1 * (a4 * a4 + a6 * a6 + b4 * b4 + b6 * b6) +
            w2 * (a3 * a3 + a7 * a7 + b3 * b3 + b7 * b7) +
            w3 * (a2 * a2 + a8 * a8 + b2 * b2 + b8 * b8) +
            w4 * (a1 * a1 + a9 * a9 + b1 * b1 + b9 * b9) +
            w5 * (a0 * a0 + a10 * a10 + b0 * b0 + b10 * b10);
    vq[j] = w0 * (a5 * b5) + w1 * (a4 * b4 + a6 * b6) +
            w2 * (a3 * b3 + a7 * b7) + w3 * (a2 * b2 + a8 * b8) +
            w4 * (a1 * b1 + a9 * b9) + w5 * (a0 * b0 + a10 * b10);
  }
}

// Horizontal valid pass over interleaved data: d[j] = sum_k w_k s[j + c (5 +
// k)], n outputs.
template <int C>
inline void HorizontalPass5(const double* __restrict s,
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

template <typename T, int C>
inline void FusedSsim5(const cv::Mat& a,
                       const cv::Mat& b,
                       const double* w,
                       double c1,
                       double c2,
                       double* channel_means) {
  const int rows = a.rows, cols = a.cols;
  const int len = cols * C;        // interleaved row length
  const int nv = (cols - 10) * C;  // valid interleaved outputs per row
  std::vector<double> buffer(4 * static_cast<size_t>(len) +
                             5 * static_cast<size_t>(nv));
  double* vx = buffer.data();
  double* vy = vx + len;
  double* vp = vy + len;
  double* vq = vp + len;
  double* hx = vq + len;
  double* hy = hx + nv;
  double* hp = hy + nv;
  double* hq = hp + nv;
  double* s = hq + nv;
  double sums[C] = {};
  for (int r = 5; r < rows - 5; ++r) {
    const T* xr[11];
    const T* yr[11];
    for (int k = 0; k < 11; ++k) {
      xr[k] = a.ptr<T>(r - 5 + k);
      yr[k] = b.ptr<T>(r - 5 + k);
    }
    VerticalPass5<T>(xr, yr, len, w, vx, vy, vp, vq);
    HorizontalPass5<C>(vx, hx, nv, w);
    HorizontalPass5<C>(vy, hy, nv, w);
    HorizontalPass5<C>(vp, hp, nv, w);
    HorizontalPass5<C>(vq, hq, nv, w);
    for (int j = 0; j < nv; ++j) {
      const double ux = hx[j], uy = hy[j];
      const double uxy = ux * uy, uu = ux * ux + uy * uy;
      s[j] = ((2 * uxy + c1) * (2 * (hq[j] - uxy) + c2)) /
             ((uu + c1) * (hp[j] - uu + c2));
    }
    // Row sums per channel (float64, like skimage's mean(dtype=float64) up to
    // summation order).
    double row[C] = {};
    for (int j = 0; j < nv; j += C) {
      for (int c = 0; c < C; ++c) row[c] += s[j + c];
    }
    for (int c = 0; c < C; ++c) sums[c] += row[c];
  }
  const double count = static_cast<double>(rows - 10) * (cols - 10);
  for (int c = 0; c < C; ++c) channel_means[c] = sums[c] / count;
}

GEODRIVE_SIMD_CLONES void FusedSsim5U8C1(const cv::Mat& a,
                                         const cv::Mat& b,
                                         const double* w,
                                         double c1,
                                         double c2,
                                         double* out) {
  FusedSsim5<uint8_t, 1>(a, b, w, c1, c2, out);
}
GEODRIVE_SIMD_CLONES void FusedSsim5U8C3(const cv::Mat& a,
                                         const cv::Mat& b,
                                         const double* w,
                                         double c1,
                                         double c2,
                                         double* out) {
  FusedSsim5<uint8_t, 3>(a, b, w, c1, c2, out);
}
GEODRIVE_SIMD_CLONES void FusedSsim5F64C1(const cv::Mat& a,
                                          const cv::Mat& b,
                                          const double* w,
                                          double c1,
                                          double c2,
                                          double* out) {
  FusedSsim5<double, 1>(a, b, w, c1, c2, out);
}
GEODRIVE_SIMD_CLONES void FusedSsim5F64C3(const cv::Mat& a,
                                          const cv::Mat& b,
                                          const double* w,
                                          double c1,
                                          double c2,
                                          double* out) {
  FusedSsim5<double, 3>(a, b, w, c1, c2, out);
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
      int64_t row = 0;  // exact
      for (int j = 0; j < n; ++j) {
        const int d = static_cast<int>(pa[j]) - static_cast<int>(pb[j]);
        row += d * d;
      }
      total += static_cast<double>(row);
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
    if (channels == 1) {
      (u8 ? FusedSsim5U8C1 : FusedSsim5F64C1)(a, b, taps.data(), c1, c2,
                                              result.data());
    } else {
      (u8 ? FusedSsim5U8C3 : FusedSsim5F64C3)(a, b, taps.data(), c1, c2,
                                              result.data());
    }
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

std::string VideoScores::Summary() const {
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
                          const std::string& what) {
  options.Check();
  GEODRIVE_CHECK_INPUT(!pred.empty(), what,
                       ": the predicted video has no frames");
  GEODRIVE_CHECK_INPUT(!gt.empty(), what,
                       ": the ground-truth video has no frames");
  GEODRIVE_CHECK_INPUT(pred.size() == gt.size(), what,
                       ": frame counts differ (predicted ", pred.size(),
                       ", ground truth ", gt.size(), ")");
  for (size_t i = 0; i < pred.size(); ++i) {
    const std::string frame = what + " frame " + std::to_string(i);
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
      const std::string frame = what + " frame " + std::to_string(i);
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
  FrameScores& m = scores.mean;
  m = FrameScores{0, 0, 0, 0};
  for (const FrameScores& f : scores.frames) {
    m.psnr_rgb += f.psnr_rgb / n;
    m.ssim_rgb += f.ssim_rgb / n;
    m.psnr_y += f.psnr_y / n;
    m.ssim_y += f.ssim_y / n;
  }
  return scores;
}

}  // namespace geodrive

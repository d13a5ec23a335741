#include "geometry/image_resize.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <utility>
#include <vector>

#include "geometry/util/simd.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

// One axis of an area resampling: output i takes `taps` source samples from
// first[i] on, with weights w[i * taps + k] (zero-padded). The weights are
// cv::INTER_AREA's (computeResizeAreaTab in OpenCV 4.6): the cell [i * scale,
// (i + 1) * scale), each source pixel weighted by its overlap / scale.
struct AreaAxis {
  int taps = 0;
  std::vector<int> first;
  std::vector<float> w;
};

AreaAxis MakeAreaAxis(int source, int out, double scale) {
  AreaAxis a;
  a.taps = std::min(source, static_cast<int>(std::ceil(scale)) + 1);
  a.first.resize(out);
  a.w.assign(static_cast<size_t>(out) * a.taps, 0.f);
  std::vector<std::pair<int, double>> cell;
  for (int i = 0; i < out; ++i) {
    const double f1 = i * scale, f2 = f1 + scale;
    const double width = std::min(scale, source - f1);
    int s2 = std::min(static_cast<int>(std::floor(f2)), source - 1);
    int s1 = std::min(static_cast<int>(std::ceil(f1)), s2);
    cell.clear();
    if (s1 - f1 > 1e-3) cell.emplace_back(s1 - 1, (s1 - f1) / width);
    for (int s = s1; s < s2; ++s) cell.emplace_back(s, 1.0 / width);
    if (f2 - s2 > 1e-3)
      cell.emplace_back(s2, std::min(std::min(f2 - s2, 1.0), width) / width);
    const int first = std::min(cell.front().first, source - a.taps);
    a.first[i] = first;
    for (const auto& [s, weight] : cell) {
      a.w[static_cast<size_t>(i) * a.taps + (s - first)] =
          static_cast<float>(weight);
    }
  }
  return a;
}

// The row kernels get an AVX2 clone picked at run time where the CPU has it
// (GEODRIVE_AVX2_CLONES, geometry/util/simd.h). No FMA and -ffp-contract=off
// (-std=c++17): every lane runs the same multiplies and adds in the same
// order in both clones, so the pixels do not depend on the CPU.
// out[i] = sum over k of w[k] * rows[k][i], i < n (rows with w[k] == 0
// skipped; w[0] always taken).
GEODRIVE_AVX2_CLONES void VerticalRow(
    const uint8_t* const* rows, const float* w, int taps, int n, float* out) {
  const uint8_t* s0 = rows[0];
  const float w0 = w[0];
  for (int i = 0; i < n; ++i) out[i] = w0 * s0[i];
  for (int k = 1; k < taps; ++k) {
    const float wk = w[k];
    if (wk == 0.f) continue;
    const uint8_t* s = rows[k];
    for (int i = 0; i < n; ++i) out[i] += wk * s[i];
  }
}

// v4f: four floats, v8f: eight (GCC/Clang vector extensions; in the AVX2
// clone a v8f is one ymm register, in the baseline two xmm). The helpers
// that pass v8f by value are all force-inlined, so GCC's note that such a
// call's ABI differs with and without AVX concerns no call that is made.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif
typedef float v4f __attribute__((vector_size(16)));
typedef float v8f __attribute__((vector_size(32)));

// The taps' weighted sum, with 0.5 added for the rounding (the sums are >= 0):
// tap(k) is tap k's weighted lanes. kTaps > 0 unrolls them as a pairwise sum
// (no chain of dependent adds); 0 runs `taps`. Every lane sees the same
// multiplies and adds in the same order whatever V is.
template <int kTaps, typename V, typename Tap>
GEODRIVE_FORCE_INLINE V SumTaps(const Tap& tap, int taps) {
  V half;
  for (size_t l = 0; l < sizeof(V) / sizeof(float); ++l) half[l] = 0.5f;
  if constexpr (kTaps == 2) {
    return (tap(0) + tap(1)) + half;
  } else if constexpr (kTaps == 3) {
    return (tap(0) + tap(1)) + (tap(2) + half);
  } else if constexpr (kTaps == 4) {
    return ((tap(0) + tap(1)) + (tap(2) + tap(3))) + half;
  } else {
    V v = half;
    for (int k = 0; k < taps; ++k) v += tap(k);
    return v;
  }
}

GEODRIVE_FORCE_INLINE v4f Load4(const float* p) {
  v4f x;
  std::memcpy(&x, p, sizeof x);
  return x;
}

// Pixel i of an output row from its first source pixel `s` and weights `w`,
// as four lanes (RGB and the next pixel's R, ignored) so the taps are vector
// multiply-adds.
template <int kTaps>
GEODRIVE_FORCE_INLINE v4f HorizontalPixel(const float* s,
                                          const float* w,
                                          int taps) {
  return SumTaps<kTaps, v4f>([&](int k) { return w[k] * Load4(s + 3 * k); },
                             taps);
}

// Pixels i and i + 1 at once (first sources s0, s1; weights w0, w1): lanes
// 0-3 are pixel i's of HorizontalPixel, lanes 4-7 pixel i + 1's, with the
// same values (each lane runs the same operations).
template <int kTaps>
GEODRIVE_FORCE_INLINE v8f HorizontalPair(const float* s0,
                                         const float* s1,
                                         const float* w0,
                                         const float* w1,
                                         int taps) {
  return SumTaps<kTaps, v8f>(
      [&](int k) {
        const v8f x = __builtin_shufflevector(
            Load4(s0 + 3 * k), Load4(s1 + 3 * k), 0, 1, 2, 3, 4, 5, 6, 7);
        const v8f w = {w0[k], w0[k], w0[k], w0[k], w1[k], w1[k], w1[k], w1[k]};
        return w * x;
      },
      taps);
}

template <int kTaps>
GEODRIVE_FORCE_INLINE void HorizontalRows(const float* in,
                                          const AreaAxis& ax,
                                          float* out) {
  const int n = static_cast<int>(ax.first.size());
  const int taps = ax.taps;
  const float* w = ax.w.data();
  int i = 0;
  // Two pixels a step (half the instructions of one at a time in the AVX2
  // clone). Each store's lane 3 is overwritten by the next one.
  for (; i + 1 < n; i += 2, w += 2 * taps) {
    const v8f v = HorizontalPair<kTaps>(
        in + static_cast<size_t>(ax.first[i]) * 3,
        in + static_cast<size_t>(ax.first[i + 1]) * 3, w, w + taps, taps);
    const v4f lo = __builtin_shufflevector(v, v, 0, 1, 2, 3);
    const v4f hi = __builtin_shufflevector(v, v, 4, 5, 6, 7);
    std::memcpy(out + 3 * i, &lo, sizeof lo);
    std::memcpy(out + 3 * i + 3, &hi, sizeof hi);
  }
  for (; i < n; ++i, w += taps) {
    const v4f v = HorizontalPixel<kTaps>(
        in + static_cast<size_t>(ax.first[i]) * 3, w, taps);
    std::memcpy(out + 3 * i, &v, sizeof v);
  }
}

// One output row (3 floats a pixel, one float of padding after it) from the
// vertically resampled row `in` (the same layout).
GEODRIVE_AVX2_CLONES void HorizontalRgb(const float* in,
                                        const AreaAxis& ax,
                                        float* out) {
  switch (ax.taps) {
    case 2:
      return HorizontalRows<2>(in, ax, out);
    case 3:
      return HorizontalRows<3>(in, ax, out);
    case 4:
      return HorizontalRows<4>(in, ax, out);
    default:
      return HorizontalRows<0>(in, ax, out);
  }
}

// Truncates (the 0.5 is in) and saturates a row to 8 bits.
GEODRIVE_AVX2_CLONES void RowToBytes(const float* in, int n, uint8_t* out) {
  for (int i = 0; i < n; ++i)
    out[i] = static_cast<uint8_t>(std::min(in[i], 255.f));
}

}  // namespace

cv::Mat AreaResizeRgb(const cv::Mat& rgb,
                      double extent_width,
                      double extent_height,
                      const cv::Size& size) {
  GEODRIVE_CHECK_INPUT(rgb.type() == CV_8UC3,
                       "AreaResizeRgb: expected an RGB CV_8UC3 image, got "
                       "OpenCV type ",
                       rgb.type());
  GEODRIVE_CHECK_INPUT(
      size.width > 0 && size.height > 0 && extent_width >= size.width &&
          extent_height >= size.height && extent_width <= rgb.cols &&
          extent_height <= rgb.rows,
      "AreaResizeRgb: cannot resample ", extent_width, "x", extent_height,
      " pixels of a ", rgb.cols, "x", rgb.rows, " image onto ", size.width, "x",
      size.height, " (the extent must lie in the image and only shrink)");
  // The source columns and rows the extent touches (a partial last one
  // included).
  const int cols =
      std::min(rgb.cols, static_cast<int>(std::ceil(extent_width)));
  const int rows =
      std::min(rgb.rows, static_cast<int>(std::ceil(extent_height)));
  const AreaAxis ax = MakeAreaAxis(cols, size.width, extent_width / size.width);
  const AreaAxis ay =
      MakeAreaAxis(rows, size.height, extent_height / size.height);
  const int in_n = cols * 3, out_n = size.width * 3;
  std::vector<float> column(in_n + 1, 0.f), row(out_n + 1, 0.f);
  cv::Mat out(size, CV_8UC3);
  std::vector<const uint8_t*> rows_in(ay.taps);
  for (int y = 0; y < size.height; ++y) {
    // Vertical first (contiguous, vectorised), then horizontal.
    for (int k = 0; k < ay.taps; ++k)
      rows_in[k] = rgb.ptr<uint8_t>(ay.first[y] + k);
    VerticalRow(rows_in.data(), &ay.w[static_cast<size_t>(y) * ay.taps],
                ay.taps, in_n, column.data());
    HorizontalRgb(column.data(), ax, row.data());
    RowToBytes(row.data(), out_n, out.ptr<uint8_t>(y));
  }
  return out;
}

}  // namespace geodrive

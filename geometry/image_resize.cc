#include "geometry/image_resize.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <utility>
#include <vector>

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
// (GCC function multiversioning). No FMA and -ffp-contract=off (-std=c++17):
// every lane runs the same multiplies and adds in the same order in both
// clones, so the pixels do not depend on the CPU.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && \
    defined(__linux__)
#define GEODRIVE_ROW_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define GEODRIVE_ROW_CLONES
#endif
// Helpers are force-inlined into the clones (an `inline` one would be compiled
// once, for the baseline target).
#if defined(__GNUC__)
#define GEODRIVE_FORCE_INLINE inline __attribute__((always_inline))
#else
#define GEODRIVE_FORCE_INLINE inline
#endif

// out[i] = sum over k of w[k] * rows[k][i], i < n (rows with w[k] == 0
// skipped; w[0] always taken).
GEODRIVE_ROW_CLONES void VerticalRow(
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

// v4f: four floats (GCC/Clang vector extension).
typedef float v4f __attribute__((vector_size(16)));

// Pixel i of an output row: the taps' weighted sum, with 0.5 added for the
// rounding (the sums are >= 0), each pixel as four lanes (RGB and the next
// pixel's R, ignored) so the taps are vector multiply-adds. kTaps > 0 unrolls
// them as a pairwise sum (no chain of dependent adds); 0 runs `taps`.
template <int kTaps>
GEODRIVE_FORCE_INLINE v4f HorizontalPixel(const float* s,
                                          const float* w,
                                          int taps) {
  const auto tap = [&](int k) {
    v4f x;
    std::memcpy(&x, s + 3 * k, sizeof x);
    return w[k] * x;
  };
  const v4f half = {0.5f, 0.5f, 0.5f, 0.5f};
  if constexpr (kTaps == 2) {
    return (tap(0) + tap(1)) + half;
  } else if constexpr (kTaps == 3) {
    return (tap(0) + tap(1)) + (tap(2) + half);
  } else if constexpr (kTaps == 4) {
    return ((tap(0) + tap(1)) + (tap(2) + tap(3))) + half;
  } else {
    v4f v = half;
    for (int k = 0; k < taps; ++k) v += tap(k);
    return v;
  }
}

template <int kTaps>
GEODRIVE_FORCE_INLINE void HorizontalRows(const float* in,
                                          const AreaAxis& ax,
                                          float* out) {
  const int n = static_cast<int>(ax.first.size());
  const float* w = ax.w.data();
  for (int i = 0; i < n; ++i, w += ax.taps) {
    const v4f v = HorizontalPixel<kTaps>(
        in + static_cast<size_t>(ax.first[i]) * 3, w, ax.taps);
    std::memcpy(out + 3 * i, &v, sizeof v);  // lane 3 is overwritten next
  }
}

// One output row (3 floats a pixel, one float of padding after it) from the
// vertically resampled row `in` (the same layout).
GEODRIVE_ROW_CLONES void HorizontalRgb(const float* in,
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
GEODRIVE_ROW_CLONES void RowToBytes(const float* in, int n, uint8_t* out) {
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

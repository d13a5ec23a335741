#pragma once
// Area resampling of 8-bit RGB images: cv::INTER_AREA's weights, separable,
// in float, with an AVX2 clone picked at run time (same pixels on every CPU).
// OpenCV's INTER_AREA is fast only for integer factors; at the builder's
// non-integer ones (1600x900 -> 720x480, 720x480 -> 160x107 thumbnails) this
// is several times faster, and it accepts a fractional source extent (a
// scaled JPEG decode's partial last row), which cv::resize cannot.
#include <opencv2/core.hpp>

namespace geodrive {

// Area resampling (cv::INTER_AREA's weights) of the top-left extent_width x
// extent_height of `rgb` (CV_8UC3) onto `size`: output pixel (x, y) averages
// the source area [x * sx, (x + 1) * sx) x [y * sy, (y + 1) * sy) with sx =
// extent_width / size.width, sy = extent_height / size.height. The extent may
// end inside the last column or row (a scaled decode's partial pixel, which
// then counts with its fraction) and must lie within rgb and be at least
// `size` on both axes (InputError otherwise): it only shrinks. Separable, in
// float; equals cv::resize(INTER_AREA) within 1 level when the extent is rgb's
// size (the sums run in another order). Returns a new continuous image.
cv::Mat AreaResizeRgb(const cv::Mat& rgb,
                      double extent_width,
                      double extent_height,
                      const cv::Size& size);

}  // namespace geodrive

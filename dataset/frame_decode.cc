#include "dataset/frame_decode.h"

#include <algorithm>
#include <cstdint>
#include <opencv2/imgproc.hpp>

#include "geometry/util/status.h"

namespace geodrive {
namespace {

// side * scale >= target, exactly (integers).
bool Covers(int side, const JpegScale& scale, int target) {
  return int64_t{side} * scale.num >= int64_t{target} * scale.denom;
}
bool Whole(int side, const JpegScale& scale) {
  return int64_t{side} * scale.num % scale.denom == 0;
}

JpegScale ChooseScale(int width,
                      int height,
                      const ImageResizeSpec& spec,
                      const FrameDecodeOptions& options,
                      bool whole_sizes_only) {
  if (options.mode == FrameDecodeMode::kFull) return {1, 1};
  for (const JpegScale& s : JpegDecodeScales(width, height)) {  // smallest 1st
    if (!options.all_jpeg_scales && s.num != 1) continue;  // SIMD IDCTs only
    if (!Covers(width, s, spec.resized_width) ||
        !Covers(height, s, spec.resized_height))
      continue;
    if (whole_sizes_only && !(Whole(width, s) && Whole(height, s))) continue;
    return s;
  }
  return {1, 1};
}

// Resizes and crops a frame decoded at `scale` from a `width` x `height`
// source: AreaResizeRgb of the decode's exact extent (side * scale,
// unrounded) onto the resized size, so output pixel i averages source pixels
// [i * S / R, (i + 1) * S / R) as the full decode + INTER_AREA does.
cv::Mat ResizeScaledFrame(const cv::Mat& decoded,
                          int width,
                          int height,
                          const JpegScale& scale,
                          const ImageResizeSpec& spec) {
  const double extent_w = static_cast<double>(width) * scale.num / scale.denom;
  const double extent_h = static_cast<double>(height) * scale.num / scale.denom;
  const cv::Size resized(spec.resized_width, spec.resized_height);
  cv::Mat out;
  if (decoded.size() == resized && extent_w == resized.width &&
      extent_h == resized.height) {
    out = decoded;  // already the resized size: no resampling
  } else {
    out = AreaResizeRgb(decoded, extent_w, extent_h, resized);
  }
  const cv::Rect crop(spec.crop_left, spec.crop_top, spec.width, spec.height);
  if (crop == cv::Rect(0, 0, out.cols, out.rows) && out.data != decoded.data)
    return out;  // already a fresh, continuous image: no copy
  return out(crop).clone();
}

}  // namespace

JpegScale FrameDecodeScale(int width,
                           int height,
                           const ImageResizeSpec& spec,
                           const FrameDecodeOptions& options) {
  return ChooseScale(width, height, spec, options, /*whole_sizes_only=*/false);
}

cv::Mat FullFrameToOutput(const cv::Mat& rgb, const ImageResizeSpec& spec) {
  if (rgb.cols < spec.resized_width || rgb.rows < spec.resized_height)
    return ResizeFrameToOutput(rgb, spec);  // grows on an axis: kFull's rule
  return ResizeScaledFrame(rgb, rgb.cols, rgb.rows, JpegScale{1, 1}, spec);
}

cv::Mat ResizeFrameToOutput(const cv::Mat& rgb, const ImageResizeSpec& spec) {
  const cv::Size size(spec.resized_width, spec.resized_height);
  cv::Mat resized;
  if (rgb.size() == size) {
    resized = rgb;
  } else {
    // The builder's rule since its first version (INTER_AREA whenever the
    // width shrinks, even if the height grows): kept so that kFull gives the
    // same pixels as before.
    const bool shrink = spec.resized_width < rgb.cols;
    cv::resize(rgb, resized, size, 0, 0,
               shrink ? cv::INTER_AREA : cv::INTER_LINEAR);
  }
  const cv::Rect crop(spec.crop_left, spec.crop_top, spec.width, spec.height);
  if (crop == cv::Rect(0, 0, resized.cols, resized.rows) &&
      resized.data != rgb.data) {
    return resized;  // already a fresh, continuous image: no copy
  }
  return resized(crop).clone();
}

cv::Mat ReadFrameAtOutputSize(const std::string& path,
                              int width,
                              int height,
                              const ImageResizeSpec& spec,
                              const FrameDecodeOptions& options) {
  const auto check_size = [&](const cv::Size& size) {
    GEODRIVE_CHECK_INPUT(size == cv::Size(width, height), path, ": image is ",
                         size.width, "x", size.height, " but the dataset says ",
                         width, "x", height);
  };
  if (options.mode == FrameDecodeMode::kFull) {
    const cv::Mat rgb = ReadImageRgb(path);
    check_size(rgb.size());
    return ResizeFrameToOutput(rgb, spec);
  }
  // The header alone gives the full size (a scaled decode cannot tell 1599
  // from 1600 columns) and the EXIF orientation. The file is read once for
  // both.
  const ImageFile file = ReadImageFile(path);
  const ImageHeader header = ReadImageHeader(file);
  check_size(header.size);
  const JpegScale scale =
      header.jpeg ? ChooseScale(width, height, spec, options,
                                /*whole_sizes_only=*/header.orientation != 1)
                  : JpegScale{1, 1};
  if (scale.num == scale.denom) {
    const cv::Mat rgb = DecodeImageRgb(file);
    check_size(rgb.size());
    return FullFrameToOutput(rgb, spec);
  }
  return ResizeScaledFrame(DecodeImageRgb(file, scale), width, height, scale,
                           spec);
}

}  // namespace geodrive

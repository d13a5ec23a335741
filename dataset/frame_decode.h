#pragma once
// Clip frames at the pair's output size (the ground truth of build-dataset).
//
// A 1600x900 nuScenes JPEG brought to 720x480 costs a decode and a resize.
// libjpeg-turbo can run the inverse DCT at M/8 scale (ReadImageRgbScaled,
// geometry/image_io.h), and kDctScaled decodes at the smallest allowed scale
// (below) whose unrounded size still covers the resized size on both axes, so
// the resize after it only shrinks. It resizes the scaled decode's exact
// extent: pixel j of a decode at M/8 covers source pixels
// [j * 8 / M, (j + 1) * 8 / M), so 900 rows at 5/8 are 562.5 decoded rows (563
// come out, the last one half past the edge), and AreaResizeRgb maps 562.5
// rows, not 563, onto 480. Output pixel i then averages the same source area
// as the full decode + INTER_AREA resize does (source pixels
// [i * S / R, (i + 1) * S / R)): pixel centres map exactly as before and the
// intrinsics of the output (ApplyResizeSpec) are unchanged
// (FrameDecode.DctScaledKeepsTheOutputIntrinsics).
//
// Which scales pay depends on libjpeg-turbo (2.1 measured): 1/8 (DC only),
// 1/4 and 1/2 have SIMD inverse DCTs and decode faster than 1/1 (whose 8x8
// IDCT is AVX2), but
// 3/8, 5/8, 3/4 and 7/8 run libjpeg's C IDCTs: 3/8 decodes slower than 1/2,
// and 5/8, 3/4 and 7/8 slower than a full-size decode (1.2-1.3x, 1.5x, 2.1x
// its CPU time on a 1600x900 frame), and the reduced IDCT loses more detail
// than the resize does (1600x900 -> 720x480 at 5/8: 39.8 dB worst against the
// full path on the synthetic demo frames). So by default kDctScaled chooses
// among 1/8, 1/4, 1/2 and 1/1, and 1600x900 -> 720x480 is a full decode, then
// AreaResizeRgb, which is ~5x faster than OpenCV's INTER_AREA at these
// non-integer factors and equals it within 1 level (75 dB). Figures:
// docs/PERFORMANCE.md ("Dataset builder"), bench/bench_builder.cc,
// tests/dataset/frame_decode_test.cc.

#include <opencv2/core.hpp>
#include <string>

#include "geometry/camera.h"
#include "geometry/image_io.h"
#include "geometry/image_resize.h"  // AreaResizeRgb

namespace geodrive {

// How a frame is brought to the output size.
enum class FrameDecodeMode {
  // Full-size decode, then ResizeFrameToOutput (cv::resize): the reference
  // path for the tests and the benchmark.
  kFull,
  // Decode a JPEG at FrameDecodeScale (the smallest allowed DCT scale whose
  // unrounded size covers the resized size on both axes), AreaResizeRgb of
  // the decode's exact extent, crop. When the source is smaller than the
  // resized size on an axis (the scale is then 1/1) the resize is
  // ResizeFrameToOutput, as in kFull. PNGs are decoded at full size.
  kDctScaled,
};

struct FrameDecodeOptions {
  // Which path; kDctScaled unless a caller needs kFull's pixels.
  FrameDecodeMode mode = FrameDecodeMode::kDctScaled;
  // The DCT scales kDctScaled chooses from. false: 1/8, 1/4, 1/2 and 1/1, the
  // ones with SIMD inverse DCTs in libjpeg-turbo (the fastest and closest to
  // the full path wherever measured). true: every scale JpegDecodeScales
  // lists (M/8, M = 1..8), for the comparison in bench/bench_builder.cc.
  bool all_jpeg_scales = false;
};

// The JPEG scale kDctScaled decodes a `width` x `height` JPEG at when it is
// resized to `spec`: the smallest allowed scale s (FrameDecodeOptions::
// all_jpeg_scales) with width * s >= spec.resized_width and height * s >=
// spec.resized_height, unrounded, so the resize only shrinks; 1/1 if none is
// smaller, and for kFull. 1600x900 -> 720x480: 1/1 (5/8 with all scales);
// -> 512x288: 1/2; -> 400x225: 1/4; -> 200x112: 1/8. For a JPEG with an EXIF
// orientation other than 1, whose rotation could put a scaled decode's partial
// last row or column first, ReadFrameAtOutputSize takes the smallest such
// scale whose scaled size is whole on both axes instead.
JpegScale FrameDecodeScale(int width,
                           int height,
                           const ImageResizeSpec& spec,
                           const FrameDecodeOptions& options = {});

// Reads the image at `path`, checks that it is `width` x `height` (the
// dataset's camera; InputError naming the file otherwise), and returns it
// resized and cropped as `spec` says (RGB CV_8UC3, spec.width x
// spec.height), through the path options.mode says.
cv::Mat ReadFrameAtOutputSize(const std::string& path,
                              int width,
                              int height,
                              const ImageResizeSpec& spec,
                              const FrameDecodeOptions& options = {});

// kDctScaled's resize and crop of a frame already decoded at full size (`rgb`
// as ReadImageRgb returns it): AreaResizeRgb where the frame covers the
// resized size, ResizeFrameToOutput where it is smaller on an axis. When
// FrameDecodeScale is 1/1 for the frame, these are ReadFrameAtOutputSize's
// pixels without a second decode (the builder's LiDAR sources decode the full
// frames anyway).
cv::Mat FullFrameToOutput(const cv::Mat& rgb, const ImageResizeSpec& spec);

// Resizes and crops a full-size decoded frame (any size) as `spec` says:
// cv::resize, INTER_AREA when the width shrinks, INTER_LINEAR otherwise (the
// kFull path). Returns a new image.
cv::Mat ResizeFrameToOutput(const cv::Mat& rgb, const ImageResizeSpec& spec);

}  // namespace geodrive

#pragma once
// Clip frames at the pair's output size (the ground truth of build-dataset).
//
// A 1600x900 nuScenes JPEG brought to 720x480 does not need its full-size
// pixels: libjpeg-turbo can run the inverse DCT at 1/2, 1/4 or 1/8 scale
// (ReadImageRgbScaled, geometry/image_io.h), which skips most of the IDCT,
// colour-conversion and upsampling work and leaves a much smaller resize. The
// reduced decode keeps the pixel grid of the full one (output pixel j covers
// source pixels d*j .. d*j + d - 1), so the resize and crop map pixel centres
// exactly as before and the intrinsics of the output (ApplyResizeSpec) are
// unchanged. Measured against the full decode + INTER_AREA resize in
// docs/PERFORMANCE.md ("Dataset builder") and
// tests/dataset/frame_decode_test.cc.

#include <opencv2/core.hpp>
#include <string>

#include "geometry/camera.h"

namespace geodrive {

// How a frame is brought to the output size.
enum class FrameDecodeMode {
  // Full-size decode, then ResizeFrameToOutput: the builder's path before
  // issue 23 (same pixels), kept as the reference for the tests and the
  // benchmark.
  kFull,
  // Decode at the smallest DCT scale (1/8, 1/4, 1/2, 1) whose size is at
  // least the resized size divided by FrameDecodeOptions::max_upsample, then
  // resize and crop.
  kDctScaled,
};

struct FrameDecodeOptions {
  // Which path; kDctScaled unless a caller needs the old pixels.
  FrameDecodeMode mode = FrameDecodeMode::kDctScaled;
  // How much smaller (per side) than the resized frame a reduced decode may
  // be; the resize then upsamples that side by at most this factor. 1.125
  // admits 1600x900 -> 800x450 for 720x480 (height x 1.067). Against the full
  // decode + resize: 41.2 dB PSNR worst, 43.8 dB mean on the 41 real
  // scene-0916 CAM_FRONT frames; 35.6 dB worst, 38.0 dB mean on the synthetic
  // demo frames, whose procedural edges carry detail a 450-row decode cannot
  // (docs/PERFORMANCE.md). 1.0 never upsamples (1600x900 -> 720x480 is then
  // a full decode, the previous pixels).
  double max_upsample = 1.125;
};

// The DCT scale denominator (1, 2, 4 or 8) kDctScaled uses for a
// `width` x `height` source resized to `spec` (1 for kFull).
int FrameDecodeDenominator(int width,
                           int height,
                           const ImageResizeSpec& spec,
                           const FrameDecodeOptions& options = {});

// Reads the image at `path`, checks that it is `width` x `height` (the
// dataset's camera; InputError naming the file otherwise), and returns it
// resized and cropped as `spec` says (RGB CV_8UC3, spec.width x
// spec.height). PNGs are decoded at full size.
cv::Mat ReadFrameAtOutputSize(const std::string& path,
                              int width,
                              int height,
                              const ImageResizeSpec& spec,
                              const FrameDecodeOptions& options = {});

// Resizes and crops a decoded frame (any size) as `spec` says: INTER_AREA when
// the width shrinks, INTER_LINEAR otherwise (the builder's rule before issue
// 23, unchanged). Returns a new image.
cv::Mat ResizeFrameToOutput(const cv::Mat& rgb, const ImageResizeSpec& spec);

}  // namespace geodrive

#pragma once
// The pair folder's PNGs (first_frame.png, preview.png) written for speed
// (internal to geodrive_dataset). geometry/image_io.h's WriteImageRgb uses
// zlib level 3 with libspng's adaptive filter choice (all five filters tried
// on every row): 38-39 ms CPU per 720x480 frame on a 2-vCPU development
// machine, a third of the builder's encode stage. Level 1 with the Paeth
// filter and zlib's run-length strategy takes 14-15 ms for files within a few
// per cent of the size (first_frame.png 366 vs 371 KB, preview.png 441 vs
// 412 KB on the demo set). Lossless: the pixels read back are the same; the
// bytes are deterministic for a given zlib.

#include <opencv2/core.hpp>
#include <string>

namespace geodrive {
namespace internal {

// What a PNG holds, which picks its row filter.
enum class PngContent {
  // A photograph (first_frame.png, a contact sheet): the Paeth filter.
  kPhoto,
  // A point render, mostly black (a condition frame, a drawn mask): no
  // filter. Filtered rows of isolated points deflate worse: on 1024x576
  // renders, 4-9 ms and 42-498 KB unfiltered against 10-20 ms and
  // 50-556 KB with Paeth.
  kRender,
};

// Writes an RGB CV_8UC3 image as an 8-bit truecolour PNG (a CV_8UC1 image
// as 8-bit gray), atomically (WriteFileAtomic). Throws InputError naming
// `path` on failure.
void WritePairPng(const std::string& path,
                  const cv::Mat& rgb,
                  PngContent content = PngContent::kPhoto);
// Writes a mask (CV_8UC1, nonzero = set) as a 1-bit gray PNG, atomically:
// an eighth of the bytes to deflate. Readers expand 1-bit gray to 0/255
// (libpng and OpenCV with expand, PIL's convert("L"), libspng's G8).
void WriteMaskPng(const std::string& path, const cv::Mat& mask);
// The bytes WriteMaskPng writes; `path` names the file in errors.
std::string EncodeMaskPng(const std::string& path, const cv::Mat& mask);

}  // namespace internal
}  // namespace geodrive

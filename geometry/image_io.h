#pragma once
// Images through OpenCV (PNG, JPEG). Errors name the file: missing, not an
// image, truncated (a JPEG without its end-of-image marker or a PNG without
// IEND is refused, although libjpeg would decode it with a grey bottom). Writes
// are atomic (temporary file + rename).

#include <opencv2/core.hpp>
#include <string>

namespace geodrive {

// Reads an 8-bit image as RGB (3 channels, CV_8UC3) -- note: RGB, not OpenCV's
// BGR.
cv::Mat ReadImageRgb(const std::string& path);
// Reads a single-channel 8-bit image (e.g. a mask) as CV_8UC1.
cv::Mat ReadImageGray(const std::string& path);
// Reads an image unchanged (any depth/channels), BGR order as OpenCV stores it.
cv::Mat ReadImageUnchanged(const std::string& path);
// Writes an RGB CV_8UC3 (or CV_8UC1) image; the format follows the extension.
// PNG writes are deterministic (fixed compression level).
void WriteImageRgb(const std::string& path, const cv::Mat& rgb);

// Size of the image ReadImageRgb would return, without decoding the pixels when
// possible (PNG, and JPEG without EXIF; a JPEG with EXIF is decoded so that its
// orientation is applied).
cv::Size ReadImageSize(const std::string& path);

}  // namespace geodrive

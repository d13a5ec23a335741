#pragma once
// Images through OpenCV (PNG, JPEG). Errors name the file.

#include <opencv2/core.hpp>
#include <string>

namespace geodrive {

// Reads an 8-bit image as RGB (3 channels, CV_8UC3) -- note: RGB, not OpenCV's BGR.
cv::Mat ReadImageRgb(const std::string& path);
// Reads a single-channel 8-bit image (e.g. a mask) as CV_8UC1.
cv::Mat ReadImageGray(const std::string& path);
// Reads an image unchanged (any depth/channels), BGR order as OpenCV stores it.
cv::Mat ReadImageUnchanged(const std::string& path);
// Writes an RGB CV_8UC3 (or CV_8UC1) image; the format follows the extension. PNG writes are
// deterministic (fixed compression level).
void WriteImageRgb(const std::string& path, const cv::Mat& rgb);

// Size without decoding the pixels when possible.
cv::Size ReadImageSize(const std::string& path);

}  // namespace geodrive

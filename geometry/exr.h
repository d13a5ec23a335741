#pragma once
// OpenEXR images through the OpenEXR library (Debian libopenexr-dev): the
// depth and point maps of MoGe / MoGe-2 (`infer.py --maps`: depth.exr,
// points.exr) and any float map a user has. Half and float channels are read
// as float32. Errors name the file and the channel.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace geodrive {

// The channel names of an EXR file, in the file's (alphabetical) order.
std::vector<std::string> ExrChannels(const std::string& path);

// Reads the named channels into one CV_32FC(n) image, channel k of the result
// = channels[k] of the file. Throws InputError when the file is not an EXR,
// a channel is missing, or the data window exceeds 16384 pixels a side.
cv::Mat ReadExr(const std::string& path,
                const std::vector<std::string>& channels);

// Writes a CV_32FC(n) image as float channels named `channels` (n names),
// zip-compressed. Throws InputError naming `path` on failure.
void WriteExr(const std::string& path,
              const cv::Mat& image,
              const std::vector<std::string>& channels);

}  // namespace geodrive

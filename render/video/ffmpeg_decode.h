#pragma once
// Video files decoded through FFmpeg's libavformat, libavcodec and libswscale
// directly (render/video/video_io.h's ReadVideoFrames uses it).
//
// Why not cv::VideoCapture: OpenCV's videoio links ~245 shared libraries
// (GDAL among them) and costs every process that links it 160-210 ms of
// start-up (issue 23), for a few dozen lines of FFmpeg calls we already link
// for the H.264 writer. The pixels are those cv::VideoCapture(CAP_FFMPEG)
// returns for the same file (same FFmpeg, same conversion: swscale at the
// coded size, SWS_BICUBIC, the default BT.601 coefficients, into a 32-byte
// aligned BGR buffer, then BGR -> RGB; the display-matrix rotation applied as
// OpenCV's CAP_PROP_ORIENTATION_AUTO does), checked frame by frame against
// cv2 in tests/render/video_reader_test.cc.
//
// Stricter than OpenCV: the container must be MP4/MOV, AVI or Matroska/WebM
// (probed, whatever the extension), the frame size is checked against
// VideoReadLimits on the header before anything is decoded, a decoder error
// (corrupt data, missing references) is an error rather than a skipped frame,
// and a file cut short of its own index is "truncated". Decoding is
// single-threaded, so the frames do not depend on the machine's core count.

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace geodrive {

// The largest video ReadVideoFrames accepts. Frame sides and pixels as for
// images (ImageReadLimits); all decoded frames together (RGB, 3 bytes a pixel)
// at most kMaxDecodedBytes, checked against the header's frame count before
// decoding and again while decoding.
struct VideoReadLimits {
  static constexpr int kMaxSide = 16384;
  static constexpr int64_t kMaxPixels = int64_t{1} << 28;
  static constexpr int64_t kMaxDecodedBytes = int64_t{16} << 30;  // 16 GiB
};

// Every frame of the video file `path`, RGB CV_8UC3, in presentation order.
// Throws InputError naming the file: not a readable container, no video
// stream, no decoder, over the limits, corrupt or truncated data, frames that
// change size, no frame at all.
std::vector<cv::Mat> DecodeVideoFileRgb(const std::string& path);

}  // namespace geodrive

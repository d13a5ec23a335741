#pragma once
// Video files decoded through FFmpeg's libavformat, libavcodec and libswscale
// directly (render/video/video_io.h's ReadVideoFrames uses it).
//
// Why not cv::VideoCapture: OpenCV's videoio links ~245 shared libraries
// (GDAL among them) and costs every process that links it 160-210 ms of
// start-up, for a few dozen lines of FFmpeg calls we already link
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
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "geometry/util/size_limits.h"

namespace geodrive {

// The largest video ReadVideoFrames accepts. Frame sides and pixels as for
// images (ImageReadLimits); all decoded frames together (RGB, 3 bytes a pixel,
// plus SizeLimits::kFrameOverheadBytes a frame) at most kMaxDecodedBytes and
// at most SizeLimits::kMaxVideoFrames frames, checked against the header's
// frame count before decoding and again while decoding
// (geometry/util/size_limits.h).
struct VideoReadLimits {
  static constexpr int kMaxSide = static_cast<int>(SizeLimits::kMaxImageSide);
  static constexpr int64_t kMaxPixels = SizeLimits::kMaxImagePixels;
  static constexpr int64_t kMaxDecodedBytes = SizeLimits::kMaxVideoDecodeBytes;
  static constexpr int64_t kMaxFrames = SizeLimits::kMaxVideoFrames;
};

// A video file decoded one frame at a time (memory: one frame and the
// decoder's own buffers, whatever the length). The constructor opens the
// container and the decoder and checks the declared frame size; Next()
// throws InputError naming the file as DecodeVideoFileRgb does. With `whole`
// (the caller keeps every frame) the declared frame count is checked against
// the limits before the container's streams are probed.
class VideoFileReader {
 public:
  explicit VideoFileReader(const std::string& path, bool whole = false);
  ~VideoFileReader();
  VideoFileReader(const VideoFileReader&) = delete;
  VideoFileReader& operator=(const VideoFileReader&) = delete;

  // The next frame, RGB CV_8UC3, in presentation order; false after the last
  // (a video without any frame is an error).
  bool Next(cv::Mat* rgb);
  // The frame size the header declares (after the display rotation) and the
  // frame count it declares (0 when the container does not say).
  int width() const;
  int height() const;
  int64_t declared_frames() const;
  int64_t frames_read() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Bytes one decoded RGB frame of `width` x `height` holds in memory.
int64_t VideoFrameBytes(int64_t width, int64_t height);
// Throws InputError naming `path` when `frames` frames of `width` x `height`
// are over SizeLimits::kMaxVideoFrames or kMaxVideoDecodeBytes.
void CheckVideoFramesFit(const std::string& path,
                         int64_t frames,
                         int64_t width,
                         int64_t height);

// Every frame of the video file `path`, RGB CV_8UC3, in presentation order.
// Throws InputError naming the file: not a readable container, no video
// stream, no decoder, over the limits, corrupt or truncated data, frames that
// change size, no frame at all.
std::vector<cv::Mat> DecodeVideoFileRgb(const std::string& path);

}  // namespace geodrive

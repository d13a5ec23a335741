#pragma once
// Video files in any codec FFmpeg's libavcodec has an encoder for, named by a
// FourCC ("mp4v", "MJPG", ...), in the container the file extension names,
// written through libavformat/libavcodec/libswscale directly. The H.264 path
// (render/video/h264.h) stays the default; this writer is the fallback and
// WriteVideoFrames' .mp4 ('mp4v') and .avi ('MJPG').
//
// Why not cv::VideoWriter: OpenCV's videoio links ~245 shared libraries and
// costs every process 160-210 ms of start-up. The FourCC is looked
// up in the container's codec tags as OpenCV does, but the settings are ours:
// a fixed quantiser (q = 2, near the best an MPEG-4 or MJPEG encoder gives)
// instead of OpenCV's 1 bit per pixel, one thread, bit-exact flags on codec,
// conversion and muxer (the same frames give the same bytes), RGB converted
// by swscale (bicubic, accurate rounding) to the encoder's 4:2:0 format, odd
// sizes padded by one black row/column (OpenCV cropped them). The file is
// written to a temporary name and renamed when complete.

#include <memory>
#include <opencv2/core.hpp>
#include <string>

namespace geodrive {

class FfmpegVideoWriter {
 public:
  // Opens `path` for `width` x `height` RGB frames at `fps` with the encoder
  // that `fourcc` (4 characters) names in the container of `path`'s
  // extension. Throws InputError naming the file when there is none or the
  // file cannot be opened.
  FfmpegVideoWriter(const std::string& path,
                    int width,
                    int height,
                    const std::string& fourcc,
                    double fps);
  // Destroyed without Finish() (an exception), it removes the temporary file.
  ~FfmpegVideoWriter();
  FfmpegVideoWriter(const FfmpegVideoWriter&) = delete;
  FfmpegVideoWriter& operator=(const FfmpegVideoWriter&) = delete;

  // Encodes one RGB CV_8UC3 frame of the constructor's size.
  void Write(const cv::Mat& frame_rgb);
  // Flushes the encoder, writes the trailer and commits the file.
  void Finish();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace geodrive

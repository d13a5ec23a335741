#pragma once
// Deterministic H.264 MP4 writing through libavcodec/libavformat (FFmpeg)
// directly.
//
// OpenCV's VideoWriter gives no control over encoder threads or container
// metadata, so the same frames produce different bytes from run to run (x264
// frame threads, the mp4 creation time). This writer encodes with libx264
// (preset `veryfast` unless set, one thread, no threaded lookahead, fixed GOP,
// CRF), sets the `bitexact` flags on codec and muxer (no encoder version
// string, zero timestamps in the header), disables macroblock-tree rate control
// (its floating-point lookahead was measured to change output bytes from run to
// run inside a multi-threaded process), converts RGB to yuv420p with OpenCV
// (BT.601 limited range), and writes yuv420p. The same frames and options give
// byte-identical files.

#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace geodrive {

struct H264Options {
  double fps = 10.0;
  int crf = 18;  // constant rate factor (0 = lossless, 18 ~ visually lossless)
  std::string preset = "veryfast";  // x264 preset
  int gop = 25;                     // keyframe interval (frames)
  void Check() const;
};

// Writes RGB CV_8UC3 frames (all the same size) as an H.264 MP4. Odd sizes are
// padded by one black row/column (yuv420p needs even sizes). Throws InputError
// naming the file on failure; the file is written to a temporary name and
// renamed when complete.
void WriteH264Mp4(const std::string& path,
                  const std::vector<cv::Mat>& frames_rgb,
                  const H264Options& options = {});

// The same writer, one frame at a time, so that a long clip never has to be
// held in memory: the constructor opens the encoder and a temporary file,
// Write() encodes one frame, Finish() flushes and renames the file into
// place. Destroyed without Finish() (an exception), it removes the temporary
// file. The bytes equal WriteH264Mp4's for the same frames.
class H264Mp4Writer {
 public:
  // `width` x `height` is the frame size (odd sizes are padded as above).
  H264Mp4Writer(const std::string& path,
                int width,
                int height,
                const H264Options& options = {});
  ~H264Mp4Writer();
  H264Mp4Writer(const H264Mp4Writer&) = delete;
  H264Mp4Writer& operator=(const H264Mp4Writer&) = delete;

  // Encodes one RGB CV_8UC3 frame of the constructor's size.
  void Write(const cv::Mat& frame_rgb);
  // Flushes the encoder, writes the trailer and commits the file.
  void Finish();
  int frames_written() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// True when this FFmpeg build has an H.264 encoder (libx264).
bool HasH264Encoder();

}  // namespace geodrive

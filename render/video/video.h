#pragma once
// Video and image outputs for rendered conditioning clips.

#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace geodrive {

struct VideoWriteOptions {
  double fps = 10;
  // FourCC tried first; "avc1" = H.264 through the deterministic libx264
  // writer (h264.h), any other through FFmpeg's encoder for that FourCC in the
  // container of the extension (ffmpeg_encode.h). If it cannot be opened,
  // `fallback_fourcc` is used (with a warning on stderr).
  std::string fourcc = "avc1";
  std::string fallback_fourcc = "mp4v";
  void Check() const;
};

struct VideoWriteResult {
  std::string fourcc;  // the codec actually used
  bool fell_back = false;
  int frames = 0;
  int width = 0, height = 0;  // written size (odd sizes are padded by one black
                              // pixel for H.264)
};

// Writes RGB CV_8UC3 frames (all the same size) as an MP4. Throws InputError if
// no codec can be opened, the frames are empty or of different sizes.
VideoWriteResult WriteVideo(const std::string& path,
                            const std::vector<cv::Mat>& frames_rgb,
                            const VideoWriteOptions& options = {});

// WriteVideo one frame at a time (the H.264 path through H264Mp4Writer, the
// others through FfmpegVideoWriter): a long clip is never held whole.
// Destroyed before Close() (an exception), it leaves no partial H.264 file.
class VideoStreamWriter {
 public:
  // Opens `path` for frames of `width` x `height`; throws InputError naming
  // the file when no codec can be opened.
  VideoStreamWriter(const std::string& path,
                    int width,
                    int height,
                    const VideoWriteOptions& options = {});
  ~VideoStreamWriter();
  VideoStreamWriter(const VideoStreamWriter&) = delete;
  VideoStreamWriter& operator=(const VideoStreamWriter&) = delete;
  // Appends one RGB CV_8UC3 frame of the opened size.
  void Write(const cv::Mat& frame_rgb);
  // Finishes the file; returns what was written.
  VideoWriteResult Close();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Lossless PNG sequence `<dir>/<prefix>NNNN.png` (4-digit, from 0), written by
// WriteImageRgb (libspng, zlib level 3, atomic). Returns the paths.
// The files are numbered from `first_index` (streaming writers call it once
// per chunk of frames).
std::vector<std::string> WritePngSequence(
    const std::string& dir,
    const std::string& prefix,
    const std::vector<cv::Mat>& frames_rgb,
    int first_index = 0);

struct ContactSheetOptions {
  int columns = 5;        // frames per row
  int thumb_width = 240;  // each frame is resized to this width (aspect kept)
  int gap = 4;            // pixels between thumbnails (black)
  void Check() const;
};
// A grid of frames (row-major). If `ground_truth` is non-empty (same count as
// `frames`), every row of renders is preceded by the row of ground-truth frames
// for the same indices.
cv::Mat MakeContactSheet(const std::vector<cv::Mat>& frames_rgb,
                         const std::vector<cv::Mat>& ground_truth_rgb = {},
                         const ContactSheetOptions& options = {});

// The thumbnail MakeContactSheet draws for `frame_rgb` (INTER_AREA weights to
// thumb_width, aspect kept). A sheet made of these thumbnails equals the
// sheet made of the frames, so a streaming caller keeps only thumbnails.
cv::Mat ContactSheetThumbnail(const cv::Mat& frame_rgb,
                              const ContactSheetOptions& options = {});

// Bilinear resize with align_corners=False semantics (PyTorch's F.interpolate,
// OpenCV INTER_LINEAR).
cv::Mat ResizeBilinear(const cv::Mat& image, int width, int height);

}  // namespace geodrive

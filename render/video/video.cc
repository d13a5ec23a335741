#include "render/video/video.h"

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "geometry/util/status.h"
#include "render/video/h264.h"

namespace geodrive {
namespace {

void CheckFrames(const std::string& what, const std::vector<cv::Mat>& frames) {
  GEODRIVE_CHECK_INPUT(!frames.empty(), what, ": no frames");
  for (size_t i = 0; i < frames.size(); ++i) {
    GEODRIVE_CHECK_INPUT(frames[i].type() == CV_8UC3 && !frames[i].empty(),
                         what, ": frame ", i,
                         " is not a non-empty RGB CV_8UC3 image");
    GEODRIVE_CHECK_INPUT(frames[i].size() == frames[0].size(), what, ": frame ",
                         i, " is ", frames[i].cols, "x", frames[i].rows,
                         ", frame 0 is ", frames[0].cols, "x", frames[0].rows);
  }
}

int FourCC(const std::string& code) {
  GEODRIVE_CHECK_INPUT(code.size() == 4, "video: fourcc '", code,
                       "' must have 4 characters");
  return cv::VideoWriter::fourcc(code[0], code[1], code[2], code[3]);
}

}  // namespace

void VideoWriteOptions::Check() const {
  GEODRIVE_CHECK_INPUT(fps > 0 && fps <= 1000, "video: fps ", fps,
                       " must be in (0, 1000]");
  FourCC(fourcc);
  if (!fallback_fourcc.empty()) FourCC(fallback_fourcc);
}

VideoWriteResult WriteVideo(const std::string& path,
                            const std::vector<cv::Mat>& frames_rgb,
                            const VideoWriteOptions& options) {
  options.Check();
  CheckFrames(path, frames_rgb);
  VideoWriteResult result;
  // H.264 (yuv420p) needs even sizes: pad with black.
  result.width = frames_rgb[0].cols + (frames_rgb[0].cols % 2);
  result.height = frames_rgb[0].rows + (frames_rgb[0].rows % 2);
  const cv::Size size(result.width, result.height);
  if (options.fourcc == "avc1" && HasH264Encoder()) {
    // Deterministic libx264 path (byte-identical files for identical frames).
    H264Options h264;
    h264.fps = options.fps;
    WriteH264Mp4(path, frames_rgb, h264);
    result.fourcc = "avc1";
    result.frames = static_cast<int>(frames_rgb.size());
    return result;
  }
  cv::VideoWriter writer;
  result.fourcc = options.fourcc;
  if (!writer.open(path, cv::CAP_FFMPEG, FourCC(options.fourcc), options.fps,
                   size, true)) {
    GEODRIVE_CHECK_INPUT(!options.fallback_fourcc.empty(), path,
                         ": cannot open a video writer with fourcc ",
                         options.fourcc);
    std::cerr << "warning: " << path << ": fourcc " << options.fourcc
              << " is not available through OpenCV's FFmpeg backend; using "
              << options.fallback_fourcc << "\n";
    result.fourcc = options.fallback_fourcc;
    result.fell_back = true;
    GEODRIVE_CHECK_INPUT(
        writer.open(path, cv::CAP_FFMPEG, FourCC(options.fallback_fourcc),
                    options.fps, size, true),
        path, ": cannot open a video writer (tried ", options.fourcc, " and ",
        options.fallback_fourcc, ")");
  }
  cv::Mat bgr;
  for (const cv::Mat& rgb : frames_rgb) {
    cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
    if (bgr.size() != size) {
      cv::copyMakeBorder(bgr, bgr, 0, size.height - bgr.rows, 0,
                         size.width - bgr.cols, cv::BORDER_CONSTANT,
                         cv::Scalar(0, 0, 0));
    }
    writer.write(bgr);
    ++result.frames;
  }
  writer.release();
  GEODRIVE_CHECK_INPUT(
      std::filesystem::exists(path) && std::filesystem::file_size(path) > 0,
      path, ": the video writer produced no file");
  return result;
}

std::vector<std::string> WritePngSequence(
    const std::string& dir,
    const std::string& prefix,
    const std::vector<cv::Mat>& frames_rgb) {
  CheckFrames(dir, frames_rgb);
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  GEODRIVE_CHECK_INPUT(!ec, dir, ": cannot create directory (", ec.message(),
                       ")");
  std::vector<std::string> paths;
  cv::Mat bgr;
  const std::vector<int> params = {cv::IMWRITE_PNG_COMPRESSION, 3};
  for (size_t i = 0; i < frames_rgb.size(); ++i) {
    char name[64];
    std::snprintf(name, sizeof(name), "%04zu.png", i);
    const std::string path =
        (std::filesystem::path(dir) / (prefix + name)).string();
    cv::cvtColor(frames_rgb[i], bgr, cv::COLOR_RGB2BGR);
    GEODRIVE_CHECK_INPUT(cv::imwrite(path, bgr, params), path,
                         ": cannot write PNG");
    paths.push_back(path);
  }
  return paths;
}

void ContactSheetOptions::Check() const {
  GEODRIVE_CHECK_INPUT(columns >= 1 && columns <= 1000,
                       "contact sheet: columns must be 1..1000");
  GEODRIVE_CHECK_INPUT(thumb_width >= 8 && thumb_width <= 4096,
                       "contact sheet: thumb_width must be 8..4096");
  GEODRIVE_CHECK_INPUT(gap >= 0 && gap <= 256,
                       "contact sheet: gap must be 0..256");
}

cv::Mat MakeContactSheet(const std::vector<cv::Mat>& frames_rgb,
                         const std::vector<cv::Mat>& ground_truth_rgb,
                         const ContactSheetOptions& options) {
  options.Check();
  CheckFrames("contact sheet", frames_rgb);
  const bool with_gt = !ground_truth_rgb.empty();
  if (with_gt) {
    GEODRIVE_CHECK_INPUT(ground_truth_rgb.size() == frames_rgb.size(),
                         "contact sheet: ", ground_truth_rgb.size(),
                         " ground-truth frames for ", frames_rgb.size(),
                         " renders");
    for (const cv::Mat& m : ground_truth_rgb) {
      GEODRIVE_CHECK_INPUT(m.type() == CV_8UC3,
                           "contact sheet: ground truth must be CV_8UC3");
    }
  }
  const int tw = options.thumb_width;
  const int th = std::max(
      1, static_cast<int>(std::lround(static_cast<double>(frames_rgb[0].rows) *
                                      tw / frames_rgb[0].cols)));
  const int n = static_cast<int>(frames_rgb.size());
  const int cols = std::min(options.columns, n);
  const int grid_rows = (n + cols - 1) / cols;
  const int rows = grid_rows * (with_gt ? 2 : 1);
  const int g = options.gap;
  cv::Mat sheet(rows * th + (rows + 1) * g, cols * tw + (cols + 1) * g, CV_8UC3,
                cv::Scalar::all(0));
  auto place = [&](const cv::Mat& img, int row, int col) {
    cv::Mat thumb;
    cv::resize(img, thumb, cv::Size(tw, th), 0, 0, cv::INTER_AREA);
    thumb.copyTo(
        sheet(cv::Rect(g + col * (tw + g), g + row * (th + g), tw, th)));
  };
  for (int i = 0; i < n; ++i) {
    const int grid_row = i / cols, col = i % cols;
    if (with_gt) {
      place(ground_truth_rgb[i], 2 * grid_row, col);
      place(frames_rgb[i], 2 * grid_row + 1, col);
    } else {
      place(frames_rgb[i], grid_row, col);
    }
  }
  return sheet;
}

cv::Mat ResizeBilinear(const cv::Mat& image, int width, int height) {
  GEODRIVE_CHECK_INPUT(!image.empty() && width > 0 && height > 0,
                       "ResizeBilinear: bad input");
  cv::Mat out;
  cv::resize(image, out, cv::Size(width, height), 0, 0, cv::INTER_LINEAR);
  return out;
}

}  // namespace geodrive

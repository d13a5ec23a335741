#include "render/video/video.h"

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <opencv2/imgproc.hpp>

#include "geometry/image_io.h"
#include "geometry/image_resize.h"
#include "geometry/util/status.h"
#include "render/video/ffmpeg_encode.h"
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

// Thumbnail height for width `tw`, aspect of `frame` kept.
int ThumbHeight(const cv::Mat& frame, int tw) {
  return std::max(1, static_cast<int>(std::lround(
                         static_cast<double>(frame.rows) * tw / frame.cols)));
}

void CheckFourCC(const std::string& code) {
  GEODRIVE_CHECK_INPUT(code.size() == 4, "video: fourcc '", code,
                       "' must have 4 characters");
}

}  // namespace

void VideoWriteOptions::Check() const {
  GEODRIVE_CHECK_INPUT(fps > 0 && fps <= 1000, "video: fps ", fps,
                       " must be in (0, 1000]");
  CheckFourCC(fourcc);
  if (!fallback_fourcc.empty()) CheckFourCC(fallback_fourcc);
}

struct VideoStreamWriter::Impl {
  std::string path;
  VideoWriteResult result;
  cv::Size size, frame_size;
  std::unique_ptr<H264Mp4Writer> h264;
  std::unique_ptr<FfmpegVideoWriter> other;  // any other fourcc
  bool closed = false;
};

VideoStreamWriter::VideoStreamWriter(const std::string& path,
                                     int width,
                                     int height,
                                     const VideoWriteOptions& options)
    : impl_(std::make_unique<Impl>()) {
  options.Check();
  GEODRIVE_CHECK_INPUT(width > 0 && height > 0, path, ": bad frame size ",
                       width, "x", height);
  Impl& m = *impl_;
  m.path = path;
  m.frame_size = cv::Size(width, height);
  // H.264 (yuv420p) needs even sizes: pad with black.
  m.result.width = width + (width % 2);
  m.result.height = height + (height % 2);
  m.size = cv::Size(m.result.width, m.result.height);
  if (options.fourcc == "avc1" && HasH264Encoder()) {
    // Deterministic libx264 path (byte-identical files for identical frames).
    H264Options h264;
    h264.fps = options.fps;
    m.h264 = std::make_unique<H264Mp4Writer>(path, width, height, h264);
    m.result.fourcc = "avc1";
    return;
  }
  m.result.fourcc = options.fourcc;
  std::string first_error;
  try {
    m.other = std::make_unique<FfmpegVideoWriter>(path, width, height,
                                                  options.fourcc, options.fps);
    return;
  } catch (const InputError& e) {
    first_error = e.what();
  }
  GEODRIVE_CHECK_INPUT(!options.fallback_fourcc.empty(), first_error);
  std::cerr << "warning: " << path << ": fourcc " << options.fourcc
            << " is not available (" << first_error << "); using "
            << options.fallback_fourcc << "\n";
  m.result.fourcc = options.fallback_fourcc;
  m.result.fell_back = true;
  try {
    m.other = std::make_unique<FfmpegVideoWriter>(
        path, width, height, options.fallback_fourcc, options.fps);
  } catch (const InputError& e) {
    ThrowInputError(path, "cannot open a video writer (tried ", options.fourcc,
                    " and ", options.fallback_fourcc, "): ", e.what());
  }
}

VideoStreamWriter::~VideoStreamWriter() = default;

void VideoStreamWriter::Write(const cv::Mat& rgb) {
  Impl& m = *impl_;
  GEODRIVE_CHECK_INPUT(!m.closed, m.path, ": write after close");
  GEODRIVE_CHECK_INPUT(rgb.type() == CV_8UC3 && rgb.size() == m.frame_size,
                       m.path, ": frame ", m.result.frames, " is not an RGB ",
                       m.frame_size.width, "x", m.frame_size.height, " image");
  if (m.h264) {
    m.h264->Write(rgb);
  } else {
    m.other->Write(rgb);  // pads odd sizes itself
  }
  ++m.result.frames;
}

VideoWriteResult VideoStreamWriter::Close() {
  Impl& m = *impl_;
  GEODRIVE_CHECK_INPUT(!m.closed, m.path, ": closed twice");
  GEODRIVE_CHECK_INPUT(m.result.frames > 0, m.path, ": no frames");
  m.closed = true;
  if (m.h264) {
    m.h264->Finish();
  } else {
    m.other->Finish();
  }
  return m.result;
}

VideoWriteResult WriteVideo(const std::string& path,
                            const std::vector<cv::Mat>& frames_rgb,
                            const VideoWriteOptions& options) {
  options.Check();
  CheckFrames(path, frames_rgb);
  VideoStreamWriter writer(path, frames_rgb[0].cols, frames_rgb[0].rows,
                           options);
  for (const cv::Mat& rgb : frames_rgb) writer.Write(rgb);
  return writer.Close();
}

std::vector<std::string> WritePngSequence(
    const std::string& dir,
    const std::string& prefix,
    const std::vector<cv::Mat>& frames_rgb,
    int first_index) {
  CheckFrames(dir, frames_rgb);
  GEODRIVE_CHECK_INPUT(first_index >= 0, dir, ": negative first frame index");
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  GEODRIVE_CHECK_INPUT(!ec, dir, ": cannot create directory (", ec.message(),
                       ")");
  std::vector<std::string> paths;
  for (size_t i = 0; i < frames_rgb.size(); ++i) {
    char name[64];
    std::snprintf(name, sizeof(name), "%04zu.png", i + first_index);
    const std::string path =
        (std::filesystem::path(dir) / (prefix + name)).string();
    WriteImageRgb(path, frames_rgb[i]);  // libspng, level 3, atomic
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

namespace {

// INTER_AREA to `size`: AreaResizeRgb where it applies (RGB, shrinking on
// both axes; INTER_AREA's weights, within 1 level, several times faster at
// the non-integer 720x480 -> 160x107 of build-dataset's previews), else
// cv::resize. A frame already at `size` comes back as it is (so a sheet of
// thumbnails equals the sheet of the frames).
cv::Mat ResizeThumbnail(const cv::Mat& img, const cv::Size& size) {
  if (img.size() == size) return img;
  if (img.type() == CV_8UC3 && size.width <= img.cols &&
      size.height <= img.rows) {
    return AreaResizeRgb(img, img.cols, img.rows, size);
  }
  cv::Mat thumb;
  cv::resize(img, thumb, size, 0, 0, cv::INTER_AREA);
  return thumb;
}

}  // namespace

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
  const int th = ThumbHeight(frames_rgb[0], tw);
  const int n = static_cast<int>(frames_rgb.size());
  const int cols = std::min(options.columns, n);
  const int grid_rows = (n + cols - 1) / cols;
  const int rows = grid_rows * (with_gt ? 2 : 1);
  const int g = options.gap;
  cv::Mat sheet(rows * th + (rows + 1) * g, cols * tw + (cols + 1) * g, CV_8UC3,
                cv::Scalar::all(0));
  auto place = [&](const cv::Mat& img, int row, int col) {
    const cv::Mat thumb = ResizeThumbnail(img, cv::Size(tw, th));
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

cv::Mat ContactSheetThumbnail(const cv::Mat& frame_rgb,
                              const ContactSheetOptions& options) {
  options.Check();
  GEODRIVE_CHECK_INPUT(!frame_rgb.empty(), "contact sheet: empty frame");
  const cv::Mat thumb = ResizeThumbnail(
      frame_rgb, cv::Size(options.thumb_width,
                          ThumbHeight(frame_rgb, options.thumb_width)));
  return thumb.data == frame_rgb.data ? thumb.clone() : thumb;
}

cv::Mat ResizeBilinear(const cv::Mat& image, int width, int height) {
  GEODRIVE_CHECK_INPUT(!image.empty() && width > 0 && height > 0,
                       "ResizeBilinear: bad input");
  cv::Mat out;
  cv::resize(image, out, cv::Size(width, height), 0, 0, cv::INTER_LINEAR);
  return out;
}

}  // namespace geodrive

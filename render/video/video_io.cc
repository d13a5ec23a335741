#include "render/video/video_io.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <map>

#include "geometry/image_io.h"
#include "geometry/reconstruction.h"
#include "geometry/util/input_file.h"
#include "geometry/util/status.h"
#include "render/video/ffmpeg_decode.h"
#include "render/video/ffmpeg_encode.h"

namespace fs = std::filesystem;

namespace geodrive {
namespace {

std::string LowerExtension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) {
    return static_cast<char>(std::tolower(c));
  });
  return ext;
}

std::vector<std::string> ImageFilesIn(const std::string& dir) {
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.is_regular_file() && IsImageFile(entry.path().string())) {
      files.push_back(entry.path().string());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

bool IsFrameFolder(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return false;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    if (entry.is_regular_file() && IsImageFile(entry.path().string()))
      return true;
  }
  return false;
}

void CheckSameSize(const std::vector<cv::Mat>& frames,
                   const std::string& where) {
  const cv::Mat& last = frames.back();
  GEODRIVE_CHECK_INPUT(last.size() == frames.front().size(), where, ": frame ",
                       frames.size() - 1, " is ", last.cols, "x", last.rows,
                       " but frame 0 is ", frames.front().cols, "x",
                       frames.front().rows);
}

}  // namespace

bool IsVideoFile(const std::string& path) {
  const std::string ext = LowerExtension(path);
  return ext == ".mp4" || ext == ".avi" || ext == ".mkv" || ext == ".mov" ||
         ext == ".webm";
}

bool IsImageFile(const std::string& path) {
  const std::string ext = LowerExtension(path);
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg";
}

std::vector<cv::Mat> ReadVideoFrames(const std::string& path) {
  GEODRIVE_CHECK_INPUT(fs::exists(path), path, ": no such file or folder");
  if (fs::is_directory(path)) {
    std::vector<cv::Mat> frames;
    const std::vector<std::string> files = ImageFilesIn(path);
    GEODRIVE_CHECK_INPUT(!files.empty(), path,
                         ": empty video (no .png/.jpg frames in the folder)");
    for (const std::string& file : files) {
      frames.push_back(ReadImageRgb(file));
      CheckSameSize(frames, file);
    }
    return frames;
  }
  GEODRIVE_CHECK_INPUT(
      IsVideoFile(path), path,
      ": not a video (expected .mp4/.avi/.mkv/.mov/.webm or a frame folder)");
  CheckInputFile(path);  // a FIFO or device named like a video
  return DecodeVideoFileRgb(path);
}

VideoFrameStream::VideoFrameStream(const std::string& path) : path_(path) {
  GEODRIVE_CHECK_INPUT(fs::exists(path), path, ": no such file or folder");
  if (fs::is_directory(path)) {
    images_ = ImageFilesIn(path);
    GEODRIVE_CHECK_INPUT(!images_.empty(), path,
                         ": empty video (no .png/.jpg frames in the folder)");
    return;
  }
  GEODRIVE_CHECK_INPUT(
      IsVideoFile(path), path,
      ": not a video (expected .mp4/.avi/.mkv/.mov/.webm or a frame folder)");
  CheckInputFile(path);
  file_ = std::make_unique<VideoFileReader>(path);
}

VideoFrameStream::~VideoFrameStream() = default;

bool VideoFrameStream::Next(cv::Mat* rgb) {
  if (file_) {
    if (!file_->Next(rgb)) return false;
  } else {
    if (read_ >= static_cast<int64_t>(images_.size())) return false;
    const std::string& file = images_[static_cast<size_t>(read_)];
    *rgb = ReadImageRgb(file);
    if (read_ == 0) first_size_ = rgb->size();
    GEODRIVE_CHECK_INPUT(rgb->size() == first_size_, file, ": frame ", read_,
                         " is ", rgb->cols, "x", rgb->rows, " but frame 0 is ",
                         first_size_.width, "x", first_size_.height);
  }
  ++read_;
  return true;
}

void WriteVideoFrames(const std::string& path,
                      const std::vector<cv::Mat>& frames,
                      double fps) {
  GEODRIVE_CHECK_INPUT(!frames.empty(), path, ": no frames to write");
  for (const cv::Mat& f : frames) {
    GEODRIVE_CHECK_INPUT(f.type() == CV_8UC3 && f.size() == frames[0].size(),
                         path, ": frames must be RGB uint8 of one size");
  }
  if (!IsVideoFile(path)) {
    fs::create_directories(path);
    for (size_t i = 0; i < frames.size(); ++i) {
      char name[32];
      std::snprintf(name, sizeof(name), "%05zu.png", i);
      WriteImageRgb((fs::path(path) / name).string(), frames[i]);
    }
    return;
  }
  const std::string fourcc = LowerExtension(path) == ".avi" ? "MJPG" : "mp4v";
  if (fs::path(path).has_parent_path())
    fs::create_directories(fs::path(path).parent_path());
  FfmpegVideoWriter writer(path, frames[0].cols, frames[0].rows, fourcc, fps);
  for (const cv::Mat& f : frames) writer.Write(f);
  writer.Finish();
}

std::vector<VideoSource> ListVideos(const std::string& path,
                                    const std::string& member) {
  GEODRIVE_CHECK_INPUT(fs::exists(path), path, ": no such file or folder");
  const fs::path root(path);
  const std::string root_name = root.filename().empty()
                                    ? root.parent_path().filename().string()
                                    : root.filename().string();
  if (!fs::is_directory(root)) {
    GEODRIVE_CHECK_INPUT(
        IsVideoFile(path), path,
        ": not a video (expected .mp4/.avi/.mkv/.mov/.webm or a folder)");
    return {{root.stem().string(), path}};
  }
  if (IsFrameFolder(root)) return {{root_name, path}};
  const std::string member_stem = fs::path(member).stem().string();
  std::vector<VideoSource> pairs, loose;
  std::vector<fs::path> entries;
  for (const auto& entry : fs::directory_iterator(root))
    entries.push_back(entry.path());
  std::sort(entries.begin(), entries.end());
  for (const fs::path& entry : entries) {
    if (fs::is_directory(entry)) {
      if (!member.empty() && fs::is_regular_file(entry / member)) {
        pairs.push_back({entry.filename().string(), (entry / member).string()});
      } else if (!member_stem.empty() && IsFrameFolder(entry / member_stem)) {
        pairs.push_back(
            {entry.filename().string(), (entry / member_stem).string()});
      } else if (IsFrameFolder(entry)) {
        loose.push_back({entry.filename().string(), entry.string()});
      }
    } else if (IsVideoFile(entry.string())) {
      loose.push_back({entry.stem().string(), entry.string()});
    }
  }
  std::vector<VideoSource>& found = pairs.empty() ? loose : pairs;
  GEODRIVE_CHECK_INPUT(!found.empty(), path,
                       ": no videos found (expected video files, frame "
                       "folders, or clip folders holding '",
                       member, "')");
  return found;
}

std::vector<VideoPairSource> MatchVideos(const std::vector<VideoSource>& pred,
                                         const std::vector<VideoSource>& gt) {
  GEODRIVE_CHECK_INPUT(!pred.empty() && !gt.empty(),
                       "eval: no videos to compare");
  if (pred.size() == 1 && gt.size() == 1) {
    return {{gt[0].id, pred[0].path, gt[0].path}};
  }
  std::map<std::string, std::string> gt_by_id, pred_by_id;
  for (const VideoSource& v : gt) gt_by_id[v.id] = v.path;
  for (const VideoSource& v : pred) pred_by_id[v.id] = v.path;
  std::vector<VideoPairSource> out;
  std::string missing_gt, missing_pred;
  int n_missing_gt = 0, n_missing_pred = 0;
  for (const auto& [id, p] : pred_by_id) {
    auto it = gt_by_id.find(id);
    if (it == gt_by_id.end()) {
      if (n_missing_gt++ < 5)
        missing_gt += (missing_gt.empty() ? "" : ", ") + id;
      continue;
    }
    out.push_back({id, p, it->second});
  }
  for (const auto& [id, g] : gt_by_id) {
    if (!pred_by_id.count(id) && n_missing_pred++ < 5) {
      missing_pred += (missing_pred.empty() ? "" : ", ") + id;
    }
  }
  GEODRIVE_CHECK_INPUT(
      n_missing_gt == 0, "eval: ", n_missing_gt,
      " predicted videos have no ground truth with the same id (", missing_gt,
      n_missing_gt > 5 ? ", ..." : "", ")");
  GEODRIVE_CHECK_INPUT(
      n_missing_pred == 0, "eval: ", n_missing_pred,
      " ground-truth videos have no prediction with the same id (",
      missing_pred, n_missing_pred > 5 ? ", ..." : "", ")");
  return out;
}

std::vector<cv::Mat> ReadVideoFramesExactly(const std::string& path,
                                            int64_t frames,
                                            int width,
                                            int height) {
  CheckVideoFramesFit(path, frames, width, height);
  VideoFileReader reader(path, /*whole=*/true);
  GEODRIVE_CHECK_INPUT(reader.width() == width && reader.height() == height,
                       path, ": frames are ", reader.width(), "x",
                       reader.height(),
                       " but the reconstruction's other files "
                       "are ",
                       width, "x", height);
  const int64_t declared = reader.declared_frames();
  GEODRIVE_CHECK_INPUT(declared == 0 || declared == frames, path, ": ",
                       declared,
                       " frames but the reconstruction's other files "
                       "have ",
                       frames);
  std::vector<cv::Mat> out;
  out.reserve(static_cast<size_t>(frames));
  cv::Mat rgb;
  while (reader.Next(&rgb)) {
    GEODRIVE_CHECK_INPUT(
        static_cast<int64_t>(out.size()) < frames, path, ": more than ", frames,
        " frames but the reconstruction's other files have ", frames);
    out.push_back(std::move(rgb));
    rgb = cv::Mat();
  }
  GEODRIVE_CHECK_INPUT(static_cast<int64_t>(out.size()) == frames, path, ": ",
                       out.size(),
                       " frames but the reconstruction's other "
                       "files have ",
                       frames);
  return out;
}

void RegisterVideoDecoderForReconstructions() {
  static const bool registered = [] {
    SetReconstructionVideoDecoder(ReadVideoFramesExactly);
    return true;
  }();
  (void)registered;
}

}  // namespace geodrive

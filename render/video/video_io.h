#pragma once
// Video inputs of `geodrive eval`: MP4/MOV, AVI and Matroska/WebM files
// (decoded through FFmpeg's libraries, render/video/ffmpeg_decode.h), folders
// of frames (PNG/JPG sorted by file name), folders of such videos, and the
// dataset's pairs folders (pairs/<clip_id>/gt.mp4, cond.mp4, ...). Frames are
// RGB CV_8UC3.

#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace geodrive {

class VideoFileReader;  // render/video/ffmpeg_decode.h

// True for .mp4 .avi .mkv .mov .webm (case-insensitive).
bool IsVideoFile(const std::string& path);
// True for .png .jpg .jpeg (case-insensitive).
bool IsImageFile(const std::string& path);

// Reads every frame of a video file or frame folder as RGB CV_8UC3 (a video
// file: the frames cv::VideoCapture returned, see ffmpeg_decode.h). Throws
// InputError naming the path if it does not exist, cannot be decoded (not a
// video, corrupt or truncated data, over VideoReadLimits), has no frames, or
// frames change size.
std::vector<cv::Mat> ReadVideoFrames(const std::string& path);

// The frames of a video file or frame folder one at a time, with
// ReadVideoFrames's checks but holding one frame (a video file: the decoder
// of ffmpeg_decode.h; a folder: one image file at a time), so a video of any
// length is compared in bounded memory.
class VideoFrameStream {
 public:
  explicit VideoFrameStream(const std::string& path);
  ~VideoFrameStream();
  VideoFrameStream(const VideoFrameStream&) = delete;
  VideoFrameStream& operator=(const VideoFrameStream&) = delete;
  // The next frame (RGB CV_8UC3); false after the last one.
  bool Next(cv::Mat* rgb);
  // Frames handed out so far.
  int64_t frames_read() const { return read_; }

 private:
  std::string path_;
  std::unique_ptr<VideoFileReader> file_;
  std::vector<std::string> images_;  // a frame folder's files
  cv::Size first_size_;
  int64_t read_ = 0;
};

// Writes RGB CV_8UC3 frames as a video file (.mp4: 'mp4v', .avi: 'MJPG',
// through FfmpegVideoWriter: fixed quantiser 2, odd sizes padded) or, when
// `path` has no video extension, as a folder of PNGs 00000.png, 00001.png,
// ... (lossless). Throws InputError.
void WriteVideoFrames(const std::string& path,
                      const std::vector<cv::Mat>& frames,
                      double fps = 8);

// The frames of the video file `path` when it must hold exactly `frames`
// frames of `width` x `height` (a reconstruction's images, e.g. the GEN3C
// export's rgb.mp4): the header's frame size and declared frame count are
// checked before anything is decoded, and decoding stops with an InputError
// naming the file at the first frame too many or when it ends short.
std::vector<cv::Mat> ReadVideoFramesExactly(const std::string& path,
                                            int64_t frames,
                                            int width,
                                            int height);
// Sets ReadVideoFramesExactly as the decoder of the reconstruction readers
// (SetReconstructionVideoDecoder, geometry/reconstruction.h). Idempotent.
void RegisterVideoDecoderForReconstructions();

// One video of a collection: id (clip id or file stem) and where its frames
// are.
struct VideoSource {
  std::string id;
  std::string path;  // video file or frame folder
};

// The videos under `path`:
//  - a video file or a frame folder: one video (id = file stem / folder name);
//  - a pairs folder (sub-folders holding `member`, e.g. pairs/<clip>/gt.mp4):
//  one per clip, id =
//    clip folder name; `member` may also name a frame sub-folder
//    (pairs/<clip>/gt/);
//  - a folder of video files and/or frame sub-folders: one per entry, id = stem
//  / name.
// Sorted by id. Throws InputError if nothing usable is found.
std::vector<VideoSource> ListVideos(const std::string& path,
                                    const std::string& member);

struct VideoPairSource {
  std::string id;
  std::string pred_path;
  std::string gt_path;
};

// Pairs predicted and ground-truth videos by id (two single videos pair
// regardless of names). Throws InputError listing ids present on one side only.
std::vector<VideoPairSource> MatchVideos(const std::vector<VideoSource>& pred,
                                         const std::vector<VideoSource>& gt);

}  // namespace geodrive

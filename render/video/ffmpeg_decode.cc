#include "render/video/ffmpeg_decode.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/display.h>
#include <libavutil/imgutils.h>
#include <libswscale/swscale.h>
}

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <deque>
#include <mutex>
#include <opencv2/imgproc.hpp>

#include "geometry/util/input_file.h"
#include "geometry/util/size_limits.h"
#include "geometry/util/status.h"
#include "render/video/ffmpeg_log.h"

namespace geodrive {
namespace {

struct Decoder {
  AVFormatContext* fmt = nullptr;
  AVCodecContext* codec = nullptr;
  AVPacket* packet = nullptr;
  AVFrame* frame = nullptr;
  AVFrame* bgr = nullptr;  // swscale's output, 32-byte aligned as OpenCV's
  SwsContext* sws = nullptr;
  int stream = -1;
  int rotation = 0;  // clockwise degrees to apply: 0, 90, 180, 270
  int64_t frame_bytes = 0;
  int first_width = 0, first_height = 0;  // of the first decoded frame
  int64_t received = 0;                   // frames decoded
  int64_t taken = 0;                      // frames handed out
  bool drained = false;                   // the decoder has given its last
  std::deque<cv::Mat> pending;            // decoded, not yet handed out
  ~Decoder() {
    if (sws) sws_freeContext(sws);
    if (bgr) av_frame_free(&bgr);
    if (frame) av_frame_free(&frame);
    if (packet) av_packet_free(&packet);
    if (codec) avcodec_free_context(&codec);
    if (fmt) avformat_close_input(&fmt);
  }
};

void CheckFrameSize(const std::string& path, int64_t width, int64_t height) {
  GEODRIVE_CHECK_INPUT(width > 0 && height > 0, path,
                       ": the video header declares frames of ", width, "x",
                       height, " pixels");
  GEODRIVE_CHECK_INPUT(width <= VideoReadLimits::kMaxSide &&
                           height <= VideoReadLimits::kMaxSide &&
                           width * height <= VideoReadLimits::kMaxPixels,
                       path, ": video frames of ", width, "x", height,
                       " pixels are over the reader's limit (",
                       VideoReadLimits::kMaxSide, " pixels per side, ",
                       VideoReadLimits::kMaxPixels, " pixels)");
}

// Opens the container (file protocol only, no external references) and
// refuses what is not MP4/MOV, AVI or Matroska/WebM.
void OpenContainer(const std::string& path, Decoder* d) {
  CheckInputFile(path);  // libavformat opens the path itself
  AVDictionary* options = nullptr;
  av_dict_set(&options, "protocol_whitelist", "file", 0);
  const std::string url = "file:" + path;
  const int r = avformat_open_input(&d->fmt, url.c_str(), nullptr, &options);
  av_dict_free(&options);
  GEODRIVE_CHECK_INPUT(r >= 0, path, ": not a readable video (libavformat: ",
                       FfmpegErrorDetail(r), ")");
  const std::string name = d->fmt->iformat->name;
  const bool known = name.rfind("mov,", 0) == 0 || name == "avi" ||
                     name.rfind("matroska", 0) == 0;
  GEODRIVE_CHECK_INPUT(known, path, ": not a video container this reader ",
                       "accepts (found '", name,
                       "'; expected MP4/MOV, AVI or Matroska/WebM)");
}

// Finds the video stream and checks its declared size, frame count and index
// before any frame is decoded.
// With `whole` (every frame to be held), the declared frame count too.
void FindVideoStream(const std::string& path, Decoder* d, bool whole) {
  AVFormatContext* fmt = d->fmt;
  for (unsigned i = 0; i < fmt->nb_streams; ++i) {
    const AVCodecParameters* par = fmt->streams[i]->codecpar;
    if (par->codec_type == AVMEDIA_TYPE_VIDEO && par->width != 0) {
      CheckFrameSize(path, par->width, par->height);
      if (whole) {
        CheckVideoFramesFit(path,
                            std::max<int64_t>(0, fmt->streams[i]->nb_frames),
                            par->width, par->height);
      }
    }
  }
  // Decoders opened while probing stay within the same pixel limit.
  std::vector<AVDictionary*> options(fmt->nb_streams, nullptr);
  for (AVDictionary*& o : options) {
    av_dict_set_int(&o, "max_pixels", VideoReadLimits::kMaxPixels, 0);
    av_dict_set(&o, "threads", "1", 0);
  }
  const int r = avformat_find_stream_info(fmt, options.data());
  for (AVDictionary*& o : options) av_dict_free(&o);
  GEODRIVE_CHECK_INPUT(r >= 0, path, ": not a readable video (libavformat: ",
                       FfmpegErrorDetail(r), ")");
  d->stream = av_find_best_stream(fmt, AVMEDIA_TYPE_VIDEO, -1, -1, nullptr, 0);
  GEODRIVE_CHECK_INPUT(d->stream >= 0, path, ": has no video stream");
  AVStream* st = fmt->streams[d->stream];
  CheckFrameSize(path, st->codecpar->width, st->codecpar->height);
  d->frame_bytes = int64_t{3} * st->codecpar->width * st->codecpar->height;
  // A file cut short: its own index points past the end.
  const int64_t file_size = fmt->pb ? avio_size(fmt->pb) : -1;
  const int entries = avformat_index_get_entries_count(st);
  if (file_size > 0 && entries > 0) {
    const AVIndexEntry* last = avformat_index_get_entry(st, entries - 1);
    GEODRIVE_CHECK_INPUT(last->pos + last->size <= file_size, path,
                         ": truncated video (its index lists data up to byte ",
                         last->pos + last->size, ", the file has ", file_size,
                         ")");
  }
  // OpenCV's rotation: the display matrix's angle, counter-clockwise.
  const uint8_t* matrix =
      av_stream_get_side_data(st, AV_PKT_DATA_DISPLAYMATRIX, nullptr);
  if (matrix != nullptr) {
    const double angle =
        av_display_rotation_get(reinterpret_cast<const int32_t*>(matrix));
    if (std::isfinite(angle)) {
      int rotation = -static_cast<int>(std::lround(angle));
      rotation = ((rotation % 360) + 360) % 360;
      if (rotation % 90 == 0) d->rotation = rotation;
    }
  }
}

void OpenDecoder(const std::string& path, Decoder* d) {
  const AVCodecParameters* par = d->fmt->streams[d->stream]->codecpar;
  const AVCodec* decoder = avcodec_find_decoder(par->codec_id);
  GEODRIVE_CHECK_INPUT(decoder != nullptr, path, ": no decoder for its '",
                       avcodec_get_name(par->codec_id), "' video");
  d->codec = avcodec_alloc_context3(decoder);
  GEODRIVE_CHECK_INPUT(d->codec != nullptr, path, ": out of memory");
  int r = avcodec_parameters_to_context(d->codec, par);
  GEODRIVE_CHECK_INPUT(r >= 0, path, ": bad codec parameters (",
                       FfmpegErrorDetail(r), ")");
  // One thread: the same frames on any machine. Errors the decoder can detect
  // stop the decode instead of being concealed.
  d->codec->thread_count = 1;
  d->codec->max_pixels = VideoReadLimits::kMaxPixels;
  d->codec->err_recognition |= AV_EF_EXPLODE;
  r = avcodec_open2(d->codec, decoder, nullptr);
  GEODRIVE_CHECK_INPUT(r >= 0, path, ": cannot open the '", decoder->name,
                       "' decoder (", FfmpegErrorDetail(r), ")");
  d->packet = av_packet_alloc();
  d->frame = av_frame_alloc();
  d->bgr = av_frame_alloc();
  GEODRIVE_CHECK_INPUT(d->packet && d->frame && d->bgr, path,
                       ": out of memory");
}

// True when every plane of `f` holds `width` pixels per row, i.e. swscale may
// read that far.
bool RowsHold(const AVFrame* f, int width) {
  int need[4] = {0, 0, 0, 0};
  if (av_image_fill_linesizes(need, static_cast<AVPixelFormat>(f->format),
                              width) < 0) {
    return false;
  }
  for (int p = 0; p < 4; ++p) {
    if (need[p] > 0 && (f->data[p] == nullptr || f->linesize[p] < need[p]))
      return false;
  }
  return true;
}

// The decoded frame as RGB, converted as OpenCV's CvCapture_FFMPEG does: at
// the coded size when the frame's rows hold it (the SIMD paths of swscale
// depend on the width), into av_frame_get_buffer(32) storage, BGR, then RGB.
cv::Mat ConvertFrame(const std::string& path, Decoder* d) {
  const AVFrame* f = d->frame;
  int bw = f->width, bh = f->height;
  if (d->codec->coded_width >= f->width &&
      d->codec->coded_height >= f->height &&
      d->codec->coded_width <= f->width + 64 &&
      d->codec->coded_height <= f->height + 64 &&
      RowsHold(f, d->codec->coded_width)) {
    bw = d->codec->coded_width;
    bh = d->codec->coded_height;
  }
  if (d->bgr->width != bw || d->bgr->height != bh) {
    av_frame_unref(d->bgr);
    d->bgr->format = AV_PIX_FMT_BGR24;
    d->bgr->width = bw;
    d->bgr->height = bh;
    GEODRIVE_CHECK_INPUT(av_frame_get_buffer(d->bgr, 32) >= 0, path,
                         ": out of memory for a ", bw, "x", bh, " frame");
  }
  d->sws = sws_getCachedContext(
      d->sws, bw, bh, static_cast<AVPixelFormat>(f->format), bw, bh,
      AV_PIX_FMT_BGR24, SWS_BICUBIC, nullptr, nullptr, nullptr);
  if (d->sws == nullptr) {
    const char* name =
        av_get_pix_fmt_name(static_cast<AVPixelFormat>(f->format));
    ThrowInputError(path, "cannot convert its '", name ? name : "unknown",
                    "' pixels to RGB");
  }
  sws_scale(d->sws, f->data, f->linesize, 0, f->height, d->bgr->data,
            d->bgr->linesize);
  const cv::Mat bgr(f->height, f->width, CV_8UC3, d->bgr->data[0],
                    static_cast<size_t>(d->bgr->linesize[0]));
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  if (d->rotation == 90) {
    cv::rotate(rgb, rgb, cv::ROTATE_90_CLOCKWISE);
  } else if (d->rotation == 180) {
    cv::rotate(rgb, rgb, cv::ROTATE_180);
  } else if (d->rotation == 270) {
    cv::rotate(rgb, rgb, cv::ROTATE_90_COUNTERCLOCKWISE);
  }
  return rgb;
}

// Takes every frame the decoder has ready into `d->pending`.
void ReceiveFrames(const std::string& path, Decoder* d) {
  while (true) {
    const int r = avcodec_receive_frame(d->codec, d->frame);
    if (r == AVERROR(EAGAIN) || r == AVERROR_EOF) return;
    const int64_t index = d->received;
    GEODRIVE_CHECK_INPUT(r >= 0, path, ": corrupt video data at frame ", index,
                         " (", FfmpegErrorDetail(r), ")");
    GEODRIVE_CHECK_INPUT(d->frame->decode_error_flags == 0 &&
                             !(d->frame->flags & AV_FRAME_FLAG_CORRUPT),
                         path, ": corrupt video data at frame ", index,
                         " (the decoder concealed errors)");
    const AVFrame* f = d->frame;
    CheckFrameSize(path, f->width, f->height);
    if (d->first_width == 0) {
      d->first_width = f->width;
      d->first_height = f->height;
    }
    GEODRIVE_CHECK_INPUT(
        f->width == d->first_width && f->height == d->first_height, path,
        ": frame ", index, " is ", f->width, "x", f->height, " but frame 0 is ",
        d->first_width, "x", d->first_height);
    d->pending.push_back(ConvertFrame(path, d));
    ++d->received;
    av_frame_unref(d->frame);
  }
}

// Decodes until a frame is ready or the video ends.
void DecodeMore(const std::string& path, Decoder* d) {
  while (d->pending.empty() && !d->drained) {
    int r = av_read_frame(d->fmt, d->packet);
    if (r == AVERROR_EOF) {
      GEODRIVE_CHECK_INPUT(d->fmt->pb == nullptr || d->fmt->pb->error == 0,
                           path, ": read error (",
                           FfmpegErrorDetail(d->fmt->pb->error), ")");
      r = avcodec_send_packet(d->codec, nullptr);  // drain
      GEODRIVE_CHECK_INPUT(r >= 0 || r == AVERROR_EOF, path,
                           ": corrupt video data at the end (",
                           FfmpegErrorDetail(r), ")");
      ReceiveFrames(path, d);
      d->drained = true;
      break;
    }
    GEODRIVE_CHECK_INPUT(r >= 0, path,
                         ": truncated or unreadable video data after frame ",
                         d->received, " (", FfmpegErrorDetail(r), ")");
    if (d->packet->stream_index != d->stream) {
      av_packet_unref(d->packet);
      continue;
    }
    const bool corrupt = (d->packet->flags & AV_PKT_FLAG_CORRUPT) != 0;
    r = avcodec_send_packet(d->codec, d->packet);
    if (r == AVERROR(EAGAIN)) {  // frames first, then the same packet again
      ReceiveFrames(path, d);
      r = avcodec_send_packet(d->codec, d->packet);
    }
    av_packet_unref(d->packet);
    GEODRIVE_CHECK_INPUT(!corrupt, path, ": corrupt video packet after frame ",
                         d->received);
    GEODRIVE_CHECK_INPUT(r >= 0, path, ": corrupt video data after frame ",
                         d->received, " (", FfmpegErrorDetail(r), ")");
    ReceiveFrames(path, d);
  }
}

}  // namespace

struct VideoFileReader::Impl {
  std::string path;
  Decoder d;
};

VideoFileReader::VideoFileReader(const std::string& path, bool whole)
    : impl_(new Impl) {
  impl_->path = path;
  InstallFfmpegLogCapture();
  TakeFfmpegLogMessage();  // forget what an earlier call left
  OpenContainer(path, &impl_->d);
  FindVideoStream(path, &impl_->d, whole);
  OpenDecoder(path, &impl_->d);
}

VideoFileReader::~VideoFileReader() = default;

int VideoFileReader::width() const {
  const AVCodecParameters* par =
      impl_->d.fmt->streams[impl_->d.stream]->codecpar;
  const bool swapped = impl_->d.rotation == 90 || impl_->d.rotation == 270;
  return swapped ? par->height : par->width;
}

int VideoFileReader::height() const {
  const AVCodecParameters* par =
      impl_->d.fmt->streams[impl_->d.stream]->codecpar;
  const bool swapped = impl_->d.rotation == 90 || impl_->d.rotation == 270;
  return swapped ? par->width : par->height;
}

int64_t VideoFileReader::declared_frames() const {
  return std::max<int64_t>(0,
                           impl_->d.fmt->streams[impl_->d.stream]->nb_frames);
}

int64_t VideoFileReader::frames_read() const { return impl_->d.taken; }

bool VideoFileReader::Next(cv::Mat* rgb) {
  Decoder& d = impl_->d;
  DecodeMore(impl_->path, &d);
  if (d.pending.empty()) {
    GEODRIVE_CHECK_INPUT(d.taken > 0, impl_->path,
                         ": empty video (no frame could be decoded)");
    return false;
  }
  *rgb = std::move(d.pending.front());
  d.pending.pop_front();
  ++d.taken;
  return true;
}

int64_t VideoFrameBytes(int64_t width, int64_t height) {
  return 3 * width * height + SizeLimits::kFrameOverheadBytes;
}

void CheckVideoFramesFit(const std::string& path,
                         int64_t frames,
                         int64_t width,
                         int64_t height) {
  CheckDeclaredCount(path, "the video", static_cast<uint64_t>(frames),
                     SizeLimits::kMaxVideoFrames);
  CheckAllocation(
      path,
      std::to_string(frames) + " decoded frames of " + std::to_string(width) +
          "x" + std::to_string(height),
      SaturatingMul(static_cast<uint64_t>(frames),
                    static_cast<uint64_t>(VideoFrameBytes(width, height))),
      SizeLimits::kMaxVideoDecodeBytes);
}

std::vector<cv::Mat> DecodeVideoFileRgb(const std::string& path) {
  VideoFileReader reader(path, /*whole=*/true);
  // The declared frame count against the limits before any frame is decoded,
  // then the frames decoded so far, frame by frame.
  CheckVideoFramesFit(path, reader.declared_frames(), reader.width(),
                      reader.height());
  std::vector<cv::Mat> frames;
  cv::Mat frame;
  while (reader.Next(&frame)) {
    CheckVideoFramesFit(path, static_cast<int64_t>(frames.size()) + 1,
                        frame.cols, frame.rows);
    frames.push_back(std::move(frame));
  }
  return frames;
}

}  // namespace geodrive

#include "render/video/h264.h"

#include "render/video/ffmpeg_log.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/imgutils.h>
#include <libavutil/opt.h>
}

#include <cstdio>
#include <cstring>
#include <memory>
#include <opencv2/imgproc.hpp>

#include "geometry/util/files.h"
#include "geometry/util/output_file.h"
#include "geometry/util/status.h"

namespace geodrive {

void H264Options::Check() const {
  GEODRIVE_CHECK_INPUT(fps > 0 && fps <= 240,
                       "video: fps must be in (0, 240], got ", fps);
  GEODRIVE_CHECK_INPUT(crf >= 0 && crf <= 51,
                       "video: crf must be in [0, 51], got ", crf);
  GEODRIVE_CHECK_INPUT(gop >= 1, "video: gop must be >= 1");
}

bool HasH264Encoder() {
  return avcodec_find_encoder_by_name("libx264") != nullptr;
}

namespace {

struct Cleanup {
  AVFormatContext* fmt = nullptr;
  AVCodecContext* codec = nullptr;
  AVFrame* frame = nullptr;
  AVPacket* packet = nullptr;
  bool io_open = false;
  ~Cleanup() {
    if (packet) av_packet_free(&packet);
    if (frame) av_frame_free(&frame);
    if (codec) avcodec_free_context(&codec);
    if (fmt) {
      if (io_open) avio_closep(&fmt->pb);
      avformat_free_context(fmt);
    }
  }
};

void Drain(Cleanup& c, AVStream* stream, const std::string& path) {
  while (true) {
    const int r = avcodec_receive_packet(c.codec, c.packet);
    if (r == AVERROR(EAGAIN) || r == AVERROR_EOF) return;
    GEODRIVE_CHECK_INPUT(r >= 0, path, ": encoding failed (", FfmpegError(r),
                         ")");
    av_packet_rescale_ts(c.packet, c.codec->time_base, stream->time_base);
    c.packet->stream_index = stream->index;
    const int w = av_interleaved_write_frame(c.fmt, c.packet);
    GEODRIVE_CHECK_INPUT(w >= 0, path, ": writing failed (", FfmpegError(w),
                         ")");
  }
}

}  // namespace

struct H264Mp4Writer::Impl {
  std::string path, tmp;
  int w = 0, h = 0, ew = 0, eh = 0;
  int frames = 0;
  bool finished = false;
  Cleanup c;
  AVStream* stream = nullptr;
  cv::Mat padded, yuv;
};

H264Mp4Writer::H264Mp4Writer(const std::string& path,
                             int width,
                             int height,
                             const H264Options& options)
    : impl_(std::make_unique<Impl>()) {
  options.Check();
  GEODRIVE_CHECK_INPUT(width > 0 && height > 0, path, ": bad frame size ",
                       width, "x", height);
  Impl& m = *impl_;
  m.path = path;
  CheckReplaceableOutput(path);
  m.tmp = TemporaryPathFor(path, ".mp4");
  m.w = width;
  m.h = height;
  m.ew = width + (width % 2);
  m.eh = height + (height % 2);
  Cleanup& c = m.c;
  av_log_set_level(AV_LOG_ERROR);
  int r = avformat_alloc_output_context2(&c.fmt, nullptr, "mp4", m.tmp.c_str());
  GEODRIVE_CHECK_INPUT(r >= 0 && c.fmt, path, ": cannot create an mp4 muxer (",
                       FfmpegError(r), ")");
  const AVCodec* codec = avcodec_find_encoder_by_name("libx264");
  GEODRIVE_CHECK_INPUT(codec, path,
                       ": this FFmpeg has no libx264 H.264 encoder");
  m.stream = avformat_new_stream(c.fmt, nullptr);
  c.codec = avcodec_alloc_context3(codec);
  c.codec->width = m.ew;
  c.codec->height = m.eh;
  c.codec->pix_fmt = AV_PIX_FMT_YUV420P;
  // A rational time base from the fps (e.g. 10 -> 1/10, 12.5 -> 2/25).
  const AVRational rate = av_d2q(options.fps, 100000);
  c.codec->time_base = av_inv_q(rate);
  c.codec->framerate = rate;
  c.codec->gop_size = options.gop;
  c.codec->thread_count = 1;  // determinism
  c.codec->flags |= AV_CODEC_FLAG_BITEXACT;
  if (c.fmt->oformat->flags & AVFMT_GLOBALHEADER)
    c.codec->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
  av_opt_set(c.codec->priv_data, "preset", options.preset.c_str(), 0);
  av_opt_set(c.codec->priv_data, "crf", std::to_string(options.crf).c_str(), 0);
  // Determinism: one thread, no threaded lookahead, x264's deterministic mode,
  // and no mbtree (with mbtree the bytes changed between runs of the same
  // frames in a multi-threaded process).
  av_opt_set(c.codec->priv_data, "x264-params",
             "threads=1:sync-lookahead=0:deterministic=1:mbtree=0", 0);
  r = avcodec_open2(c.codec, codec, nullptr);
  GEODRIVE_CHECK_INPUT(r >= 0, path, ": cannot open the H.264 encoder (",
                       FfmpegError(r), ")");
  r = avcodec_parameters_from_context(m.stream->codecpar, c.codec);
  GEODRIVE_CHECK_INPUT(r >= 0, path, ": codec parameters (", FfmpegError(r),
                       ")");
  m.stream->time_base = c.codec->time_base;
  m.stream->avg_frame_rate = rate;
  c.fmt->flags |= AVFMT_FLAG_BITEXACT;
  r = avio_open(&c.fmt->pb, m.tmp.c_str(), AVIO_FLAG_WRITE);
  GEODRIVE_CHECK_INPUT(r >= 0, path, ": cannot open for writing (",
                       FfmpegError(r), ")");
  c.io_open = true;
  AVDictionary* mux_options = nullptr;
  av_dict_set(&mux_options, "movflags", "+faststart", 0);
  r = avformat_write_header(c.fmt, &mux_options);
  av_dict_free(&mux_options);
  GEODRIVE_CHECK_INPUT(r >= 0, path, ": cannot write the mp4 header (",
                       FfmpegError(r), ")");
  c.packet = av_packet_alloc();
  cv::Mat padded_storage(m.eh + 2, m.ew, CV_8UC3, cv::Scalar(0, 0, 0));
  m.padded = padded_storage(cv::Rect(0, 0, m.ew, m.eh)).clone();
}

H264Mp4Writer::~H264Mp4Writer() {
  if (!impl_ || impl_->finished) return;
  // Abandoned (an exception): close the muxer's file and remove it.
  Cleanup& c = impl_->c;
  if (c.fmt && c.io_open) {
    avio_closep(&c.fmt->pb);
    c.io_open = false;
  }
  std::remove(impl_->tmp.c_str());
}

int H264Mp4Writer::frames_written() const { return impl_->frames; }

void H264Mp4Writer::Write(const cv::Mat& frame_rgb) {
  Impl& m = *impl_;
  Cleanup& c = m.c;
  GEODRIVE_CHECK_INPUT(!m.finished, m.path, ": write after finish");
  GEODRIVE_CHECK_INPUT(frame_rgb.type() == CV_8UC3 && frame_rgb.cols == m.w &&
                           frame_rgb.rows == m.h,
                       m.path, ": frame ", m.frames, " is not an RGB ", m.w,
                       "x", m.h, " image");
  const int ew = m.ew, eh = m.eh;
  // Odd sides are padded to even ones (black); even-sized frames convert
  // from the caller's image directly (no 1 MB copy a 720x480 frame).
  const bool direct = ew == m.w && eh == m.h;
  if (!direct) frame_rgb.copyTo(m.padded(cv::Rect(0, 0, m.w, m.h)));
  // A fresh, fully zeroed frame each time (the encoder may keep a reference
  // to the previous one, and uninitialised row padding would make the output
  // depend on heap contents).
  if (c.frame) av_frame_free(&c.frame);
  c.frame = av_frame_alloc();
  c.frame->format = AV_PIX_FMT_YUV420P;
  c.frame->width = ew;
  c.frame->height = eh;
  int r = av_frame_get_buffer(c.frame, 0);
  GEODRIVE_CHECK_INPUT(r >= 0, m.path, ": frame allocation failed");
  for (int p = 0; p < 3; ++p) {
    std::memset(c.frame->data[p], 0,
                static_cast<size_t>(c.frame->linesize[p]) * (p ? eh / 2 : eh));
  }
  // RGB -> YUV 4:2:0 (BT.601, limited range) with OpenCV: deterministic and
  // independent of buffer alignment (swscale picks SIMD paths by alignment).
  cv::cvtColor(direct ? frame_rgb : m.padded, m.yuv, cv::COLOR_RGB2YUV_I420);
  const uint8_t* y = m.yuv.ptr<uint8_t>(0);
  const uint8_t* u = y + static_cast<size_t>(ew) * eh;
  const uint8_t* v = u + static_cast<size_t>(ew / 2) * (eh / 2);
  for (int row = 0; row < eh; ++row) {
    std::memcpy(
        c.frame->data[0] + static_cast<size_t>(row) * c.frame->linesize[0],
        y + static_cast<size_t>(row) * ew, ew);
  }
  for (int row = 0; row < eh / 2; ++row) {
    std::memcpy(
        c.frame->data[1] + static_cast<size_t>(row) * c.frame->linesize[1],
        u + static_cast<size_t>(row) * (ew / 2), ew / 2);
    std::memcpy(
        c.frame->data[2] + static_cast<size_t>(row) * c.frame->linesize[2],
        v + static_cast<size_t>(row) * (ew / 2), ew / 2);
  }
  c.frame->pts = static_cast<int64_t>(m.frames);
  r = avcodec_send_frame(c.codec, c.frame);
  GEODRIVE_CHECK_INPUT(r >= 0, m.path, ": encoding frame ", m.frames,
                       " failed (", FfmpegError(r), ")");
  Drain(c, m.stream, m.path);
  ++m.frames;
}

void H264Mp4Writer::Finish() {
  Impl& m = *impl_;
  Cleanup& c = m.c;
  GEODRIVE_CHECK_INPUT(!m.finished, m.path, ": finished twice");
  GEODRIVE_CHECK_INPUT(m.frames > 0, m.path, ": no frames to write");
  avcodec_send_frame(c.codec, nullptr);
  Drain(c, m.stream, m.path);
  const int r = av_write_trailer(c.fmt);
  GEODRIVE_CHECK_INPUT(r >= 0, m.path, ": cannot finish the mp4 (",
                       FfmpegError(r), ")");
  avio_closep(&c.fmt->pb);
  c.io_open = false;
  CommitTemporaryFile(m.tmp, m.path);
  m.finished = true;
}

void WriteH264Mp4(const std::string& path,
                  const std::vector<cv::Mat>& frames,
                  const H264Options& options) {
  GEODRIVE_CHECK_INPUT(!frames.empty(), path, ": no frames to write");
  // Write() checks each frame; a failure removes the temporary file.
  H264Mp4Writer writer(path, frames[0].cols, frames[0].rows, options);
  for (const cv::Mat& frame : frames) writer.Write(frame);
  writer.Finish();
}

}  // namespace geodrive

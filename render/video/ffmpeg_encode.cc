#include "render/video/ffmpeg_encode.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/imgutils.h>
#include <libswscale/swscale.h>
}

#include <cstdio>
#include <cstring>
#include <filesystem>

#include "geometry/util/files.h"
#include "geometry/util/output_file.h"
#include "geometry/util/status.h"
#include "render/video/ffmpeg_log.h"

namespace geodrive {
namespace {

// The codec a FourCC names: the container's own tags first, then the AVI and
// MOV tables (as OpenCV's writer looks it up).
AVCodecID CodecForFourcc(const AVOutputFormat* format,
                         const std::string& fourcc) {
  const unsigned tag = MKTAG(fourcc[0], fourcc[1], fourcc[2], fourcc[3]);
  AVCodecID id = AV_CODEC_ID_NONE;
  if (format->codec_tag != nullptr)
    id = av_codec_get_id(format->codec_tag, tag);
  if (id == AV_CODEC_ID_NONE) {
    const AVCodecTag* const tables[] = {avformat_get_riff_video_tags(),
                                        avformat_get_mov_video_tags(), nullptr};
    id = av_codec_get_id(tables, tag);
  }
  return id;
}

// 4:2:0 as OpenCV picks it (full-range for MJPEG), else the encoder's best
// format for RGB input.
AVPixelFormat EncoderPixelFormat(const AVCodec* codec) {
  const AVPixelFormat want =
      codec->id == AV_CODEC_ID_MJPEG ? AV_PIX_FMT_YUVJ420P : AV_PIX_FMT_YUV420P;
  if (codec->pix_fmts == nullptr) return want;
  for (const AVPixelFormat* p = codec->pix_fmts; *p != AV_PIX_FMT_NONE; ++p) {
    if (*p == want) return want;
  }
  return avcodec_find_best_pix_fmt_of_list(codec->pix_fmts, AV_PIX_FMT_RGB24, 0,
                                           nullptr);
}

}  // namespace

struct FfmpegVideoWriter::Impl {
  std::string path, tmp;
  int w = 0, h = 0;  // input frame size
  int64_t frames = 0;
  bool finished = false, io_open = false;
  AVFormatContext* fmt = nullptr;
  AVCodecContext* codec = nullptr;
  AVStream* stream = nullptr;
  AVPacket* packet = nullptr;
  AVFrame* rgb = nullptr;  // aligned, padded copy of the input (SIMD reads)
  SwsContext* sws = nullptr;
  ~Impl() {
    if (sws) sws_freeContext(sws);
    if (rgb) av_frame_free(&rgb);
    if (packet) av_packet_free(&packet);
    if (codec) avcodec_free_context(&codec);
    if (fmt) {
      if (io_open) avio_closep(&fmt->pb);
      avformat_free_context(fmt);
    }
    if (!finished && !tmp.empty()) std::remove(tmp.c_str());
  }
  void Drain();
};

void FfmpegVideoWriter::Impl::Drain() {
  while (true) {
    const int r = avcodec_receive_packet(codec, packet);
    if (r == AVERROR(EAGAIN) || r == AVERROR_EOF) return;
    GEODRIVE_CHECK_INPUT(r >= 0, path, ": encoding failed (",
                         FfmpegErrorDetail(r), ")");
    av_packet_rescale_ts(packet, codec->time_base, stream->time_base);
    packet->stream_index = stream->index;
    const int w = av_interleaved_write_frame(fmt, packet);
    GEODRIVE_CHECK_INPUT(w >= 0, path, ": writing failed (",
                         FfmpegErrorDetail(w), ")");
  }
}

FfmpegVideoWriter::FfmpegVideoWriter(const std::string& path,
                                     int width,
                                     int height,
                                     const std::string& fourcc,
                                     double fps)
    : impl_(std::make_unique<Impl>()) {
  GEODRIVE_CHECK_INPUT(fourcc.size() == 4, path, ": fourcc '", fourcc,
                       "' must have 4 characters");
  GEODRIVE_CHECK_INPUT(
      width > 0 && height > 0 && width <= 16384 && height <= 16384, path,
      ": bad frame size ", width, "x", height);
  GEODRIVE_CHECK_INPUT(fps > 0 && fps <= 1000, path, ": fps ", fps,
                       " must be in (0, 1000]");
  InstallFfmpegLogCapture();
  TakeFfmpegLogMessage();
  Impl& m = *impl_;
  m.path = path;
  CheckReplaceableOutput(path);
  m.tmp =
      TemporaryPathFor(path, std::filesystem::path(path).extension().string());
  m.w = width;
  m.h = height;
  int r =
      avformat_alloc_output_context2(&m.fmt, nullptr, nullptr, m.tmp.c_str());
  GEODRIVE_CHECK_INPUT(r >= 0 && m.fmt, path,
                       ": no video container for this extension (",
                       FfmpegErrorDetail(r), ")");
  const AVCodecID id = CodecForFourcc(m.fmt->oformat, fourcc);
  const AVCodec* codec =
      id == AV_CODEC_ID_NONE ? nullptr : avcodec_find_encoder(id);
  GEODRIVE_CHECK_INPUT(codec != nullptr, path, ": this FFmpeg has no encoder ",
                       "for fourcc '", fourcc, "'");
  m.stream = avformat_new_stream(m.fmt, nullptr);
  m.codec = avcodec_alloc_context3(codec);
  GEODRIVE_CHECK_INPUT(m.stream && m.codec, path, ": out of memory");
  AVCodecContext* c = m.codec;
  c->width = width + (width % 2);
  c->height = height + (height % 2);
  c->pix_fmt = EncoderPixelFormat(codec);
  if (c->pix_fmt == AV_PIX_FMT_YUVJ420P) c->color_range = AVCOL_RANGE_JPEG;
  const AVRational rate = av_d2q(fps, 100000);
  c->time_base = av_inv_q(rate);
  c->framerate = rate;
  c->gop_size = 12;
  c->thread_count = 1;
  c->flags |= AV_CODEC_FLAG_BITEXACT;
  // A fixed quantiser where the encoder has one, else OpenCV's bit rate.
  c->flags |= AV_CODEC_FLAG_QSCALE;
  c->global_quality = 2 * FF_QP2LAMBDA;
  c->bit_rate = static_cast<int64_t>(fps * c->width * c->height);
  if (m.fmt->oformat->flags & AVFMT_GLOBALHEADER)
    c->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
  r = avcodec_open2(c, codec, nullptr);
  GEODRIVE_CHECK_INPUT(r >= 0, path, ": cannot open the '", codec->name,
                       "' encoder (", FfmpegErrorDetail(r), ")");
  r = avcodec_parameters_from_context(m.stream->codecpar, c);
  GEODRIVE_CHECK_INPUT(r >= 0, path, ": codec parameters (",
                       FfmpegErrorDetail(r), ")");
  m.stream->time_base = c->time_base;
  m.stream->avg_frame_rate = rate;
  m.fmt->flags |= AVFMT_FLAG_BITEXACT;
  r = avio_open(&m.fmt->pb, m.tmp.c_str(), AVIO_FLAG_WRITE);
  GEODRIVE_CHECK_INPUT(r >= 0, path, ": cannot open for writing (",
                       FfmpegErrorDetail(r), ")");
  m.io_open = true;
  r = avformat_write_header(m.fmt, nullptr);
  GEODRIVE_CHECK_INPUT(r >= 0, path, ": cannot write the header of a '",
                       codec->name, "' video in this container (",
                       FfmpegErrorDetail(r), ")");
  m.packet = av_packet_alloc();
  m.rgb = av_frame_alloc();
  GEODRIVE_CHECK_INPUT(m.packet && m.rgb, path, ": out of memory");
  m.rgb->format = AV_PIX_FMT_RGB24;
  m.rgb->width = c->width;
  m.rgb->height = c->height;
  GEODRIVE_CHECK_INPUT(av_frame_get_buffer(m.rgb, 32) >= 0, path,
                       ": out of memory");
  // Black padding (odd sizes) and row tails, set once.
  for (int y = 0; y < c->height; ++y)
    std::memset(m.rgb->data[0] + static_cast<size_t>(y) * m.rgb->linesize[0], 0,
                m.rgb->linesize[0]);
  m.sws = sws_getContext(
      c->width, c->height, AV_PIX_FMT_RGB24, c->width, c->height, c->pix_fmt,
      SWS_BICUBIC | SWS_ACCURATE_RND | SWS_BITEXACT, nullptr, nullptr, nullptr);
  GEODRIVE_CHECK_INPUT(m.sws != nullptr, path,
                       ": cannot convert RGB to the encoder's pixel format");
}

FfmpegVideoWriter::~FfmpegVideoWriter() = default;

void FfmpegVideoWriter::Write(const cv::Mat& frame_rgb) {
  Impl& m = *impl_;
  GEODRIVE_CHECK_INPUT(!m.finished, m.path, ": write after finish");
  GEODRIVE_CHECK_INPUT(frame_rgb.type() == CV_8UC3 && frame_rgb.cols == m.w &&
                           frame_rgb.rows == m.h,
                       m.path, ": frame ", m.frames, " is not an RGB ", m.w,
                       "x", m.h, " image");
  for (int y = 0; y < m.h; ++y) {
    std::memcpy(m.rgb->data[0] + static_cast<size_t>(y) * m.rgb->linesize[0],
                frame_rgb.ptr<uint8_t>(y), static_cast<size_t>(m.w) * 3);
  }
  // A fresh, zeroed frame each time (the encoder may keep a reference to the
  // previous one).
  AVFrame* out = av_frame_alloc();
  GEODRIVE_CHECK_INPUT(out != nullptr, m.path, ": out of memory");
  std::unique_ptr<AVFrame, void (*)(AVFrame*)> owned(
      out, [](AVFrame* f) { av_frame_free(&f); });
  out->format = m.codec->pix_fmt;
  out->width = m.codec->width;
  out->height = m.codec->height;
  out->color_range = m.codec->color_range;
  GEODRIVE_CHECK_INPUT(av_frame_get_buffer(out, 32) >= 0, m.path,
                       ": out of memory");
  for (int p = 0; p < 4 && out->buf[p] != nullptr; ++p)
    std::memset(out->buf[p]->data, 0, out->buf[p]->size);
  sws_scale(m.sws, m.rgb->data, m.rgb->linesize, 0, m.codec->height, out->data,
            out->linesize);
  out->pts = m.frames;
  const int r = avcodec_send_frame(m.codec, out);
  GEODRIVE_CHECK_INPUT(r >= 0, m.path, ": encoding frame ", m.frames,
                       " failed (", FfmpegErrorDetail(r), ")");
  m.Drain();
  ++m.frames;
}

void FfmpegVideoWriter::Finish() {
  Impl& m = *impl_;
  GEODRIVE_CHECK_INPUT(!m.finished, m.path, ": finished twice");
  GEODRIVE_CHECK_INPUT(m.frames > 0, m.path, ": no frames to write");
  avcodec_send_frame(m.codec, nullptr);
  m.Drain();
  const int r = av_write_trailer(m.fmt);
  GEODRIVE_CHECK_INPUT(r >= 0, m.path, ": cannot finish the video (",
                       FfmpegErrorDetail(r), ")");
  avio_closep(&m.fmt->pb);
  m.io_open = false;
  CommitTemporaryFile(m.tmp, m.path);
  m.finished = true;
}

}  // namespace geodrive

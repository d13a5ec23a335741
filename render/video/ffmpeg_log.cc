#include "render/video/ffmpeg_log.h"

extern "C" {
#include <libavutil/error.h>
#include <libavutil/log.h>
}

#include <cstdarg>
#include <cstdio>
#include <mutex>

namespace geodrive {
namespace {

thread_local std::string last_message;

void Capture(void* avcl, int level, const char* fmt, va_list args) {
  if (level > AV_LOG_ERROR) return;
  char line[512];
  int print_prefix = 0;  // no "[h264 @ 0x...]": addresses vary run to run
  av_log_format_line2(avcl, level, fmt, args, line, sizeof(line),
                      &print_prefix);
  std::string s = line;
  const AVClass* cls =
      avcl ? *static_cast<const AVClass* const*>(avcl) : nullptr;
  if (cls != nullptr && cls->item_name != nullptr)
    s = std::string(cls->item_name(avcl)) + ": " + s;
  for (char& c : s) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  while (!s.empty() && s.back() == ' ') s.pop_back();
  if (s.size() > 200) s.resize(200);
  if (!s.empty()) last_message = s;
}

}  // namespace

void InstallFfmpegLogCapture() {
  static std::once_flag once;
  std::call_once(once, [] { av_log_set_callback(Capture); });
}

std::string TakeFfmpegLogMessage() {
  std::string s;
  s.swap(last_message);
  return s;
}

std::string FfmpegError(int code) {
  char buf[AV_ERROR_MAX_STRING_SIZE] = {0};
  av_strerror(code, buf, sizeof(buf));
  return buf;
}

std::string FfmpegErrorDetail(int code) {
  std::string s = FfmpegError(code);
  const std::string logged = TakeFfmpegLogMessage();
  if (!logged.empty()) s += "; " + logged;
  return s;
}

}  // namespace geodrive

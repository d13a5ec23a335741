#pragma once
// FFmpeg's log, captured instead of printed: a reader or writer failure is one
// InputError naming the file, and the libraries print nothing (as the image
// codecs, docs/RELIABILITY.md). The last error-level message of the calling
// thread is kept so that the error can quote it.

#include <string>

namespace geodrive {

// Installs the capturing av_log callback (once per process; idempotent).
void InstallFfmpegLogCapture();
// The last error-level FFmpeg message logged on this thread since the previous
// call (one line, at most 200 characters), or "" -- and forgets it.
std::string TakeFfmpegLogMessage();
// An FFmpeg error code in words (av_strerror).
std::string FfmpegError(int code);
// FfmpegError(code) followed by the library's own last message when it logged
// one (e.g. "Invalid data found when processing input; error while decoding
// MB 3 4"); takes that message (TakeFfmpegLogMessage).
std::string FfmpegErrorDetail(int code);

}  // namespace geodrive

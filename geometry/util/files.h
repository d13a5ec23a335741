#pragma once
// File helpers shared by every module: reading whole files with a size cap,
// atomic writes (temporary file in the same folder, fsync, rename: the one
// implementation the toolkit uses), atomic folder commits, append-only
// JSON-lines logs. Every failure throws InputError naming the file.

#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

namespace geodrive {

// "<path>: cannot open (No such file or directory)" style error from the
// current errno.
[[noreturn]] void ThrowOpenError(const std::string& path, int errno_value);

// Size of a regular file in bytes; throws "cannot open (...)" if it does not
// exist or is not a regular file.
uint64_t FileSizeOrThrow(const std::string& path);

// Reads a whole file. Throws if it cannot be opened or is larger than
// `max_bytes`.
std::vector<uint8_t> ReadFileBytes(const std::string& path,
                                   uint64_t max_bytes = 1ull << 34);
std::string ReadFileText(const std::string& path,
                         uint64_t max_bytes = 1ull << 32);

// A unique temporary path next to `path` (same directory, so rename() is
// atomic); it ends with `keep_suffix` so that extension-sniffing writers (PCL,
// OpenCV) still work.
std::string TemporaryPathFor(const std::string& path,
                             const std::string& keep_suffix = "");

// Writes `bytes` to `path` atomically: a temporary file in the same
// directory, fsync, then rename(), so readers never see a partial file.
// Throws InputError naming the path on failure (the temporary is removed).
void WriteFileAtomic(const std::string& path, const void* bytes, size_t size);
inline void WriteFileAtomic(const std::string& path,
                            const std::string& content) {
  WriteFileAtomic(path, content.data(), content.size());
}

// The commit step of every atomic write: fsyncs the finished temporary file
// `tmp` (written by a library that wants a path: FFmpeg, OpenCV, PCL, a
// stream) and renames it to `path`; removes it and throws naming `path` on
// failure. WriteFileAtomic and WriteViaTemporary end with it.
void CommitTemporaryFile(const std::string& tmp, const std::string& path);

// Creates `dir` (and its parents) if needed and checks that a file can be
// created in it, so that a command finds an unusable output folder before it
// computes anything. Throws InputError "<dir>: cannot create the output
// folder (...)" or "<dir>: output folder is not writable (...)".
void CreateOutputDirectory(const std::string& dir);

// Renames a completed temporary folder to its final name (atomic on one
// filesystem) after fsync-ing its files. Throws InputError if `final_dir`
// already exists or the rename fails.
void CommitDirectory(const std::string& tmp_dir, const std::string& final_dir);

// An exclusive advisory lock (flock) on `path`, held while the object lives
// and released by the kernel when the process dies (kill -9 included). The
// file holds the holder's pid. Throws InputError naming the holder when
// another process holds it.
class ExclusiveLock {
 public:
  // `what` names the thing locked in the error ("output folder OUT").
  ExclusiveLock(const std::string& path, const std::string& what);
  ~ExclusiveLock();
  ExclusiveLock(const ExclusiveLock&) = delete;
  ExclusiveLock& operator=(const ExclusiveLock&) = delete;

 private:
  int fd_ = -1;
};

// Appends lines to a JSON-lines file; each Append writes one whole line,
// flushes and fsyncs (thread-safe within a process).
class JsonlAppender {
 public:
  explicit JsonlAppender(const std::string& path);
  ~JsonlAppender();
  JsonlAppender(const JsonlAppender&) = delete;
  JsonlAppender& operator=(const JsonlAppender&) = delete;
  void Append(const std::string& line);

 private:
  std::string path_;
  int fd_ = -1;
  std::mutex mutex_;
};

// Runs `write_to(temporary_path)` (which returns false or throws on failure)
// and commits the temporary file to `path` (CommitTemporaryFile); removes it
// on failure.
void WriteViaTemporary(const std::string& path,
                       const std::string& keep_suffix,
                       const std::function<bool(const std::string&)>& write_to);

// Lower-cased file name of `path` (no directories), for extension dispatch.
std::string LowerFileName(const std::string& path);
bool EndsWith(const std::string& text, const std::string& suffix);

}  // namespace geodrive

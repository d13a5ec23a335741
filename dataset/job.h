#pragma once
// Building blocks for long batch jobs: atomic files and folders, append-only
// JSON-lines logs, progress reporting (bar on a terminal, periodic lines
// otherwise), and clean stop on SIGINT / SIGTERM.

#include <chrono>
#include <cstdio>
#include <memory>
#include <mutex>
#include <string>

namespace geodrive {

// Writes `content` to `path` through a temporary file in the same folder, fsync
// and rename, so readers never see a partial file. Throws InputError naming the
// path on failure.
void WriteFileAtomic(const std::string& path, const std::string& content);

// Renames a completed temporary folder to its final name (atomic on one
// filesystem) after fsync-ing its files. Throws InputError if `final_dir`
// already exists or the rename fails.
void CommitDirectory(const std::string& tmp_dir, const std::string& final_dir);

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

// Progress of `total` items: a bar with rate and ETA when stderr is a terminal,
// else one plain line every `interval_s` seconds (and at the end). Thread-safe.
class ProgressReporter {
 public:
  ProgressReporter(const std::string& label,
                   size_t total,
                   double interval_s = 10.0,
                   bool quiet = false);
  void Advance(size_t n = 1, const std::string& note = "");
  void Finish();

 private:
  void Print(bool final);
  std::string label_;
  size_t total_, done_ = 0;
  double interval_s_;
  bool quiet_, tty_;
  std::chrono::steady_clock::time_point start_, last_print_;
  std::string note_;
  std::mutex mutex_;
};

// Installs SIGINT/SIGTERM handlers that set a flag (the first signal asks for a
// clean stop after the current items; a second one exits immediately with code
// 130).
void InstallStopSignalHandlers();
bool StopRequested();
// For tests: request/reset a stop without a signal.
void SetStopRequested(bool value);

}  // namespace geodrive

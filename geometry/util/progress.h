#pragma once
// Progress of long batch jobs (a bar on a terminal, periodic lines otherwise)
// and clean stop on SIGINT / SIGTERM.

#include <chrono>
#include <cstddef>
#include <mutex>
#include <string>

namespace geodrive {

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

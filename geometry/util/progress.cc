#include "geometry/util/progress.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <sstream>

#include "geometry/util/output_file.h"
#include "geometry/util/status.h"

namespace geodrive {

namespace fs = std::filesystem;

ProgressReporter::ProgressReporter(const std::string& label,
                                   size_t total,
                                   double interval_s,
                                   bool quiet)
    : label_(label),
      total_(total),
      interval_s_(interval_s),
      quiet_(quiet),
      tty_(::isatty(STDERR_FILENO) != 0) {
  start_ = last_print_ = std::chrono::steady_clock::now();
}

void ProgressReporter::Advance(size_t n, const std::string& note) {
  std::lock_guard<std::mutex> lock(mutex_);
  done_ += n;
  if (!note.empty()) note_ = note;
  const auto now = std::chrono::steady_clock::now();
  const double since = std::chrono::duration<double>(now - last_print_).count();
  if (tty_ ? since >= 0.1 : since >= interval_s_) {
    last_print_ = now;
    Print(false);
  }
}

void ProgressReporter::Finish() {
  std::lock_guard<std::mutex> lock(mutex_);
  Print(true);
}

void ProgressReporter::Print(bool final) {
  if (quiet_) return;
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_)
          .count();
  const double rate = elapsed > 0 ? done_ / elapsed : 0.0;
  const double eta = rate > 0 && total_ > done_ ? (total_ - done_) / rate : 0.0;
  std::ostringstream os;
  char buf[160];
  if (tty_) {
    const int width = 30;
    const int filled =
        total_ ? static_cast<int>(width * done_ / total_) : width;
    os << "\r" << label_ << " [" << std::string(filled, '#')
       << std::string(width - filled, '.') << "] ";
  } else {
    os << label_ << ": ";
  }
  std::snprintf(buf, sizeof(buf), "%zu/%zu  %.2f/s  elapsed %.0fs  ETA %.0fs",
                done_, total_, rate, elapsed, eta);
  os << buf;
  if (!note_.empty()) os << "  " << note_;
  if (tty_) {
    os << "\033[K";
    if (final) os << "\n";
  } else {
    os << "\n";
  }
  std::cerr << os.str() << std::flush;
}

namespace {
std::atomic<int> g_stop_signals{0};
void OnStopSignal(int) {
  if (g_stop_signals.fetch_add(1) >= 1) {
    RemoveRegisteredTemporaries();
    _exit(130);
  }
  const char msg[] =
      "\ngeodrive: stop requested; finishing current items (signal again to "
      "abort)\n";
  const ssize_t ignored = ::write(STDERR_FILENO, msg, sizeof(msg) - 1);
  (void)ignored;
}
}  // namespace

void InstallStopSignalHandlers() {
  struct sigaction sa;
  std::memset(&sa, 0, sizeof(sa));
  sa.sa_handler = OnStopSignal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  ::signal(SIGXFSZ, SIG_IGN);  // a file-size limit is a write error
}

bool StopRequested() { return g_stop_signals.load() > 0; }
void SetStopRequested(bool value) { g_stop_signals.store(value ? 1 : 0); }

}  // namespace geodrive

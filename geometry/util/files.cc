#include "geometry/util/files.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>

#include "geometry/util/input_file.h"
#include "geometry/util/status.h"

namespace geodrive {

namespace fs = std::filesystem;
void ThrowOpenError(const std::string& path, int errno_value) {
  ThrowInputError(path, "cannot open (", std::strerror(errno_value), ")");
}

uint64_t FileSizeOrThrow(const std::string& path) {
  return CheckInputFile(path);
}

std::vector<uint8_t> ReadFileBytes(const std::string& path,
                                   uint64_t max_bytes) {
  return ReadInputFileBytes(path, max_bytes);
}

std::string ReadFileText(const std::string& path, uint64_t max_bytes) {
  const std::vector<uint8_t> bytes = ReadFileBytes(path, max_bytes);
  return std::string(bytes.begin(), bytes.end());
}

std::string TemporaryPathFor(const std::string& path,
                             const std::string& keep_suffix) {
  static std::atomic<uint64_t> counter{0};
  const std::filesystem::path p(path);
  const std::string name = "." + p.filename().string() + ".tmp" +
                           std::to_string(::getpid()) + "_" +
                           std::to_string(counter++) + keep_suffix;
  return (p.parent_path() / name).string();
}

void WriteViaTemporary(
    const std::string& path,
    const std::string& keep_suffix,
    const std::function<bool(const std::string&)>& write_to) {
  const std::string tmp = TemporaryPathFor(path, keep_suffix);
  bool ok = false;
  try {
    ok = write_to(tmp);
  } catch (...) {
    std::remove(tmp.c_str());
    throw;
  }
  if (!ok) {
    std::remove(tmp.c_str());
    ThrowInputError(path, "cannot write");
  }
  CommitTemporaryFile(tmp, path);
}

std::string LowerFileName(const std::string& path) {
  std::string name = std::filesystem::path(path).filename().string();
  std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) {
    return static_cast<char>(std::tolower(c));
  });
  return name;
}

bool EndsWith(const std::string& text, const std::string& suffix) {
  return text.size() >= suffix.size() &&
         text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

namespace {
void FsyncPath(const std::string& path, bool directory) {
  const int fd =
      ::open(path.c_str(), directory ? O_RDONLY | O_DIRECTORY : O_RDONLY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}
}  // namespace

namespace {
// rename(tmp, path); on failure removes tmp and throws naming `path`.
void RenameIntoPlace(const std::string& tmp, const std::string& path) {
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    ThrowInputError(path, "rename failed (", std::strerror(err), ")");
  }
}
}  // namespace

void CreateOutputDirectory(const std::string& dir) {
  GEODRIVE_CHECK_INPUT(!dir.empty(), "the output folder is an empty path");
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    ThrowInputError(dir, "cannot create the output folder (", ec.message(),
                    ")");
  }
  GEODRIVE_CHECK_INPUT(std::filesystem::is_directory(dir, ec), dir,
                       ": exists and is not a folder");
  std::string probe =
      (std::filesystem::path(dir) / ".geodrive-probe-XXXXXX").string();
  const int fd = ::mkstemp(&probe[0]);
  if (fd < 0) {
    ThrowInputError(dir, "output folder is not writable (",
                    std::strerror(errno), ")");
  }
  ::close(fd);
  ::unlink(probe.c_str());
}

void WriteFileAtomic(const std::string& path, const void* bytes, size_t size) {
  const std::string tmp = TemporaryPathFor(path);
  const char* data = static_cast<const char*>(bytes);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  GEODRIVE_CHECK_INPUT(fd >= 0, path, ": cannot write (", std::strerror(errno),
                       ")");
  size_t off = 0;
  while (off < size) {
    const ssize_t n = ::write(fd, data + off, size - off);
    if (n < 0) {
      const int err = errno;
      ::close(fd);
      ::unlink(tmp.c_str());
      ThrowInputError(path, "write failed (", std::strerror(err), ")");
    }
    off += static_cast<size_t>(n);
  }
  const bool synced = ::fsync(fd) == 0 || errno == EINVAL;  // EINVAL: pipes
  const int sync_err = errno;
  if (::close(fd) != 0 || !synced) {
    const int err = synced ? errno : sync_err;
    ::unlink(tmp.c_str());
    ThrowInputError(path, "write failed (", std::strerror(err), ")");
  }
  RenameIntoPlace(tmp, path);
}

void CommitTemporaryFile(const std::string& tmp, const std::string& path) {
  const int fd = ::open(tmp.c_str(), O_RDONLY);
  if (fd < 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    ThrowInputError(path, "cannot write (", std::strerror(err), ")");
  }
  const bool synced = ::fsync(fd) == 0 || errno == EINVAL;
  const int sync_err = errno;
  ::close(fd);
  if (!synced) {
    ::unlink(tmp.c_str());
    ThrowInputError(path, "write failed (", std::strerror(sync_err), ")");
  }
  RenameIntoPlace(tmp, path);
}

void CommitDirectory(const std::string& tmp_dir, const std::string& final_dir) {
  GEODRIVE_CHECK_INPUT(!fs::exists(final_dir), final_dir, ": already exists");
  for (const auto& entry : fs::directory_iterator(tmp_dir)) {
    if (entry.is_regular_file()) FsyncPath(entry.path().string(), false);
  }
  FsyncPath(tmp_dir, true);
  GEODRIVE_CHECK_INPUT(::rename(tmp_dir.c_str(), final_dir.c_str()) == 0,
                       final_dir, ": rename from ", tmp_dir, " failed (",
                       std::strerror(errno), ")");
  FsyncPath(fs::path(final_dir).parent_path().string(), true);
}

ExclusiveLock::ExclusiveLock(const std::string& path, const std::string& what) {
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  GEODRIVE_CHECK_INPUT(fd_ >= 0, path, ": cannot create lock file (",
                       std::strerror(errno), ")");
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    char buf[32] = {0};
    const ssize_t n = ::pread(fd_, buf, sizeof(buf) - 1, 0);
    ::close(fd_);
    fd_ = -1;
    std::string holder = n > 0 ? std::string(buf, static_cast<size_t>(n)) : "";
    while (!holder.empty() && (holder.back() == '\n' || holder.back() == ' '))
      holder.pop_back();
    ThrowInputError(what, "another process",
                    holder.empty() ? std::string() : " (pid " + holder + ")",
                    " is writing it (lock ", path,
                    "); wait for it to finish or use another folder");
  }
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd_, 0) == 0) {
    const ssize_t n = ::pwrite(fd_, pid.data(), pid.size(), 0);
    (void)n;  // the pid is informative; the lock itself is the flock
  }
}

ExclusiveLock::~ExclusiveLock() {
  if (fd_ >= 0) ::close(fd_);  // releases the flock
}

JsonlAppender::JsonlAppender(const std::string& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  GEODRIVE_CHECK_INPUT(fd_ >= 0, path, ": cannot open for appending (",
                       std::strerror(errno), ")");
}

JsonlAppender::~JsonlAppender() {
  if (fd_ >= 0) ::close(fd_);
}

void JsonlAppender::Append(const std::string& line) {
  std::lock_guard<std::mutex> lock(mutex_);
  const std::string text = line + "\n";
  // O_APPEND + one write per line keeps lines whole even with several processes
  // appending.
  const ssize_t n = ::write(fd_, text.data(), text.size());
  GEODRIVE_CHECK_INPUT(n == static_cast<ssize_t>(text.size()), path_,
                       ": append failed (", std::strerror(errno), ")");
  ::fsync(fd_);
}

}  // namespace geodrive

#include "geometry/util/files.h"

#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>

#include "geometry/util/input_file.h"
#include "geometry/util/output_file.h"
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
  const std::string tmp = (p.parent_path() / name).string();
  RegisterTemporaryPath(tmp);
  return tmp;
}

void WriteViaTemporary(
    const std::string& path,
    const std::string& keep_suffix,
    const std::function<bool(const std::string&)>& write_to) {
  CheckReplaceableOutput(path);
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
// rename(tmp, path); on failure (or when `path` is not a regular file)
// removes tmp and throws naming `path`.
void RenameIntoPlace(const std::string& tmp, const std::string& path) {
  try {
    CheckReplaceableOutput(path);
  } catch (...) {
    ::unlink(tmp.c_str());
    throw;
  }
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
  CheckReplaceableOutput(path);
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

void CheckReplaceableOutput(const std::string& path) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0 || S_ISREG(st.st_mode)) return;
  const char* kind = S_ISDIR(st.st_mode)    ? "a folder"
                     : S_ISCHR(st.st_mode)  ? "a character device"
                     : S_ISBLK(st.st_mode)  ? "a block device"
                     : S_ISFIFO(st.st_mode) ? "a FIFO"
                     : S_ISSOCK(st.st_mode) ? "a socket"
                                            : "not a file";
  ThrowInputError(path, "exists and is not a regular file (", kind,
                  "): refusing to replace it; write to a file path");
}

namespace {

// The registered temporaries: a ring of fixed buffers, so that a signal
// handler can read them without allocating. state: 0 empty, 1 being written,
// 2 ready.
constexpr int kTemporarySlots = 256;
constexpr size_t kTemporaryPathMax = 4096;
struct TemporarySlot {
  std::atomic<int> state{0};
  std::atomic<int64_t> registered_ms{0};
  char path[kTemporaryPathMax];
};
TemporarySlot g_temporaries[kTemporarySlots];
std::atomic<unsigned> g_next_temporary{0};

// Removes `name` (relative to `dirfd`) and, for a folder, its contents, with
// system calls only (async-signal-safe). `depth` bounds the recursion.
void RemoveTreeAt(int dirfd, const char* name, int depth) {
  if (::unlinkat(dirfd, name, 0) == 0 || errno == ENOENT) return;
  if (depth <= 0) return;
  const int fd =
      ::openat(dirfd, name, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) return;
  alignas(8) char buf[4096];
  for (;;) {
    const long n = ::syscall(SYS_getdents64, fd, buf, sizeof(buf));
    if (n <= 0) break;
    for (long off = 0; off < n;) {
      // struct linux_dirent64: ino (8), off (8), reclen (2), type (1), name.
      unsigned short reclen;
      std::memcpy(&reclen, buf + off + 16, sizeof(reclen));
      const char* entry = buf + off + 19;
      if (!(entry[0] == '.' &&
            (entry[1] == 0 || (entry[1] == '.' && entry[2] == 0)))) {
        RemoveTreeAt(fd, entry, depth - 1);
      }
      off += reclen;
    }
  }
  ::close(fd);
  ::unlinkat(dirfd, name, AT_REMOVEDIR);
}

void OnInterruptSignal(int) {
  RemoveRegisteredTemporaries();
  _exit(130);
}

}  // namespace

void RegisterTemporaryPath(const std::string& path) {
  if (path.empty() || path.size() >= kTemporaryPathMax) return;
  const int64_t now_ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(
          std::chrono::steady_clock::now().time_since_epoch())
          .count();
  // A free slot, or one whose temporary is gone (committed or removed; older
  // than a second, so that it is not one about to be created); else the next.
  const unsigned start = g_next_temporary.fetch_add(1);
  for (int k = 0; k <= kTemporarySlots; ++k) {
    TemporarySlot& slot = g_temporaries[(start + k) % kTemporarySlots];
    int state = slot.state.load();
    const bool last_try = k == kTemporarySlots;
    const bool reusable =
        state == 0 ||
        (state == 2 && now_ms - slot.registered_ms.load() > 1000 &&
         ::access(slot.path, F_OK) != 0);
    if (state == 1 || !(reusable || last_try) ||
        !slot.state.compare_exchange_strong(state, 1)) {
      continue;
    }
    std::memcpy(slot.path, path.c_str(), path.size() + 1);
    slot.registered_ms.store(now_ms);
    slot.state.store(2);
    return;
  }
}

void RemoveRegisteredTemporaries() {
  for (TemporarySlot& slot : g_temporaries) {
    if (slot.state.load() == 2) RemoveTreeAt(AT_FDCWD, slot.path, 16);
  }
}

void InstallInterruptHandlers() {
  struct sigaction sa;
  std::memset(&sa, 0, sizeof(sa));
  sa.sa_handler = OnInterruptSignal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  ::signal(SIGXFSZ, SIG_IGN);
}

namespace {
// The lock file's holder as written by OutputFolderLock: "pid N" or a word.
std::string LockHolder(int fd) {
  char buf[32] = {0};
  const ssize_t n = ::pread(fd, buf, sizeof(buf) - 1, 0);
  std::string holder = n > 0 ? std::string(buf, static_cast<size_t>(n)) : "";
  while (!holder.empty() && (holder.back() == '\n' || holder.back() == ' '))
    holder.pop_back();
  if (holder.empty()) return "";
  const bool digits =
      holder.find_first_not_of("0123456789") == std::string::npos;
  return " (" + (digits ? "pid " + holder : holder) + ")";
}
}  // namespace

OutputFolderLock::OutputFolderLock(const std::string& path,
                                   const std::string& what,
                                   Mode mode) {
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  GEODRIVE_CHECK_INPUT(fd_ >= 0, path, ": cannot create lock file (",
                       std::strerror(errno), ")");
  const bool exclusive = mode == Mode::kExclusive;
  if (::flock(fd_, (exclusive ? LOCK_EX : LOCK_SH) | LOCK_NB) != 0) {
    const std::string holder = LockHolder(fd_);
    ::close(fd_);
    fd_ = -1;
    ThrowInputError(what, "another process", holder, " is writing it (lock ",
                    path, "); wait for it to finish or use another folder");
  }
  // The holder, for the error of the next one: a pid, or the shard runs
  // (several shared holders write the same text).
  const std::string text =
      exclusive ? std::to_string(::getpid()) + "\n" : "shard runs\n";
  if (::ftruncate(fd_, 0) == 0) {
    const ssize_t n = ::pwrite(fd_, text.data(), text.size(), 0);
    (void)n;  // informative; the lock itself is the flock
  }
}

OutputFolderLock::~OutputFolderLock() {
  if (fd_ >= 0) ::close(fd_);  // releases the flock
}

bool LockFileIsHeld(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool held = ::flock(fd, LOCK_EX | LOCK_NB) != 0;
  ::close(fd);  // releases the probe's lock, if it got one
  return held;
}

void CheckOutputIsNotInput(const std::string& out,
                           const std::vector<std::string>& inputs) {
  std::error_code ec;
  const fs::path target = fs::weakly_canonical(fs::absolute(out, ec), ec);
  for (const std::string& input : inputs) {
    if (input.empty()) continue;
    std::error_code e2;
    if (!fs::exists(input, e2)) continue;
    const fs::path in = fs::weakly_canonical(fs::absolute(input, e2), e2);
    if (fs::exists(out, e2) && fs::equivalent(out, input, e2)) {
      ThrowInputError(out, "is the input ", input,
                      ": the command would overwrite what it reads; write "
                      "it elsewhere");
    }
    if (!fs::is_directory(input, e2)) continue;
    for (fs::path p = target.parent_path(); !p.empty(); p = p.parent_path()) {
      if (p == in || fs::equivalent(p, in, e2)) {
        ThrowInputError(out, "is inside the input folder ", input,
                        " (it would overwrite or mix with its files): write "
                        "it elsewhere");
      }
      if (p == p.root_path()) break;
    }
  }
}

}  // namespace geodrive

#include "geometry/util/input_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ext/stdio_filebuf.h>
#include <utility>

#include "geometry/util/status.h"

namespace geodrive {

namespace {

// What a non-regular file is, as the error message says it.
const char* KindOf(mode_t mode) {
  if (S_ISDIR(mode)) return "is a directory (expected a file)";
  if (S_ISFIFO(mode)) return "is a FIFO/pipe, not a regular file";
  if (S_ISCHR(mode)) return "is a character device, not a regular file";
  if (S_ISBLK(mode)) return "is a block device, not a regular file";
  if (S_ISSOCK(mode)) return "is a socket, not a regular file";
  return "is not a regular file";
}

[[noreturn]] void ThrowCannotOpen(const std::string& path, int err) {
  // open() of a socket fails (ENXIO); say what the path is instead.
  struct stat st;
  if (err == ENXIO && ::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
    ThrowInputError(path, KindOf(st.st_mode));
  ThrowInputError(path, "cannot open (", std::strerror(err), ")");
}

}  // namespace

InputFile::~InputFile() {
  if (fd_ >= 0) ::close(fd_);
}

InputFile::InputFile(InputFile&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)),
      size_(other.size_),
      path_(std::move(other.path_)) {}

InputFile& InputFile::operator=(InputFile&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    size_ = other.size_;
    path_ = std::move(other.path_);
  }
  return *this;
}

int InputFile::Release() { return std::exchange(fd_, -1); }

InputFile OpenInputFile(const std::string& path) {
  // O_NONBLOCK: opening a FIFO without a writer returns at once instead of
  // waiting for one; O_NOCTTY: a terminal never becomes ours.
  const int fd =
      ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
  if (fd < 0) ThrowCannotOpen(path, errno);
  InputFile file;
  file.fd_ = fd;
  file.path_ = path;
  struct stat st;
  if (::fstat(fd, &st) != 0) ThrowCannotOpen(path, errno);
  if (!S_ISREG(st.st_mode)) ThrowInputError(path, KindOf(st.st_mode));
  // Regular files never block; clear the flag so reads behave as usual.
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
  file.size_ = static_cast<uint64_t>(st.st_size);
  return file;
}

std::vector<uint8_t> InputFile::ReadAll(uint64_t max_bytes) {
  if (size_ > max_bytes) {
    ThrowInputError(path_, "file of ", size_, " bytes exceeds the limit of ",
                    max_bytes, " bytes");
  }
  std::vector<uint8_t> bytes(size_);
  uint64_t done = 0;
  while (done < size_) {
    const ssize_t n = ::pread(fd_, bytes.data() + done, size_ - done,
                              static_cast<off_t>(done));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0)
      ThrowInputError(path_, "read error (", std::strerror(errno), ")");
    if (n == 0)
      ThrowInputError(path_, "read error (file changed while reading?)");
    done += static_cast<uint64_t>(n);
  }
  return bytes;
}

uint64_t CheckInputFile(const std::string& path) {
  return OpenInputFile(path).size();
}

std::vector<uint8_t> ReadInputFileBytes(const std::string& path,
                                        uint64_t max_bytes) {
  return OpenInputFile(path).ReadAll(max_bytes);
}

std::string ReadInputFileText(const std::string& path, uint64_t max_bytes) {
  const std::vector<uint8_t> bytes = ReadInputFileBytes(path, max_bytes);
  return std::string(bytes.begin(), bytes.end());
}

InputFileStream::InputFileStream(const std::string& path, size_t buffer_bytes)
    : std::istream(nullptr) {
  InputFile file = OpenInputFile(path);
  size_ = file.size();
  // The filebuf owns the descriptor from here on and closes it.
  buf_ = std::make_unique<__gnu_cxx::stdio_filebuf<char>>(
      file.fd(), std::ios::in | std::ios::binary, buffer_bytes);
  file.Release();
  rdbuf(buf_.get());
}

InputFileStream::~InputFileStream() { rdbuf(nullptr); }

}  // namespace geodrive

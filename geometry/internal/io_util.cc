#include "geometry/internal/io_util.h"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>

#include "geometry/status.h"

namespace geodrive {
namespace internal {
namespace {

struct FileCloser {
  void operator()(std::FILE* f) const {
    if (f) std::fclose(f);
  }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

}  // namespace

void ThrowOpenError(const std::string& path, int errno_value) {
  ThrowInputError(path, "cannot open (", std::strerror(errno_value), ")");
}

uint64_t FileSizeOrThrow(const std::string& path) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) ThrowOpenError(path, errno);
  if (S_ISDIR(st.st_mode))
    ThrowInputError(path, "is a directory (expected a file)");
  if (!S_ISREG(st.st_mode)) ThrowInputError(path, "not a regular file");
  return static_cast<uint64_t>(st.st_size);
}

std::vector<uint8_t> ReadFileBytes(const std::string& path,
                                   uint64_t max_bytes) {
  const uint64_t size = FileSizeOrThrow(path);
  if (size > max_bytes) {
    ThrowInputError(path, "file of ", size, " bytes exceeds the limit of ",
                    max_bytes, " bytes");
  }
  FilePtr file(std::fopen(path.c_str(), "rb"));
  if (!file) ThrowOpenError(path, errno);
  std::vector<uint8_t> bytes(size);
  if (size > 0 && std::fread(bytes.data(), 1, size, file.get()) != size) {
    ThrowInputError(path, "read error (file changed while reading?)");
  }
  return bytes;
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
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    std::remove(tmp.c_str());
    ThrowInputError(path, "cannot write (", std::strerror(err), ")");
  }
}

void WriteFileAtomically(const std::string& path,
                         const void* bytes,
                         size_t size) {
  const std::string tmp = TemporaryPathFor(path);
  FilePtr file(std::fopen(tmp.c_str(), "wb"));
  if (!file) ThrowInputError(path, "cannot write (", std::strerror(errno), ")");
  bool ok = size == 0 || std::fwrite(bytes, 1, size, file.get()) == size;
  ok = std::fflush(file.get()) == 0 && ok;
  const int err = errno;
  ok = std::fclose(file.release()) == 0 && ok;
  if (!ok) {
    std::remove(tmp.c_str());
    ThrowInputError(path, "cannot write (", std::strerror(err ? err : EIO),
                    ")");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int rename_err = errno;
    std::remove(tmp.c_str());
    ThrowInputError(path, "cannot write (", std::strerror(rename_err), ")");
  }
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

}  // namespace internal
}  // namespace geodrive

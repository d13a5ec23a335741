#pragma once
// Small file helpers shared by the geometry I/O code (not installed; internal
// to geodrive_geometry). Every failure throws InputError naming the file.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace geodrive {
namespace internal {

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

// Writes `bytes` to `path` atomically: a temporary file in the same directory,
// then rename().
void WriteFileAtomically(const std::string& path,
                         const void* bytes,
                         size_t size);
inline void WriteFileAtomically(const std::string& path,
                                const std::string& text) {
  WriteFileAtomically(path, text.data(), text.size());
}

// Runs `write_to(temporary_path)` (which returns false or throws on failure)
// and renames the temporary file to `path`; removes the temporary file on
// failure.
void WriteViaTemporary(const std::string& path,
                       const std::string& keep_suffix,
                       const std::function<bool(const std::string&)>& write_to);

// Lower-cased file name of `path` (no directories), for extension dispatch.
std::string LowerFileName(const std::string& path);
bool EndsWith(const std::string& text, const std::string& suffix);

}  // namespace internal
}  // namespace geodrive

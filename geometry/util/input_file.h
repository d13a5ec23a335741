#pragma once
// The one way the toolkit opens a user-given path for reading. Every reader
// (trajectories, tables, configs, arrays, images, point clouds, weights) goes
// through OpenInputFile or one of the forms below, so that a path that is not
// a regular file -- a folder, a FIFO, a character device such as /dev/zero, a
// socket -- is refused with one InputError naming the path and what it is,
// instead of blocking forever (a FIFO without a writer), reading until memory
// runs out (/dev/zero) or failing deep inside a parser (a folder).
//
// How: open(O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC), so that opening a
// FIFO returns at once; fstat the open descriptor (the checked object is the
// one read, whatever the path points to later); refuse anything but S_ISREG;
// then clear O_NONBLOCK so reads behave as usual.

#include <cstdint>
#include <istream>
#include <memory>
#include <streambuf>
#include <string>
#include <vector>

namespace geodrive {

// An open read-only descriptor of a regular file (closed when destroyed).
class InputFile {
 public:
  InputFile() = default;
  ~InputFile();
  InputFile(InputFile&& other) noexcept;
  InputFile& operator=(InputFile&& other) noexcept;
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;

  int fd() const { return fd_; }
  // Size in bytes when opened (fstat).
  uint64_t size() const { return size_; }
  const std::string& path() const { return path_; }
  // Hands the descriptor to the caller, who closes it.
  int Release();

  // Reads the whole file (exactly size() bytes from the start); throws
  // InputError naming the path if it is larger than `max_bytes` or a read
  // fails.
  std::vector<uint8_t> ReadAll(uint64_t max_bytes);

 private:
  friend InputFile OpenInputFile(const std::string& path);
  int fd_ = -1;
  uint64_t size_ = 0;
  std::string path_;
};

// Opens `path` (symbolic links followed) for reading. Throws InputError
// "<path>: cannot open (No such file or directory)", "<path>: is a directory
// (expected a file)", "<path>: is a FIFO/pipe, not a regular file",
// "<path>: is a character device, not a regular file", "<path>: is a block
// device, ...", "<path>: is a socket, ...". Never blocks.
InputFile OpenInputFile(const std::string& path);

// For libraries that open the path themselves (FFmpeg, libzip, OpenEXR,
// OpenCV): checks that `path` is a regular file as OpenInputFile does and
// returns its size.
uint64_t CheckInputFile(const std::string& path);

// Whole-file forms: OpenInputFile + ReadAll.
std::vector<uint8_t> ReadInputFileBytes(const std::string& path,
                                        uint64_t max_bytes);
std::string ReadInputFileText(const std::string& path, uint64_t max_bytes);

// A std::istream over a regular file, for readers that stream (parsers that
// take an istream, line readers, the nuScenes table parser). It wraps the
// checked descriptor in a libstdc++ stdio_filebuf rather than reading the file
// into a string first, because some inputs (nuScenes tables, point clouds)
// are hundreds of megabytes and streaming keeps memory at one buffer.
// Construction throws like OpenInputFile.
class InputFileStream : public std::istream {
 public:
  explicit InputFileStream(const std::string& path,
                           size_t buffer_bytes = size_t{1} << 16);
  ~InputFileStream() override;
  uint64_t size() const { return size_; }

 private:
  std::unique_ptr<std::streambuf> buf_;
  uint64_t size_ = 0;
};

}  // namespace geodrive

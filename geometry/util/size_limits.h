#pragma once
// Sizes a file declares, checked before anything is allocated or inflated.
//
// A reader takes every size, shape, member count, frame count and
// compression ratio a file declares through these checks, against what the
// file itself can hold and against the documented limits below
// (docs/RELIABILITY.md, "Sizes checked before allocating"), and only then
// allocates. Each check throws one InputError naming the file, the declared
// figure and the limit.

#include <cstdint>
#include <limits>
#include <string>

#include "geometry/util/status.h"

namespace geodrive {

struct SizeLimits {
  // One decompressed .npz member or .npy array: 8 GiB (the largest array a
  // reconstruction writes is a few hundred MB).
  static constexpr uint64_t kMaxMemberBytes = uint64_t{8} << 30;
  // All members of one archive together, as declared: 32 GiB.
  static constexpr uint64_t kMaxArchiveBytes = uint64_t{32} << 30;
  // Members of one archive: numpy.savez writes one per array, a reconstruction
  // a few dozen.
  static constexpr uint64_t kMaxArchiveMembers = 65536;
  // Decompressed bytes per compressed byte. Deflate cannot exceed 1032:1, so
  // no member numpy (or OpenEXR's ZIP) writes is refused; bzip2/zstd bombs
  // and entries that overlap are.
  static constexpr uint64_t kMaxCompressionRatio = 1100;
  // Bytes a small member may always declare, whatever its ratio (headers,
  // empty arrays).
  static constexpr uint64_t kRatioFreeBytes = 64 << 10;
  // Image sides and pixels (as JPEG/PNG, ImageReadLimits, and videos).
  static constexpr int64_t kMaxImageSide = 16384;
  static constexpr int64_t kMaxImagePixels = int64_t{1} << 28;
  // An EXR header (attributes before the offset table): 1 MiB.
  static constexpr uint64_t kMaxExrHeaderBytes = 1 << 20;
  // Frames of one video read whole (ReadVideoFrames): an hour at 25 fps.
  static constexpr int64_t kMaxVideoFrames = 100000;
  // One TFRecord record (a Waymo v1 frame is a few MB: a 200-frame segment
  // is about 1 GB).
  static constexpr uint64_t kMaxTfRecordBytes = uint64_t{1} << 30;
  // Decoded frames of one video held at once, RGB, plus kFrameOverheadBytes
  // a frame: 16 GiB.
  static constexpr int64_t kMaxVideoDecodeBytes = int64_t{16} << 30;
  // What a decoded frame costs beyond its pixels (cv::Mat header, allocation,
  // the demuxer's index entry).
  static constexpr int64_t kFrameOverheadBytes = 1024;
};

// `a` * `b`, or UINT64_MAX when the product overflows.
inline uint64_t SaturatingMul(uint64_t a, uint64_t b) {
  if (a != 0 && b > std::numeric_limits<uint64_t>::max() / a)
    return std::numeric_limits<uint64_t>::max();
  return a * b;
}

// A size the file declares (`declared` bytes of `what`) must fit in what the
// file has (`available`: bytes after the header, a member's stored bytes) and
// under `limit`.
inline void CheckDeclaredSize(const std::string& file,
                              const std::string& what,
                              uint64_t declared,
                              uint64_t available,
                              uint64_t limit) {
  if (declared > limit) {
    ThrowInputError(file, what, " declares ", declared,
                    " bytes, over the limit of ", limit, " bytes");
  }
  if (declared > available) {
    ThrowInputError(file, what, " declares ", declared,
                    " bytes but the file holds only ", available);
  }
}

// `uncompressed` bytes from `compressed` bytes: refused above
// SizeLimits::kMaxCompressionRatio (past SizeLimits::kRatioFreeBytes).
inline void CheckCompressionRatio(
    const std::string& file,
    const std::string& what,
    uint64_t uncompressed,
    uint64_t compressed,
    uint64_t ratio = SizeLimits::kMaxCompressionRatio) {
  if (uncompressed <= SizeLimits::kRatioFreeBytes) return;
  if (uncompressed / ratio > compressed ||
      (uncompressed / ratio == compressed && uncompressed % ratio != 0)) {
    ThrowInputError(file, what, " declares ", uncompressed, " bytes from ",
                    compressed, " compressed bytes, over the limit of ", ratio,
                    ":1");
  }
}

// A count the file declares (members, frames, points) under `limit`.
inline void CheckDeclaredCount(const std::string& file,
                               const std::string& what,
                               uint64_t declared,
                               uint64_t limit) {
  if (declared > limit) {
    ThrowInputError(file, what, " declares ", declared, ", over the limit of ",
                    limit);
  }
}

// An allocation of `bytes` for `what`, computed from declared sizes, under
// `limit`.
inline void CheckAllocation(const std::string& file,
                            const std::string& what,
                            uint64_t bytes,
                            uint64_t limit) {
  if (bytes > limit) {
    ThrowInputError(file, what, " would need ", bytes,
                    " bytes, over the limit of ", limit, " bytes");
  }
}

}  // namespace geodrive

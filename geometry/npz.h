#pragma once
// NumPy .npz archives (numpy.savez and numpy.savez_compressed): zip files whose
// members are .npy files, stored or deflated, read through libzip (Debian
// libzip-dev; zip64, CRC checks). The reconstruction front-ends' outputs (VGGT
// predictions.npz, Depth Anything 3 results.npz, MegaSaM *.npz, CUT3R's camera
// npz, our generic npz) are read with it. Every failure throws InputError
// naming the archive and the member.

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "geometry/npy.h"

namespace geodrive {

class NpzReader {
 public:
  // Opens the archive and lists its members. Throws InputError when the file
  // is missing, is not a zip archive, or is damaged.
  explicit NpzReader(const std::string& path);
  ~NpzReader();
  NpzReader(const NpzReader&) = delete;
  NpzReader& operator=(const NpzReader&) = delete;

  const std::string& path() const;
  // The arrays' names (member names without ".npy"), in archive order.
  const std::vector<std::string>& Keys() const;
  bool Has(const std::string& key) const;
  // The header of array `key` (reads only the member's first bytes).
  NpyHeader Header(const std::string& key) const;
  // Array `key`. Its declared size is checked against the member's
  // uncompressed size and options.max_bytes before anything is allocated; a
  // truncated member or a CRC mismatch is an error.
  NpyArray Read(const std::string& key,
                const NpyReadOptions& options = {}) const;
  // Array `key` converted to float32 (float16 depths included).
  NpyArray ReadAsFloat32(const std::string& key,
                         const NpyReadOptions& options = {}) const;
  // A string scalar `key` as numpy.savez writes a Python str ('<U' dtype,
  // shape () or (1,)) or bytes ('|S'); ASCII text only. Throws InputError
  // for any other array.
  std::string ReadString(const std::string& key) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Writes `arrays` (name without ".npy" -> array) as an .npz, deflated
// (numpy.savez_compressed) or stored (numpy.savez), atomically (temporary
// file + rename); the same arrays give the same bytes (members dated
// 1980-01-02). Throws InputError naming `path` on failure.
void WriteNpz(const std::string& path,
              const std::vector<std::pair<std::string, NpyArray>>& arrays,
              bool compress = true);

// An array whose C-order bytes are held elsewhere, in pieces (pointer, byte
// count) concatenated in order: an array assembled from per-frame buffers,
// written without a copy. The pieces must outlive the write.
struct NpyPieces {
  NpyDtype dtype = NpyDtype::kFloat32;
  std::vector<int64_t> shape;
  std::vector<std::pair<const void*, size_t>> pieces;
};
// WriteNpz of arrays given as pieces: the bytes WriteNpz writes for the
// assembled arrays. Throws InputError when the pieces do not hold the
// shape's bytes.
void WriteNpz(const std::string& path,
              const std::vector<std::pair<std::string, NpyPieces>>& arrays,
              bool compress = true);

// True when `path` starts with a zip signature (an .npz or any zip file).
bool LooksLikeZip(const std::string& path);

}  // namespace geodrive

#pragma once
// The header of a safetensors file (https://github.com/huggingface/safetensors,
// README "Format"), parsed and validated without LibTorch, so that the checks
// every checkpoint passes through can be fuzzed (fuzz/fuzz_safetensors.cc) and
// reused by tools that do not link the runtime.
//
// Layout: u64 little-endian header length N, N bytes of JSON {"name": {"dtype",
// "shape", "data_offsets": [begin, end)}, "__metadata__": {str: str}}, then the
// byte buffer (offsets are relative to byte 8 + N).

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace geodrive {
namespace diffusion {

// Header limit of the reference implementation (100 MB).
constexpr uint64_t kSafetensorsMaxHeaderBytes = 100u * 1000u * 1000u;
// Most tensors (top-level keys, __metadata__ included) one header may hold:
// twice the largest public checkpoints, all shards together (CogVideoX-5b's
// transformer has under 1,000; the largest mixture-of-experts models under
// 100,000). Bounds the header's parsed form (about 1 KB a tensor) at about
// 200 MB, where the 100 MB header alone would allow 2 million entries.
constexpr uint64_t kSafetensorsMaxTensors = 200000;

// One tensor of a safetensors header.
struct SafetensorsEntry {
  std::string name;
  std::string dtype;  // "F32", "BF16", ... (see SafetensorsDtypeNames()).
  std::vector<int64_t> shape;   // empty = 0-rank scalar
  uint64_t begin = 0, end = 0;  // byte range in the data buffer
  std::string file;  // the file holding it (the shard, for sharded checkpoints)
};

// The dtype names this reader accepts (those with a LibTorch 1.13 equivalent).
const std::vector<std::string>& SafetensorsDtypeNames();
// Bytes per element of an accepted dtype name ("BF16" -> 2); 0 for any other.
int64_t SafetensorsDtypeSize(const std::string& dtype);

// A validated header.
struct SafetensorsHeader {
  // Offset of the data buffer in the file (8 + header length).
  uint64_t data_start = 0;
  // The tensors in data-offset order; they tile the buffer exactly.
  std::vector<SafetensorsEntry> entries;
  std::map<std::string, std::string> metadata;
};

// Parses and validates the header of the `size`-byte file image `bytes` (the
// whole file, e.g. memory-mapped): header length bounds, JSON (nested at most
// kMaxJsonDepth deep), at most kSafetensorsMaxTensors tensors, duplicate
// names, dtypes, shapes, offsets inside the buffer, non-overlapping and
// covering it. Linear in the header size. Throws InputError naming `path`.
SafetensorsHeader ParseSafetensorsHeader(const std::string& path,
                                         const uint8_t* bytes,
                                         uint64_t size);

}  // namespace diffusion
}  // namespace geodrive

#pragma once
// safetensors checkpoints (https://github.com/huggingface/safetensors, README
// "Format"): memory-mapped, validated reading into at::Tensor, writing, and the
// sharded `*.index.json` form.
//
// Layout: u64 little-endian header length N, N bytes of JSON {"name": {"dtype",
// "shape", "data_offsets": [begin, end)}, "__metadata__": {str: str}}, then the
// byte buffer (offsets are relative to byte 8 + N). Every error is a
// geodrive::InputError naming the file.

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "diffusion/format/safetensors_header.h"

namespace geodrive {
namespace diffusion {

// A validated, memory-mapped safetensors file; tensors are copied out on
// Load().
class SafetensorsFile {
 public:
  // Maps and validates `path` (header length bounds, JSON, dtypes, shapes,
  // offsets inside the buffer, non-overlapping and covering it, no duplicate
  // names). Throws InputError.
  explicit SafetensorsFile(const std::string& path);
  ~SafetensorsFile();
  SafetensorsFile(const SafetensorsFile&) = delete;
  SafetensorsFile& operator=(const SafetensorsFile&) = delete;

  const std::string& path() const { return path_; }
  // Entries in data-offset order.
  const std::vector<SafetensorsEntry>& entries() const { return entries_; }
  const std::map<std::string, std::string>& metadata() const {
    return metadata_;
  }
  bool Has(const std::string& name) const { return index_.count(name) > 0; }
  const SafetensorsEntry& Entry(const std::string& name) const;
  // A fresh CPU tensor (own memory) with the stored dtype and shape.
  at::Tensor Load(const std::string& name) const;

 private:
  std::string path_;
  int fd_ = -1;
  const uint8_t* map_ = nullptr;
  uint64_t map_size_ = 0;
  uint64_t data_start_ = 0;
  std::vector<SafetensorsEntry> entries_;
  std::map<std::string, size_t> index_;
  std::map<std::string, std::string> metadata_;
};

// A checkpoint that is either one `.safetensors` file or a sharded
// `*.safetensors.index.json`
// ({"metadata": {...}, "weight_map": {name: shard file next to the index}}).
// Shards are opened lazily; names and shapes are available without reading
// tensor data.
class SafetensorsCheckpoint {
 public:
  explicit SafetensorsCheckpoint(const std::string& path);
  ~SafetensorsCheckpoint();
  const std::string& path() const { return path_; }
  bool sharded() const { return sharded_; }
  // All entries (every shard), sorted by name.
  const std::vector<SafetensorsEntry>& entries() const { return entries_; }
  bool Has(const std::string& name) const { return index_.count(name) > 0; }
  const SafetensorsEntry& Entry(const std::string& name) const;
  at::Tensor Load(const std::string& name) const;

 private:
  std::string path_;
  bool sharded_ = false;
  std::map<std::string, std::unique_ptr<SafetensorsFile>>
      shards_;  // by file path
  std::vector<SafetensorsEntry> entries_;
  std::map<std::string, size_t> index_;
};

using NamedTensors = std::vector<std::pair<std::string, at::Tensor>>;

// Loads every tensor of a file or sharded index, in name order.
NamedTensors LoadSafetensors(const std::string& path);

// Writes `tensors` (CPU or not, any layout; stored contiguous, little-endian)
// in the given order, header padded with spaces so the data starts 8-byte
// aligned. Writes to `path`.tmp and renames. Throws InputError on duplicate
// names, unsupported dtypes or I/O failure.
void SaveSafetensors(const std::string& path,
                     const NamedTensors& tensors,
                     const std::map<std::string, std::string>& metadata = {});

}  // namespace diffusion
}  // namespace geodrive

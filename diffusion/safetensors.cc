#include "diffusion/safetensors.h"

#include <ATen/ATen.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "geometry/util/files.h"
#include "geometry/util/input_file.h"
#include "geometry/util/json_depth.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace diffusion {
namespace {

using nlohmann::json;

struct DtypeInfo {
  const char* name;
  at::ScalarType type;
  int64_t itemsize;
};

const std::vector<DtypeInfo>& DtypeTable() {
  static const std::vector<DtypeInfo> table = {
      {"F64", at::kDouble, 8},    {"F32", at::kFloat, 4}, {"F16", at::kHalf, 2},
      {"BF16", at::kBFloat16, 2}, {"I64", at::kLong, 8},  {"I32", at::kInt, 4},
      {"I16", at::kShort, 2},     {"I8", at::kChar, 1},   {"U8", at::kByte, 1},
      {"BOOL", at::kBool, 1}};
  return table;
}

const DtypeInfo* FindDtype(const std::string& name) {
  for (const auto& d : DtypeTable()) {
    if (name == d.name) return &d;
  }
  return nullptr;
}

const DtypeInfo* FindDtype(at::ScalarType type) {
  for (const auto& d : DtypeTable()) {
    if (type == d.type) return &d;
  }
  return nullptr;
}

bool IsLittleEndianHost() {
  const uint16_t probe = 1;
  uint8_t first;
  std::memcpy(&first, &probe, 1);
  return first == 1;
}

std::string DirName(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? std::string(".") : path.substr(0, slash);
}

}  // namespace

SafetensorsFile::SafetensorsFile(const std::string& path) : path_(path) {
  InputFile input = OpenInputFile(path);  // a regular file, never blocking
  map_size_ = input.size();
  fd_ = input.Release();
  // From here on, failures must release the fd/map.
  try {
    if (map_size_ < 8)
      ThrowInputError(path, "truncated safetensors file (", map_size_,
                      " bytes)");
    void* m = ::mmap(nullptr, map_size_, PROT_READ, MAP_PRIVATE, fd_, 0);
    if (m == MAP_FAILED)
      ThrowInputError(path, "mmap failed (", std::strerror(errno), ")");
    map_ = static_cast<const uint8_t*>(m);
    SafetensorsHeader header = ParseSafetensorsHeader(path, map_, map_size_);
    data_start_ = header.data_start;
    entries_ = std::move(header.entries);
    metadata_ = std::move(header.metadata);
    for (size_t i = 0; i < entries_.size(); ++i) index_[entries_[i].name] = i;
  } catch (...) {
    if (map_ != nullptr) ::munmap(const_cast<uint8_t*>(map_), map_size_);
    map_ = nullptr;
    ::close(fd_);
    fd_ = -1;
    throw;
  }
}

SafetensorsFile::~SafetensorsFile() {
  if (map_ != nullptr) ::munmap(const_cast<uint8_t*>(map_), map_size_);
  if (fd_ >= 0) ::close(fd_);
}

const SafetensorsEntry& SafetensorsFile::Entry(const std::string& name) const {
  auto it = index_.find(name);
  if (it == index_.end())
    ThrowInputError(path_, "no tensor named '", name, "'");
  return entries_[it->second];
}

at::Tensor SafetensorsFile::Load(const std::string& name) const {
  const SafetensorsEntry& e = Entry(name);
  GEODRIVE_CHECK_INPUT(IsLittleEndianHost(), path_,
                       ": big-endian hosts are not supported");
  const DtypeInfo* dt = FindDtype(e.dtype);
  at::Tensor t = at::empty(e.shape, at::TensorOptions().dtype(dt->type));
  // Copy rather than from_blob: the mapped bytes may be unaligned and must not
  // outlive the map.
  if (e.end > e.begin)
    std::memcpy(t.data_ptr(), map_ + data_start_ + e.begin, e.end - e.begin);
  if (dt->type == at::kBool) {
    const uint8_t* p = static_cast<const uint8_t*>(t.data_ptr());
    for (uint64_t i = 0; i < e.end - e.begin; ++i) {
      if (p[i] > 1)
        ThrowInputError(path_, "tensor '", name,
                        "' has a BOOL byte that is not 0/1");
    }
  }
  return t;
}

SafetensorsCheckpoint::SafetensorsCheckpoint(const std::string& path)
    : path_(path) {
  if (!EndsWith(path, ".index.json")) {
    auto file = std::make_unique<SafetensorsFile>(path);
    entries_ = file->entries();
    shards_[path] = std::move(file);
  } else {
    sharded_ = true;
    InputFileStream in(path);
    json doc;
    try {
      doc = internal::ParseJson(in, path);
    } catch (const json::exception& e) {
      ThrowInputError(path, "safetensors index is not valid JSON (", e.what(),
                      ")");
    }
    if (!doc.is_object() || !doc.contains("weight_map") ||
        !doc["weight_map"].is_object()) {
      ThrowInputError(path, "safetensors index has no \"weight_map\" object");
    }
    const std::string dir = DirName(path);
    for (auto it = doc["weight_map"].begin(); it != doc["weight_map"].end();
         ++it) {
      if (!it.value().is_string()) {
        ThrowInputError(path, "weight_map entry '", it.key(),
                        "' is not a file name");
      }
      const std::string shard = it.value().get<std::string>();
      if (shard.empty() || shard.find('/') != std::string::npos ||
          shard == "." || shard == "..") {
        ThrowInputError(path, "weight_map entry '", it.key(), "' names '",
                        shard, "', not a file next to the index");
      }
      const std::string shard_path = dir + "/" + shard;
      auto sit = shards_.find(shard_path);
      if (sit == shards_.end()) {
        sit = shards_
                  .emplace(shard_path,
                           std::make_unique<SafetensorsFile>(shard_path))
                  .first;
      }
      if (!sit->second->Has(it.key())) {
        ThrowInputError(path, "weight_map says '", it.key(), "' is in ", shard,
                        " but that shard has no such tensor");
      }
      entries_.push_back(sit->second->Entry(it.key()));
    }
  }
  std::sort(entries_.begin(), entries_.end(),
            [](const auto& a, const auto& b) { return a.name < b.name; });
  for (size_t i = 0; i < entries_.size(); ++i) index_[entries_[i].name] = i;
}

SafetensorsCheckpoint::~SafetensorsCheckpoint() = default;

const SafetensorsEntry& SafetensorsCheckpoint::Entry(
    const std::string& name) const {
  auto it = index_.find(name);
  if (it == index_.end())
    ThrowInputError(path_, "no tensor named '", name, "'");
  return entries_[it->second];
}

at::Tensor SafetensorsCheckpoint::Load(const std::string& name) const {
  const SafetensorsEntry& e = Entry(name);
  return shards_.at(e.file)->Load(name);
}

NamedTensors LoadSafetensors(const std::string& path) {
  SafetensorsCheckpoint ckpt(path);
  NamedTensors out;
  for (const auto& e : ckpt.entries())
    out.emplace_back(e.name, ckpt.Load(e.name));
  return out;
}

void SaveSafetensors(const std::string& path,
                     const NamedTensors& tensors,
                     const std::map<std::string, std::string>& metadata) {
  GEODRIVE_CHECK_INPUT(IsLittleEndianHost(), path,
                       ": big-endian hosts are not supported");
  json header = json::object();
  if (!metadata.empty()) header["__metadata__"] = metadata;
  std::vector<at::Tensor> data;
  uint64_t offset = 0;
  for (const auto& [name, tensor] : tensors) {
    if (name == "__metadata__" || header.contains(name)) {
      ThrowInputError(path, "cannot write tensor name '", name,
                      "' (duplicate or reserved)");
    }
    const DtypeInfo* dt = FindDtype(tensor.scalar_type());
    if (dt == nullptr) {
      ThrowInputError(path, "tensor '", name, "' has dtype ",
                      at::toString(tensor.scalar_type()),
                      " which safetensors/LibTorch 1.13 cannot store");
    }
    at::Tensor c = tensor.detach().to(at::kCPU).contiguous();
    const uint64_t bytes = static_cast<uint64_t>(c.numel()) * dt->itemsize;
    header[name] = {
        {"dtype", dt->name},
        {"shape", std::vector<int64_t>(c.sizes().begin(), c.sizes().end())},
        {"data_offsets", {offset, offset + bytes}}};
    offset += bytes;
    data.push_back(c);
  }
  std::string text = header.dump();
  while ((8 + text.size()) % 8 != 0) text.push_back(' ');
  // A unique temporary beside the file, removed on SIGINT/SIGTERM.
  const std::string tmp = TemporaryPathFor(path, ".safetensors");
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) ThrowInputError(path, "cannot open for writing");
    uint8_t len[8];
    uint64_t n = text.size();
    for (int i = 0; i < 8; ++i)
      len[i] = static_cast<uint8_t>((n >> (8 * i)) & 0xff);
    out.write(reinterpret_cast<const char*>(len), 8);
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    for (const auto& c : data) {
      out.write(static_cast<const char*>(c.data_ptr()),
                static_cast<std::streamsize>(c.numel() * c.element_size()));
    }
    out.flush();
    if (!out) {
      std::remove(tmp.c_str());
      ThrowInputError(path, "write failed");
    }
  }
  CommitTemporaryFile(tmp, path);
}

}  // namespace diffusion
}  // namespace geodrive

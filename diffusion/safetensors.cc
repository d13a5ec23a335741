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

std::string ShapeString(const std::vector<int64_t>& shape) {
  std::ostringstream os;
  os << "[";
  for (size_t i = 0; i < shape.size(); ++i) os << (i ? ", " : "") << shape[i];
  os << "]";
  return os.str();
}

bool IsLittleEndianHost() {
  const uint16_t probe = 1;
  uint8_t first;
  std::memcpy(&first, &probe, 1);
  return first == 1;
}

// Reads a non-negative integer that fits int64 from a JSON value.
bool AsNonNegative(const json& v, uint64_t* out) {
  if (v.is_number_unsigned()) {
    *out = v.get<uint64_t>();
  } else if (v.is_number_integer()) {
    const int64_t s = v.get<int64_t>();
    if (s < 0) return false;
    *out = static_cast<uint64_t>(s);
  } else {
    return false;
  }
  return *out <= static_cast<uint64_t>(INT64_MAX);
}

std::string DirName(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? std::string(".") : path.substr(0, slash);
}

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

const std::vector<std::string>& SafetensorsDtypeNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const auto& d : DtypeTable()) n.push_back(d.name);
    return n;
  }();
  return names;
}

namespace {

// One tensor record of the header, checked against the data buffer.
SafetensorsEntry ParseTensorEntry(const std::string& path,
                                  const std::string& name,
                                  const json& v,
                                  uint64_t buffer_size) {
  if (!v.is_object() || !v.contains("dtype") || !v.contains("shape") ||
      !v.contains("data_offsets")) {
    ThrowInputError(path, "tensor '", name,
                    "' needs dtype, shape and data_offsets");
  }
  SafetensorsEntry e;
  e.name = name;
  e.file = path;
  if (!v["dtype"].is_string())
    ThrowInputError(path, "tensor '", name, "' dtype is not a string");
  e.dtype = v["dtype"].get<std::string>();
  const DtypeInfo* dt = FindDtype(e.dtype);
  if (dt == nullptr) {
    ThrowInputError(path, "tensor '", name, "' has unsupported dtype '",
                    e.dtype,
                    "' (supported: F64 F32 F16 BF16 I64 I32 I16 I8 U8 BOOL)");
  }
  if (!v["shape"].is_array())
    ThrowInputError(path, "tensor '", name, "' shape is not a list");
  uint64_t numel = 1;
  bool overflow = false;
  for (const auto& d : v["shape"]) {
    uint64_t dim;
    if (!AsNonNegative(d, &dim)) {
      ThrowInputError(path, "tensor '", name, "' has an invalid shape entry ",
                      d.dump());
    }
    e.shape.push_back(static_cast<int64_t>(dim));
    overflow |= __builtin_mul_overflow(numel, dim, &numel);
  }
  const json& off = v["data_offsets"];
  if (!off.is_array() || off.size() != 2 || !AsNonNegative(off[0], &e.begin) ||
      !AsNonNegative(off[1], &e.end)) {
    ThrowInputError(path, "tensor '", name,
                    "' data_offsets must be two non-negative integers");
  }
  if (e.end < e.begin)
    ThrowInputError(path, "tensor '", name, "' has data_offsets end < begin");
  if (e.end > buffer_size) {
    ThrowInputError(path, "tensor '", name, "' data_offsets [", e.begin, ", ",
                    e.end, ") lie outside the ", buffer_size,
                    "-byte data buffer");
  }
  uint64_t bytes = 0;
  overflow |= __builtin_mul_overflow(numel, static_cast<uint64_t>(dt->itemsize),
                                     &bytes);
  if (overflow || bytes != e.end - e.begin) {
    ThrowInputError(path, "tensor '", name, "' of dtype ", e.dtype,
                    " and shape ", ShapeString(e.shape), " needs ",
                    overflow ? std::string("too many") : std::to_string(bytes),
                    " bytes but data_offsets span ", e.end - e.begin);
  }
  return e;
}

// The tensors (sorted by offset) tile the data buffer exactly: no overlap, no
// hole, no trailing bytes.
void CheckContiguous(const std::string& path,
                     const std::vector<SafetensorsEntry>& entries,
                     uint64_t buffer_size) {
  uint64_t cursor = 0;
  for (const auto& e : entries) {
    if (e.begin < cursor) {
      ThrowInputError(path, "tensor '", e.name, "' data_offsets [", e.begin,
                      ", ", e.end, ") overlap the previous tensor");
    }
    if (e.begin > cursor) {
      ThrowInputError(path, "data buffer has a hole at bytes [", cursor, ", ",
                      e.begin, ") before tensor '", e.name, "'");
    }
    cursor = e.end;
  }
  if (cursor != buffer_size) {
    ThrowInputError(path, "data buffer has ", buffer_size - cursor,
                    " trailing bytes not covered by any tensor");
  }
}

}  // namespace

SafetensorsFile::SafetensorsFile(const std::string& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0)
    ThrowInputError(path, "cannot open safetensors file (",
                    std::strerror(errno), ")");
  struct stat st;
  if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd_);
    fd_ = -1;
    ThrowInputError(path, "not a regular file");
  }
  map_size_ = static_cast<uint64_t>(st.st_size);
  // From here on, failures must release the fd/map: validate inside a lambda
  // and clean up.
  try {
    if (map_size_ < 8)
      ThrowInputError(path, "truncated safetensors file (", map_size_,
                      " bytes)");
    void* m = ::mmap(nullptr, map_size_, PROT_READ, MAP_PRIVATE, fd_, 0);
    if (m == MAP_FAILED)
      ThrowInputError(path, "mmap failed (", std::strerror(errno), ")");
    map_ = static_cast<const uint8_t*>(m);

    uint64_t n = 0;
    for (int i = 7; i >= 0; --i) n = (n << 8) | map_[i];  // little-endian u64
    if (n < 2)
      ThrowInputError(path, "safetensors header length ", n, " is too small");
    if (n > kSafetensorsMaxHeaderBytes) {
      ThrowInputError(path, "safetensors header length ", n, " exceeds the ",
                      kSafetensorsMaxHeaderBytes, "-byte limit");
    }
    if (n > map_size_ - 8) {
      ThrowInputError(path, "safetensors header length ", n,
                      " runs past the end of the ", map_size_, "-byte file");
    }
    data_start_ = 8 + n;
    const char* header = reinterpret_cast<const char*>(map_ + 8);
    if (header[0] != '{')
      ThrowInputError(path, "safetensors header does not start with '{'");

    // Parse, detecting duplicate top-level keys (nlohmann keeps the last one
    // silently).
    std::set<std::string> seen_keys;
    std::string duplicate;
    json::parser_callback_t cb = [&](int depth, json::parse_event_t event,
                                     json& parsed) {
      if (depth == 1 && event == json::parse_event_t::key) {
        const std::string key = parsed.get<std::string>();
        if (!seen_keys.insert(key).second && duplicate.empty()) duplicate = key;
      }
      return true;
    };
    json doc;
    try {
      doc = json::parse(header, header + n, cb);
    } catch (const json::exception& e) {
      ThrowInputError(path, "safetensors header is not valid JSON (", e.what(),
                      ")");
    }
    if (!duplicate.empty())
      ThrowInputError(path, "duplicate tensor name '", duplicate, "'");
    if (!doc.is_object())
      ThrowInputError(path, "safetensors header is not a JSON object");

    const uint64_t buffer_size = map_size_ - data_start_;
    for (auto it = doc.begin(); it != doc.end(); ++it) {
      const std::string& name = it.key();
      const json& v = it.value();
      if (name == "__metadata__") {
        if (!v.is_object())
          ThrowInputError(path, "__metadata__ is not an object");
        for (auto m = v.begin(); m != v.end(); ++m) {
          if (!m.value().is_string()) {
            ThrowInputError(path, "__metadata__ value of '", m.key(),
                            "' is not a string");
          }
          metadata_[m.key()] = m.value().get<std::string>();
        }
        continue;
      }
      entries_.push_back(ParseTensorEntry(path, name, v, buffer_size));
    }
    std::sort(entries_.begin(), entries_.end(),
              [](const auto& a, const auto& b) {
                return a.begin != b.begin ? a.begin < b.begin : a.end < b.end;
              });
    CheckContiguous(path, entries_, buffer_size);
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
    std::ifstream in(path);
    if (!in) ThrowInputError(path, "cannot open safetensors index");
    json doc;
    try {
      doc = json::parse(in);
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
  const std::string tmp = path + ".tmp";
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

#include "diffusion/format/safetensors_header.h"

#include <algorithm>
#include <nlohmann/json.hpp>
#include <sstream>
#include <unordered_set>

#include "geometry/util/json_depth.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace diffusion {
namespace {

using nlohmann::json;

struct DtypeSize {
  const char* name;
  int64_t itemsize;
};
// Keep in step with the LibTorch table of diffusion/safetensors.cc (a test
// checks that both list the same names).
constexpr DtypeSize kDtypes[] = {
    {"F64", 8}, {"F32", 4}, {"F16", 2}, {"BF16", 2}, {"I64", 8},
    {"I32", 4}, {"I16", 2}, {"I8", 1},  {"U8", 1},   {"BOOL", 1}};

std::string ShapeString(const std::vector<int64_t>& shape) {
  std::ostringstream os;
  os << "[";
  for (size_t i = 0; i < shape.size(); ++i) os << (i ? ", " : "") << shape[i];
  os << "]";
  return os.str();
}

// A JSON value for an error message: a number, bool or null as written, a
// string cut at 40 bytes, an array or object by its type (never dump() of a
// container: its size is the input's).
std::string DescribeValue(const json& v) {
  if (v.is_array()) return "(an array)";
  if (v.is_object()) return "(an object)";
  if (v.is_string()) {
    const std::string& s = v.get_ref<const std::string&>();
    if (s.size() > 40) return json(s.substr(0, 40)).dump() + "...";
  }
  return v.dump();
}

// The header's JSON: nlohmann's DOM with the JSON depth limit
// (geometry/util/json_depth.h), the tensor limit, and the first top-level key
// that repeats (nlohmann would keep the last one silently). Linear, unlike
// nlohmann's parser callbacks, which rescan the parent object at the end of
// every object (quadratic in the tensor count: 100,000 tensors take minutes).
class HeaderSax : public internal::DepthLimitedJsonSax {
 public:
  using DepthLimitedJsonSax::DepthLimitedJsonSax;
  bool key(json::string_t& k) {
    if (depth() == 1) {
      if (seen_.size() == kSafetensorsMaxTensors) {
        ThrowInputError(path(), "safetensors header holds more than ",
                        kSafetensorsMaxTensors, " tensors (the limit)");
      }
      if (!seen_.insert(k).second && duplicate_.empty()) duplicate_ = k;
    }
    return DepthLimitedJsonSax::key(k);
  }
  const std::string& duplicate() const { return duplicate_; }

 private:
  std::unordered_set<std::string> seen_;
  std::string duplicate_;
};

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
  const int64_t itemsize = SafetensorsDtypeSize(e.dtype);
  if (itemsize == 0) {
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
                      DescribeValue(d));
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
  overflow |=
      __builtin_mul_overflow(numel, static_cast<uint64_t>(itemsize), &bytes);
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

const std::vector<std::string>& SafetensorsDtypeNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const auto& d : kDtypes) n.push_back(d.name);
    return n;
  }();
  return names;
}

int64_t SafetensorsDtypeSize(const std::string& dtype) {
  for (const auto& d : kDtypes) {
    if (dtype == d.name) return d.itemsize;
  }
  return 0;
}

SafetensorsHeader ParseSafetensorsHeader(const std::string& path,
                                         const uint8_t* bytes,
                                         uint64_t size) {
  SafetensorsHeader out;
  if (size < 8)
    ThrowInputError(path, "truncated safetensors file (", size, " bytes)");
  uint64_t n = 0;
  for (int i = 7; i >= 0; --i) n = (n << 8) | bytes[i];  // little-endian u64
  if (n < 2)
    ThrowInputError(path, "safetensors header length ", n, " is too small");
  if (n > kSafetensorsMaxHeaderBytes) {
    ThrowInputError(path, "safetensors header length ", n, " exceeds the ",
                    kSafetensorsMaxHeaderBytes, "-byte limit");
  }
  if (n > size - 8) {
    ThrowInputError(path, "safetensors header length ", n,
                    " runs past the end of the ", size, "-byte file");
  }
  out.data_start = 8 + n;
  const char* header = reinterpret_cast<const char*>(bytes + 8);
  if (header[0] != '{')
    ThrowInputError(path, "safetensors header does not start with '{'");

  json doc;
  HeaderSax sax(&doc, path);
  try {
    json::sax_parse(header, header + n, &sax);
  } catch (const json::exception& e) {
    ThrowInputError(path, "safetensors header is not valid JSON (", e.what(),
                    ")");
  }
  if (!sax.duplicate().empty())
    ThrowInputError(path, "duplicate tensor name '", sax.duplicate(), "'");
  if (!doc.is_object())
    ThrowInputError(path, "safetensors header is not a JSON object");

  const uint64_t buffer_size = size - out.data_start;
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
        out.metadata[m.key()] = m.value().get<std::string>();
      }
      continue;
    }
    out.entries.push_back(ParseTensorEntry(path, name, v, buffer_size));
  }
  std::sort(out.entries.begin(), out.entries.end(),
            [](const auto& a, const auto& b) {
              return a.begin != b.begin ? a.begin < b.begin : a.end < b.end;
            });
  CheckContiguous(path, out.entries, buffer_size);
  return out;
}

}  // namespace diffusion
}  // namespace geodrive

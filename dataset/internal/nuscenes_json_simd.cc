// The fast JSON front end of the nuScenes table reader: simdjson On Demand
// (Debian's libsimdjson-dev) over slices of whole records. See
// nuscenes_json.h for how it pairs with the reference (nlohmann SAX) front
// end.
//
// Why slices. simdjson parses a document that is wholly in memory, padded,
// and its structural index costs 4 bytes per structural character of the
// document on top. A v1.0-trainval sample_data.json is 1.29 GB: loading it
// padded (padded_string::load) is 1.29 GB of RSS before a single row exists,
// and the index would be gigabytes more; mmap does not help (touched pages of
// a mapping count in RSS too, and the index is the same). simdjson 3.0's
// document streams (iterate_many) take concatenated documents, not the
// elements of one big array (comma-separated streams came in 3.1). So the
// table is cut into slices of about 256 KiB (kDefaultSliceBytes): TableSlicer
// finds the last boundary between two records ("}" , "{" with only whitespace
// around the comma) in the next 256 KiB of the file and hands out "[" + those
// records +
// "]"; the next slice starts at the "{" after the boundary. Only the search
// is serial (under the slicer's lock, in a pread of the window's last 4 KiB);
// each thread reads its slice's bytes itself, outside the lock. Memory is one
// slice buffer plus simdjson's buffers per thread (a few MiB), and slices of
// one table parse on several threads at once, so one big table no longer bounds
// the load time.
//
// Why a slice cannot give wrong records. The first slice starts after the
// file's "[", every later one at the "{" after a boundary; by induction a
// slice starts outside any string at the top level. A "boundary" found
// inside a string leaves the slice with an unterminated string, and one found
// inside a nested value leaves it with unbalanced brackets; simdjson rejects
// both, the slicer and parser report failure, and the table is re-parsed by
// the reference front end. The parser also checks that the top-level array
// of the slice ends exactly where the slice ends (raw_json), iterates every
// value (On Demand only checks what it visits), and treats any top-level
// element that is not an object, and any number simdjson will not parse
// (beyond 64-bit integers, out-of-range doubles), as "not mine": the
// reference front end decides those.
//
// Portability: the On Demand code here is compiled with the project's flags
// (no -mavx2), which makes simdjson's compile-time "builtin" kernel the
// portable one for the tree walk and number parsing; the two costly steps --
// the structural index (stage 1) and string unescaping -- go through the
// runtime-dispatched kernels of libsimdjson (haswell / icelake here). A
// -march=haswell build of the walk measured no faster (ego_pose.json, 0.52
// GB: 0.65-0.78 s of CPU either way).

#include <fcntl.h>
#include <simdjson.h>
#include <sys/stat.h>
#include <unistd.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <utility>

#include "dataset/internal/nuscenes_json.h"
#include "geometry/util/input_file.h"
#include "geometry/util/json_depth.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace nuscenes_json {
namespace {

namespace od = simdjson::ondemand;

constexpr size_t kPadding = simdjson::SIMDJSON_PADDING;
// Nesting deeper than kMaxJsonDepth (geometry/util/json_depth.h) is left to
// the reference front end, which rejects it; this bounds the recursion of
// Skip, ReadArray and ReadInnerArray (On Demand does not check the depth
// itself: 110,000 nested arrays overflowed the stack in Skip). Depths: the
// slice's array is 1, a record 2, a field's array 3, its inner arrays 4.
constexpr int kRecordDepth = 2;

bool IsSpace(char c) { return c == ' ' || c == '\n' || c == '\r' || c == '\t'; }

// Whether the raw JSON key at `raw` (just after its opening quote, inside a
// padded simdjson document) is exactly f's plain key: the same bytes, then
// the closing quote. 32 bytes compared at once (the padding makes them
// readable), instead of a memcmp call per field.
bool RawKeyIs(const char* raw, const JsonField& f) {
  const size_t n = f.key.size();  // <= 32 for a plain key
#if defined(__SSE2__)
  const auto* r = reinterpret_cast<const __m128i*>(raw);
  const auto* k = reinterpret_cast<const __m128i*>(f.key32);
  const uint32_t lo = static_cast<uint32_t>(
      _mm_movemask_epi8(_mm_cmpeq_epi8(_mm_loadu_si128(r), _mm_load_si128(k))));
  const uint32_t hi = static_cast<uint32_t>(_mm_movemask_epi8(
      _mm_cmpeq_epi8(_mm_loadu_si128(r + 1), _mm_load_si128(k + 1))));
  const uint32_t equal = lo | hi << 16;
  const uint32_t need = n >= 32 ? ~uint32_t{0} : (uint32_t{1} << n) - 1;
  return (equal & need) == need && raw[n] == '"';
#else
  return std::memcmp(raw, f.key.data(), n) == 0 && raw[n] == '"';
#endif
}

// pread of exactly n bytes at `offset`.
bool ReadAt(int fd, char* out, size_t n, size_t offset) {
  while (n > 0) {
    const ssize_t got = pread(fd, out, n, static_cast<off_t>(offset));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) return false;
    out += got;
    n -= static_cast<size_t>(got);
    offset += static_cast<size_t>(got);
  }
  return true;
}

// The last record boundary in data[0, n): a "}" then whitespace, ",",
// whitespace and the "{" of the next record. Sets *end to one past the "}"
// and *next to the "{".
bool FindBoundary(const char* data, size_t n, size_t* end, size_t* next) {
  size_t limit = n;
  while (limit > 0) {
    const void* hit = memrchr(data, '{', limit);
    if (!hit) return false;
    const size_t open =
        static_cast<size_t>(static_cast<const char*>(hit) - data);
    limit = open;
    size_t p = open;
    while (p > 0 && IsSpace(data[p - 1])) --p;
    if (p == 0 || data[p - 1] != ',') continue;
    --p;
    while (p > 0 && IsSpace(data[p - 1])) --p;
    if (p == 0 || data[p - 1] != '}') continue;
    *end = p;
    *next = open;
    return true;
  }
  return false;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// TableSlicer.

TableSlicer::TableSlicer(const std::string& path, size_t slice_bytes)
    : slice_bytes_(std::max<size_t>(slice_bytes, 64)) {
  // Not a readable regular file: failed(), and the SAX reader reports why.
  try {
    InputFile input = OpenInputFile(path);
    file_bytes_ = static_cast<size_t>(input.size());
    fd_ = input.Release();
  } catch (const InputError&) {
    failed_ = true;
  }
}

TableSlicer::~TableSlicer() {
  if (fd_ >= 0) close(fd_);
}

bool TableSlicer::failed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return failed_;
}

bool TableSlicer::Fail() {
  failed_ = true;
  return false;
}

// Whitespace, "[", whitespace, then the first record's "{" (offset_ is set to
// it) or "]" and whitespace to the end (an empty table: done_).
bool TableSlicer::ReadHeader(std::vector<char>* buffer) {
  const size_t n = std::min<size_t>(file_bytes_, 4096);
  buffer->resize(n);
  if (!ReadAt(fd_, buffer->data(), n, 0)) return false;
  const char* d = buffer->data();
  size_t p = 0;
  while (p < n && IsSpace(d[p])) ++p;
  if (p == n || d[p] != '[') return false;
  ++p;
  while (p < n && IsSpace(d[p])) ++p;
  if (p < n && d[p] == '{') {
    offset_ = p;
    return true;
  }
  if (p == n || d[p] != ']' || n != file_bytes_) return false;
  for (++p; p < n; ++p) {
    if (!IsSpace(d[p])) return false;
  }
  done_ = true;
  return true;
}

// Under the lock: where the slice that starts at offset_ ends. For the last
// slice *end is the file size; otherwise *end is one past a record's "}" and
// *next the offset of the next record's "{". The boundary is searched in the
// tail of a window of slice_bytes_ (4 KiB of it first, more only when a record
// is longer); a window without one doubles.
bool TableSlicer::FindSliceEnd(size_t* end, size_t* next) {
  constexpr size_t kTail = 4096;
  for (size_t want = slice_bytes_;; want *= 2) {
    const size_t n = std::min(want, file_bytes_ - offset_);
    if (offset_ + n == file_bytes_) {
      *end = file_bytes_;
      return true;
    }
    for (size_t tail = std::min(n, kTail);; tail = std::min(n, 4 * tail)) {
      tail_.resize(tail);
      const size_t at = offset_ + n - tail;
      if (!ReadAt(fd_, tail_.data(), tail, at)) return false;
      size_t e = 0, x = 0;
      if (FindBoundary(tail_.data(), tail, &e, &x)) {
        *end = at + e;
        *next = at + x;
        return true;
      }
      if (tail == n) break;
    }
  }
}

bool TableSlicer::Next(Slice* slice) {
  size_t begin = 0, end = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    slice->index = next_index_;
    if (done_ || failed_) return false;
    if (!started_) {
      started_ = true;
      if (!ReadHeader(&slice->buffer)) return Fail();
      if (done_) return false;
    }
    size_t next = 0;
    if (!FindSliceEnd(&end, &next)) return Fail();
    begin = offset_;
    if (end == file_bytes_) {
      done_ = true;
    } else {
      offset_ = next;
    }
    ++next_index_;
  }
  // Outside the lock: buffer[0] = "[", the records, then "]" over the byte
  // after the last record's "}" (the last slice keeps the file's own "]").
  const size_t n = end - begin;
  std::vector<char>& buffer = slice->buffer;
  if (buffer.size() < n + 2 + kPadding) buffer.resize(n + 2 + kPadding);
  bool ok = ReadAt(fd_, buffer.data() + 1, n, begin);
  buffer[0] = '[';
  const char* data = buffer.data() + 1;
  slice->begin = 0;
  if (ok && end == file_bytes_) {
    // Only whitespace may follow the file's "]".
    size_t last = n;
    while (last > 0 && IsSpace(data[last - 1])) --last;
    ok = last > 0 && data[last - 1] == ']';
    slice->size = last + 1;
  } else if (ok) {
    // The "}" the search found (a file changed since is not trusted).
    ok = n > 0 && data[n - 1] == '}';
    buffer[1 + n] = ']';
    slice->size = n + 2;
  }
  if (!ok) {
    std::lock_guard<std::mutex> lock(mutex_);
    return Fail();
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// SliceParser.

struct SliceParser::Impl {
  od::parser parser;
  JsonRecord record;

  // A number as nlohmann's SAX reports it: an integer in the int64 range
  // (is_integer), an unsigned integer above it, or a double. simdjson 3.0.1's
  // get_number() gives 0 for a double of more than 19 significant digits
  // (found by the corrupted-tables test; get_double() is right), so a token
  // longer than 19 characters goes through get_number_type() and the typed
  // getter; shorter ones (all that JSON writers emit for doubles) through the
  // single-pass get_number().
  static bool ReadNumber(od::value value,
                         double* number,
                         int64_t* integer,
                         bool* is_integer) {
    od::number_type type;
    if (value.raw_json_token().size() <= 19) {
      od::number n;
      if (value.get_number().get(n)) return false;
      type = n.get_number_type();
      if (type == od::number_type::signed_integer) {
        *integer = n.get_int64();
        *number = static_cast<double>(*integer);
        *is_integer = true;
      } else if (type == od::number_type::unsigned_integer) {  // > INT64_MAX
        *integer = static_cast<int64_t>(n.get_uint64());
        *number = static_cast<double>(n.get_uint64());
        *is_integer = false;
      } else {
        *integer = 0;
        *number = n.get_double();
        *is_integer = false;
      }
      return true;
    }
    if (value.get_number_type().get(type)) return false;
    switch (type) {
      case od::number_type::signed_integer:
        if (value.get_int64().get(*integer)) return false;
        *number = static_cast<double>(*integer);
        *is_integer = true;
        return true;
      case od::number_type::unsigned_integer: {
        uint64_t u;
        if (value.get_uint64().get(u)) return false;
        *integer = static_cast<int64_t>(u);
        *number = static_cast<double>(u);
        *is_integer = false;
        return true;
      }
      default:
        *integer = 0;
        *is_integer = false;
        return !value.get_double().get(*number);
    }
  }

  // Visits (and so validates) a value whose content the record does not keep;
  // `parent_depth` is the depth of the array or object holding it.
  static bool Skip(od::value value, int parent_depth) {
    od::json_type type;
    if (value.type().get(type)) return false;
    const int depth = parent_depth + 1;  // if the value is an array or object
    switch (type) {
      case od::json_type::object: {
        if (depth > kMaxJsonDepth) return false;
        od::object object;
        if (value.get_object().get(object)) return false;
        for (auto field : object) {
          std::string_view key;
          if (field.error() || field.unescaped_key().get(key)) return false;
          if (!Skip(field.value(), depth)) return false;
        }
        return true;
      }
      case od::json_type::array: {
        if (depth > kMaxJsonDepth) return false;
        od::array array;
        if (value.get_array().get(array)) return false;
        for (auto element : array) {
          od::value v;
          if (element.get(v) || !Skip(v, depth)) return false;
        }
        return true;
      }
      case od::json_type::string: {
        std::string_view s;
        return !value.get_string().get(s);
      }
      case od::json_type::number: {
        double d;
        int64_t i;
        bool is_integer;
        return ReadNumber(value, &d, &i, &is_integer);
      }
      case od::json_type::boolean: {
        bool b;
        return !value.get_bool().get(b);
      }
      case od::json_type::null: {
        bool is_null = false;
        return !value.is_null().get(is_null) && is_null;
      }
    }
    return false;
  }

  // An array inside an inner array: numbers are kept (flattened, counted in
  // row_sizes), anything else marks the field array_of_other.
  static bool ReadInnerArray(od::value value, JsonField* f) {
    od::array array;
    if (value.get_array().get(array)) return false;
    f->row_sizes.push_back(0);
    for (auto element : array) {
      od::value v;
      od::json_type type;
      if (element.get(v) || v.type().get(type)) return false;
      if (type == od::json_type::number) {
        double d;
        int64_t i;
        bool is_integer;
        if (!ReadNumber(v, &d, &i, &is_integer)) return false;
        f->numbers.push_back(d);
        ++f->row_sizes.back();
      } else {
        f->array_of_other = true;
        if (!Skip(v, kRecordDepth + 2)) return false;
      }
    }
    return true;
  }

  // A field's array: numbers and strings are kept, inner arrays go through
  // ReadInnerArray, anything else marks the field array_of_other.
  static bool ReadArray(od::value value, JsonField* f) {
    od::array array;
    if (value.get_array().get(array)) return false;
    f->kind = JsonField::kArray;
    for (auto element : array) {
      od::value v;
      od::json_type type;
      if (element.get(v) || v.type().get(type)) return false;
      switch (type) {
        case od::json_type::number: {
          double d;
          int64_t i;
          bool is_integer;
          if (!ReadNumber(v, &d, &i, &is_integer)) return false;
          f->numbers.push_back(d);
          break;
        }
        case od::json_type::string: {
          std::string_view s;
          if (v.get_string().get(s)) return false;
          f->strings.emplace_back(s);
          break;
        }
        case od::json_type::array:
          if (!ReadInnerArray(v, f)) return false;
          break;
        default:
          f->array_of_other = true;
          if (!Skip(v, kRecordDepth + 1)) return false;
      }
    }
    return true;
  }

  static bool ReadValue(od::value value, JsonField* f) {
    od::json_type type;
    if (value.type().get(type)) return false;
    switch (type) {
      case od::json_type::string: {
        std::string_view s;
        if (value.get_string().get(s)) return false;
        f->kind = JsonField::kString;
        f->text = s;  // simdjson's string buffer: valid for this slice
        return true;
      }
      case od::json_type::number:
        f->kind = JsonField::kNumber;
        return ReadNumber(value, &f->number, &f->integer, &f->is_integer);
      case od::json_type::boolean:
        f->kind = JsonField::kBool;
        return !value.get_bool().get(f->boolean);
      case od::json_type::null: {
        bool is_null = false;
        f->kind = JsonField::kNull;
        return !value.is_null().get(is_null) && is_null;
      }
      case od::json_type::array:
        return ReadArray(value, f);
      case od::json_type::object:
        f->kind = JsonField::kOther;
        return Skip(value, kRecordDepth);
    }
    return false;
  }

  bool ReadRecord(od::object object) {
    record.Clear();
    for (auto field_result : object) {
      od::field field;
      if (std::move(field_result).get(field)) return false;
      // Records of a table nearly always repeat the previous record's keys:
      // compare the raw key with it instead of unescaping it.
      JsonField* f = nullptr;
      const JsonField* expected = record.NextPlainKey();
      if (expected && RawKeyIs(field.key().raw(), *expected)) {
        f = record.AddSameKey();
      } else {
        std::string_view key;
        if (field.unescaped_key().get(key)) return false;
        f = record.Add(key.data(), key.size());
      }
      if (!ReadValue(field.value(), f)) return false;
    }
    record.Finish();
    return true;
  }
};

SliceParser::SliceParser() : impl_(std::make_unique<Impl>()) {}
SliceParser::~SliceParser() = default;

bool SliceParser::Parse(const Slice& slice, RecordSink* sink) {
  od::parser& parser = impl_->parser;
  constexpr size_t kMaxDepth = kMaxJsonDepth;
  if (parser.capacity() < slice.size || parser.max_depth() != kMaxDepth) {
    // Room for any slice of the usual size at once: tables come small first
    // (category.json is 3 KB), and sized to each larger slice the parser's
    // buffers were allocated again, and their pages faulted in again, several
    // times a load. Untouched capacity costs address space, not RSS.
    const size_t usual = SliceBytes() + SliceBytes() / 8;
    if (parser.allocate(std::max(slice.size, usual), kMaxDepth)) return false;
  }
  const char* json = slice.buffer.data() + slice.begin;
  od::document doc;
  if (parser.iterate(json, slice.size, slice.buffer.size() - slice.begin)
          .get(doc)) {
    return false;
  }
  od::array records;
  if (doc.get_array().get(records)) return false;
  for (auto element : records) {
    od::object object;
    if (element.get_object().get(object)) return false;
    if (!impl_->ReadRecord(object)) return false;
    sink->OnRecord(impl_->record);
  }
  // The top-level array must end where the slice ends: On Demand would
  // otherwise ignore what follows it. After the array, the iterator is at the
  // end of the structural index only if no token follows (current_location
  // is then OUT_OF_BOUNDS). Checked after the walk rather than with
  // raw_json() before it, which walked every slice twice.
  return doc.current_location().error() == simdjson::OUT_OF_BOUNDS;
}

}  // namespace nuscenes_json
}  // namespace geodrive

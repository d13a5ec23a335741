// nuScenes reader. Loading: every table goes through the fast JSON front end
// (simdjson over slices of whole records, parsed on all threads;
// dataset/internal/nuscenes_json_simd.cc says why slices), which fills the
// same flat records as the reference front end (nlohmann SAX) did; all field
// checks and their errors live here, in RecordReader and the per-table
// converters, and so do not depend on the front end. A table the fast front
// end does not take (bad JSON, anything it cannot mirror exactly) is parsed
// again by the reference front end, whose errors are the reader's JSON errors.
// Rows of a table are committed in file order whatever thread parsed them, and
// the first error in the old order (tables in load order, records in file
// order) is the one thrown, so results and errors are those of a
// single-threaded SAX load.

#include "dataset/nuscenes.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <exception>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <iterator>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>
#include <unordered_map>

#include "dataset/internal/nuscenes_json.h"
#include "geometry/point_cloud_io.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

// ---------------------------------------------------------------------------------------------
// Tokens.

constexpr uint64_t kInternTag = 0xFFFFFFFFFFFFFFFFull;

struct TokenInterner {
  std::mutex mutex;
  std::vector<std::string> strings;
  std::unordered_map<std::string, uint64_t> ids;
};

TokenInterner& Interner() {
  static TokenInterner* interner = new TokenInterner();
  return *interner;
}

#if defined(__SSE2__)
// 32 lowercase hex digits -> two 64-bit words (first digit most significant);
// false if any is not [0-9a-f]. SSE2 (every x86-64): 16 digits per register,
// checked and converted at once. It runs for every token and reference of
// every record, 19 M times at v1.0-trainval size (under callgrind: a quarter
// of the instructions of the 64-bit SWAR version it replaces, kept below for
// other targets).
bool ParseHex32(const char* s, uint64_t* hi, uint64_t* lo) {
  // Digit values of 16 characters; *ok is false if one is not a hex digit.
  auto values = [](__m128i x, bool* ok) {
    const __m128i d = _mm_sub_epi8(x, _mm_set1_epi8('0'));  // '0'-'9' -> 0-9
    const __m128i l = _mm_sub_epi8(x, _mm_set1_epi8('a'));  // 'a'-'f' -> 0-5
    // Unsigned d <= 9 and l <= 5 (bytes >= 0x80 fail both).
    const __m128i is_d = _mm_cmpeq_epi8(_mm_min_epu8(d, _mm_set1_epi8(9)), d);
    const __m128i is_l = _mm_cmpeq_epi8(_mm_min_epu8(l, _mm_set1_epi8(5)), l);
    *ok = _mm_movemask_epi8(_mm_or_si128(is_d, is_l)) == 0xFFFF;
    const __m128i v =
        _mm_or_si128(_mm_and_si128(d, is_d),
                     _mm_and_si128(_mm_add_epi8(l, _mm_set1_epi8(10)), is_l));
    // 16-bit lane k holds v[2k] | v[2k+1] << 8; its low byte becomes
    // v[2k] << 4 | v[2k+1], the byte of digits 2k and 2k+1.
    const __m128i pair =
        _mm_or_si128(_mm_slli_epi16(v, 4), _mm_srli_epi16(v, 8));
    return _mm_and_si128(pair, _mm_set1_epi16(0x00FF));
  };
  bool ok_a, ok_b;
  const __m128i a =
      values(_mm_loadu_si128(reinterpret_cast<const __m128i*>(s)), &ok_a);
  const __m128i b =
      values(_mm_loadu_si128(reinterpret_cast<const __m128i*>(s + 16)), &ok_b);
  if (!ok_a || !ok_b) return false;
  // Bytes 0-7: digits 0-15, bytes 8-15: digits 16-31, in reading order; the
  // words are their big-endian values.
  const __m128i bytes = _mm_packus_epi16(a, b);
  *hi = __builtin_bswap64(static_cast<uint64_t>(_mm_cvtsi128_si64(bytes)));
  *lo = __builtin_bswap64(static_cast<uint64_t>(
      _mm_cvtsi128_si64(_mm_unpackhi_epi64(bytes, bytes))));
  return true;
}
#else
// 16 lowercase hex digits -> their value (the first digit most significant);
// false if any is not [0-9a-f]. Eight digits at a time in a 64-bit word
// (SWAR).
bool ParseHex16(const char* s, uint64_t* value) {
  constexpr uint64_t kOnes = 0x0101010101010101ull;
  constexpr uint64_t kHigh = 0x8080808080808080ull;
  // Bytes strictly between m and n (for bytes < 0x80): high bit set.
  auto between = [](uint64_t x, uint64_t m, uint64_t n) {
    const uint64_t low = x & (kOnes * 127);
    return (kOnes * (127 + n) - low) & ~x & (low + kOnes * (127 - m)) & kHigh;
  };
  uint64_t result = 0;
  for (int half = 0; half < 2; ++half) {
    uint64_t x;
    std::memcpy(&x, s + 8 * half, 8);  // x's lowest byte is the first digit
    const uint64_t ok =
        between(x, '0' - 1, '9' + 1) | between(x, 'a' - 1, 'f' + 1);
    if ((x & kHigh) != 0 || ok != kHigh) return false;
    // '0'-'9' -> 0-9 and 'a'-'f' -> 10-15: low nibble + 9 if bit 6 is set.
    const uint64_t v = (x & (kOnes * 0x0F)) + ((x >> 6) & kOnes) * 9;
    // Pairs of digits into bytes, then bytes into 32 bits, first digit high.
    const uint64_t t = ((v << 4) | (v >> 8)) & 0x00FF00FF00FF00FFull;
    const uint64_t u = (t | (t >> 8)) & 0x0000FFFF0000FFFFull;
    const uint32_t w = static_cast<uint32_t>(u | (u >> 16));
    result = (result << 32) | __builtin_bswap32(w);
  }
  *value = result;
  return true;
}

bool ParseHex32(const char* s, uint64_t* hi, uint64_t* lo) {
  return ParseHex16(s, hi) && ParseHex16(s + 16, lo);
}
#endif

// Parses 32 lowercase hex digits; false otherwise.
bool ParseHexToken(const char* s, size_t n, NuscenesToken* token) {
  uint64_t words[2];
  if (n != 32 || !ParseHex32(s, &words[0], &words[1])) return false;
  // The all-zero and the tag pattern are reserved: intern those (practically
  // never happens).
  if ((words[0] == 0 && words[1] == 0) || words[0] == kInternTag) return false;
  token->hi = words[0];
  token->lo = words[1];
  return true;
}

NuscenesToken TokenFromChars(const char* s, size_t n) {
  NuscenesToken token;
  if (n == 0) return token;
  if (ParseHexToken(s, n, &token)) return token;
  TokenInterner& interner = Interner();
  std::lock_guard<std::mutex> lock(interner.mutex);
  std::string key(s, n);
  auto it = interner.ids.find(key);
  if (it == interner.ids.end()) {
    it = interner.ids.emplace(key, interner.strings.size()).first;
    interner.strings.push_back(key);
  }
  token.hi = kInternTag;
  token.lo = it->second;
  return token;
}

inline uint64_t HashToken(const NuscenesToken& t) {
  uint64_t x = t.hi ^ (t.lo * 0x9E3779B97F4A7C15ull);
  x ^= x >> 30;
  x *= 0xBF58476D1CE4E5B9ull;
  x ^= x >> 27;
  x *= 0x94D049BB133111EBull;
  x ^= x >> 31;
  return x;
}

// ---------------------------------------------------------------------------------------------
// Tables.

enum Table {
  kCategory,
  kAttribute,
  kVisibility,
  kInstance,
  kSensor,
  kCalibratedSensor,
  kEgoPose,
  kLog,
  kScene,
  kSample,
  kSampleData,
  kSampleAnnotation,
  kMap,
  kNumTables
};

// Tables that real extracts often lack: loading goes on without them and
// references into them resolve to "unknown" (kNoIndex).
bool IsOptionalTable(int table) {
  return table == kAttribute || table == kVisibility || table == kLog ||
         table == kMap;
}

const char* const kTableNames[kNumTables] = {
    "category", "attribute",   "visibility",
    "instance", "sensor",      "calibrated_sensor",
    "ego_pose", "log",         "scene",
    "sample",   "sample_data", "sample_annotation",
    "map"};

int TableFromName(const std::string& name) {
  for (int t = 0; t < kNumTables; ++t) {
    if (name == kTableNames[t]) return t;
  }
  return -1;
}

namespace nj = nuscenes_json;
using nj::JsonField;
using nj::JsonRecord;

// ---------------------------------------------------------------------------------------------
// Field accessors with errors naming the table file and the record token.

class RecordReader {
 public:
  RecordReader(const std::string& path, const JsonRecord& record)
      : path_(path), record_(record) {
    const JsonField* f = record.Find("token");
    if (!f) Fail("a record has no 'token' field");
    if (f->kind != JsonField::kString || f->text.empty())
      Fail("a record has an invalid 'token'");
    token_str_ = f->text;
    token_ = TokenFromChars(f->text.data(), f->text.size());
  }
  const NuscenesToken& token() const { return token_; }
  std::string_view token_str() const { return token_str_; }

  template <typename... Args>
  [[noreturn]] void Error(const Args&... args) const {
    ThrowInputError(path_, "record ", token_str_, ": ", args...);
  }

  const JsonField& Get(const char* key, JsonField::Kind kind) const {
    const JsonField* f = record_.Find(key);
    if (!f) Error("missing field '", key, "'");
    if (f->kind != kind) Error("field '", key, "' has the wrong type");
    return *f;
  }
  const JsonField* Optional(const char* key) const { return record_.Find(key); }

  std::string String(const char* key) const {
    return std::string(Get(key, JsonField::kString).text);
  }
  std::string OptionalString(const char* key) const {
    const JsonField* f = record_.Find(key);
    return f && f->kind == JsonField::kString ? std::string(f->text)
                                              : std::string();
  }
  // A token reference; null and "" are the empty token.
  NuscenesToken Ref(const char* key) const {
    const JsonField* f = record_.Find(key);
    if (!f) Error("missing field '", key, "'");
    if (f->kind == JsonField::kNull) return NuscenesToken();
    if (f->kind != JsonField::kString)
      Error("field '", key, "' is not a token string");
    return TokenFromChars(f->text.data(), f->text.size());
  }
  int64_t Int(const char* key) const {
    const JsonField& f = Get(key, JsonField::kNumber);
    if (!f.is_integer) {
      // In range first: casting 1.7e93 to int64 is undefined (found by
      // fuzz_nuscenes_tables under UBSan).
      if (!std::isfinite(f.number) || f.number != std::floor(f.number) ||
          std::abs(f.number) >= 9.2233720368547758e18) {
        Error("field '", key, "' is not an integer in the int64 range");
      }
      return static_cast<int64_t>(f.number);
    }
    return f.integer;
  }
  int64_t OptionalInt(const char* key, int64_t fallback) const {
    const JsonField* f = record_.Find(key);
    if (!f || f->kind == JsonField::kNull) return fallback;
    return Int(key);
  }
  bool Bool(const char* key) const {
    return Get(key, JsonField::kBool).boolean;
  }
  const std::vector<double>& Numbers(const char* key, size_t expected) const {
    const JsonField& f = Get(key, JsonField::kArray);
    if (f.numbers.size() != expected || !f.row_sizes.empty() ||
        f.array_of_other || !f.strings.empty()) {
      Error("field '", key, "' must be an array of ", expected, " numbers");
    }
    for (double v : f.numbers) {
      if (!std::isfinite(v)) Error("field '", key, "' has a non-finite value");
    }
    return f.numbers;
  }
  Eigen::Vector3d Vec3(const char* key) const {
    const auto& v = Numbers(key, 3);
    return Eigen::Vector3d(v[0], v[1], v[2]);
  }
  Eigen::Quaterniond Quat(const char* key, double tol) const {
    const JsonField& f = Get(key, JsonField::kArray);
    if (f.numbers.size() != 4 || !f.row_sizes.empty() || f.array_of_other) {
      Error("field '", key, "' must be a quaternion [w, x, y, z]");
    }
    const auto& v = f.numbers;
    const double norm =
        std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3]);
    if (!std::isfinite(norm)) Error("quaternion '", key, "' is not finite");
    if (std::abs(norm - 1.0) > tol) {
      Error("quaternion '", key, "' is not unit (norm ", norm, ")");
    }
    return QuaternionFromWxyz(v[0] / norm, v[1] / norm, v[2] / norm,
                              v[3] / norm);
  }
  std::vector<NuscenesToken> RefList(const char* key) const {
    const JsonField& f = Get(key, JsonField::kArray);
    if (!f.numbers.empty() || f.array_of_other || !f.row_sizes.empty()) {
      Error("field '", key, "' must be an array of tokens");
    }
    std::vector<NuscenesToken> out;
    out.reserve(f.strings.size());
    for (const auto& s : f.strings)
      out.push_back(TokenFromChars(s.data(), s.size()));
    return out;
  }
  // Relative path inside the dataset: not absolute, no ".." component.
  std::string RelativePath(const char* key) const {
    std::string p = String(key);
    if (p.empty()) Error("field '", key, "' is empty");
    if (p[0] == '/' || p[0] == '\\' || (p.size() > 1 && p[1] == ':')) {
      Error("field '", key, "' is an absolute path (", p,
            "); a dataset cannot point outside its root");
    }
    // Components between '/' or '\\' separators: none may be "..". (Most
    // paths hold no ".." at all: one find, memchr-based, then.)
    if (p.find("..") == std::string::npos) return p;
    size_t start = 0;
    for (size_t i = 0; i <= p.size(); ++i) {
      if (i < p.size() && p[i] != '/' && p[i] != '\\') continue;
      if (i - start == 2 && p[start] == '.' && p[start + 1] == '.') {
        Error("field '", key, "' contains '..' (", p,
              "); a dataset cannot point outside its root");
      }
      start = i + 1;
    }
    return p;
  }

 private:
  [[noreturn]] void Fail(const std::string& what) const {
    ThrowInputError(path_, what);
  }
  const std::string& path_;
  const JsonRecord& record_;
  std::string_view token_str_;
  NuscenesToken token_;
};

// A sink that calls a lambda with a RecordReader.
template <typename Fn>
class LambdaSink : public nj::RecordSink {
 public:
  LambdaSink(const std::string& path, Fn fn)
      : path_(path), fn_(std::move(fn)) {}
  void OnRecord(const JsonRecord& record) override {
    RecordReader reader(path_, record);
    fn_(reader);
  }

 private:
  const std::string& path_;
  Fn fn_;
};

// ---------------------------------------------------------------------------------------------
// Loading one table: slices parsed by every thread, rows committed in file
// order, the reference front end after a fast-path failure.

// Rows of a table (or of one slice of it) and what they reference, pending
// resolution.
template <typename Row>
struct TableRows {
  std::vector<Row> rows;
  std::vector<NuscenesToken> refs;                // a fixed number per row
  std::vector<std::vector<NuscenesToken>> lists;  // per-row token lists
};

// Moves src to the end of dst. `expected` is the final size expected: growth
// reserves it at once, so a big table's rows are not copied (and held twice)
// over and over; capacity never touched costs address space, not RSS. The
// first slice's buffer becomes dst only when it has room for them all:
// taken whatever its size, it filled up after a few slices and all of those
// rows were copied again (16 % of a single-threaded v1.0-mini-size load's
// page faults).
template <typename T>
void AppendMoved(std::vector<T>* src, size_t expected, std::vector<T>* dst) {
  if (dst->empty() && src->capacity() >= expected) {
    dst->swap(*src);
  } else {
    const size_t need = dst->size() + src->size();
    if (need > dst->capacity()) dst->reserve(std::max(need, expected));
    std::move(src->begin(), src->end(), std::back_inserter(*dst));
  }
  src->clear();
}

class TableTask {
 public:
  virtual ~TableTask() = default;
  // Claims and parses slices until the table has none left or has failed.
  // Never throws: errors are kept for Finish. Called on every thread.
  virtual void Work(nj::SliceParser* parser, nj::Slice* slice) = 0;
  // After all Work: throws the table's first error, or re-parses it with the
  // reference front end after a fast-path failure; then moves the rows to
  // their destination. Returns the file size (0 for a missing table).
  virtual size_t Finish() = 0;
};

// `Fn` converts one record: fn(const RecordReader&, TableRows<Row>*).
template <typename Row, typename Fn>
class TypedTableTask : public TableTask {
 public:
  TypedTableTask(const std::string& path,
                 bool missing,
                 Fn fn,
                 std::vector<Row>* rows,
                 std::vector<NuscenesToken>* refs,
                 std::vector<std::vector<NuscenesToken>>* lists)
      : path_(path),
        missing_(missing),
        fn_(std::move(fn)),
        rows_(rows),
        refs_(refs),
        lists_(lists) {
    if (!missing_ && nj::FastFrontEndEnabled()) {
      slicer_ = std::make_unique<nj::TableSlicer>(path_, nj::SliceBytes());
    }
  }

  void Work(nj::SliceParser* parser, nj::Slice* slice) override {
    if (!slicer_) return;
    for (;;) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (failed_at_ != kNone) return;
      }
      if (!slicer_->Next(slice)) {
        if (slicer_->failed()) Fail(slice->index, nullptr);
        return;
      }
      TableRows<Row> part;
      bool ok = false;
      try {
        Reserve(slice->size, &part);
        auto convert = [&](const RecordReader& r) { fn_(r, &part); };
        LambdaSink<decltype(convert)> sink(path_, convert);
        ok = parser->Parse(*slice, &sink);
        if (ok) Commit(slice->index, slice->size, &part);
      } catch (...) {
        Fail(slice->index, std::current_exception());
        return;
      }
      if (!ok) {
        Fail(slice->index, nullptr);
        return;
      }
    }
  }

  size_t Finish() override {
    if (missing_) return 0;
    size_t bytes = 0;
    if (slicer_ && failed_at_ == kNone) {
      bytes = slicer_->file_bytes();
    } else if (error_) {
      std::rethrow_exception(error_);
    } else {
      if (slicer_) nj::CountFallback();
      result_ = TableRows<Row>();
      pending_.clear();
      auto convert = [&](const RecordReader& r) { fn_(r, &result_); };
      LambdaSink<decltype(convert)> sink(path_, convert);
      bytes = nj::ParseTableFileSax(path_, &sink);
    }
    *rows_ = std::move(result_.rows);
    if (refs_) *refs_ = std::move(result_.refs);
    if (lists_) *lists_ = std::move(result_.lists);
    return bytes;
  }

 private:
  static constexpr size_t kNone = ~size_t{0};
  struct Pending {
    size_t bytes = 0;
    TableRows<Row> part;
  };

  // Reserves the rows a slice of `bytes` is expected to give, over-estimated
  // (the bytes per row of the slices committed so far, less a quarter; 64
  // bytes, a record with a token and little else, before any): growth by
  // doubling copied each slice's rows about once more and touched as many
  // pages again (11 % of a single-threaded v1.0-mini-size load's page
  // faults). Capacity never touched costs address space, not RSS.
  void Reserve(size_t bytes, TableRows<Row>* part) {
    size_t rows_per_kib = 16, refs_per_row = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!result_.rows.empty()) {
        rows_per_kib = 1 + 4 * 1024 * result_.rows.size() / (3 * consumed_);
        refs_per_row = result_.refs.size() / result_.rows.size();
      }
    }
    const size_t rows = 16 + bytes / 1024 * rows_per_kib;
    part->rows.reserve(rows);
    if (refs_) part->refs.reserve(rows * (refs_per_row ? refs_per_row : 5));
    if (lists_) part->lists.reserve(rows);
  }

  // The slice `index` failed: with `error` (a conversion error), or without
  // (the fast front end gave up). The first failing slice in file order
  // decides, as it would have in a single pass.
  void Fail(size_t index, std::exception_ptr error) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (index < failed_at_) {
      failed_at_ = index;
      error_ = error;
    }
  }

  // Appends the rows of slice `index` once every earlier slice is in.
  void Commit(size_t index, size_t bytes, TableRows<Row>* part) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (index > failed_at_) return;  // the table has failed before it
    pending_[index] = Pending{bytes, std::move(*part)};
    for (auto it = pending_.begin();
         it != pending_.end() && it->first == committed_;
         it = pending_.erase(it), ++committed_) {
      consumed_ += it->second.bytes;
      // Rows expected in the whole file, from the bytes per row so far.
      const double scale = 1.1 * static_cast<double>(slicer_->file_bytes()) /
                           static_cast<double>(std::max<size_t>(consumed_, 1));
      TableRows<Row>& p = it->second.part;
      auto expected = [&](size_t n, size_t add) {
        return static_cast<size_t>(static_cast<double>(n + add) * scale) + 16;
      };
      AppendMoved(&p.refs, expected(result_.refs.size(), p.refs.size()),
                  &result_.refs);
      AppendMoved(&p.lists, expected(result_.lists.size(), p.lists.size()),
                  &result_.lists);
      AppendMoved(&p.rows, expected(result_.rows.size(), p.rows.size()),
                  &result_.rows);
    }
  }

  const std::string path_;
  const bool missing_;
  Fn fn_;
  std::vector<Row>* rows_;
  std::vector<NuscenesToken>* refs_;
  std::vector<std::vector<NuscenesToken>>* lists_;
  std::unique_ptr<nj::TableSlicer> slicer_;

  std::mutex mutex_;
  size_t failed_at_ = kNone;
  std::exception_ptr error_;
  std::map<size_t, Pending> pending_;  // parsed, waiting for earlier slices
  size_t committed_ = 0;               // slices appended to result_
  size_t consumed_ = 0;                // their bytes
  TableRows<Row> result_;
};

// The loader's thread count: `num_threads`, or OpenMP's default for 0 (so
// OMP_NUM_THREADS applies, and 1 inside another parallel region).
int LoaderThreads(int num_threads) {
  return num_threads > 0 ? num_threads : omp_get_max_threads();
}

// Runs body(k) for k in [0, threads) on the calling thread and threads - 1
// std::threads. Not an OpenMP region: OpenMP's idle threads spin-wait between
// regions (GOMP_SPINCOUNT), which at v1.0-mini size cost as much CPU as the
// load itself and slowed the serial steps in between on a busy machine.
// `body` must not throw.
template <typename Body>
void RunOnThreads(int threads, Body body) {
  std::vector<std::thread> pool;
  pool.reserve(threads > 1 ? threads - 1 : 0);
  for (int k = 1; k < threads; ++k) pool.emplace_back([&body, k] { body(k); });
  body(0);
  for (auto& t : pool) t.join();
}

// Runs fn(i, after) for i in [0, n) on `num_threads` threads and rethrows
// the exception of the smallest i that threw: the error a serial loop would
// have stopped at. Rows after it may have run too. `after` is true when the
// same thread ran fn(i - 1) just before (so row i - 1's results may be read).
template <typename Fn>
void ForEachRow(size_t n, int num_threads, Fn fn) {
  constexpr size_t kBlock = 4096;
  const int threads = LoaderThreads(num_threads);
  if (threads <= 1 || n < 2 * kBlock) {
    for (size_t i = 0; i < n; ++i) fn(i, i > 0);
    return;
  }
  std::atomic<size_t> next_block{0};
  std::atomic<size_t> first_error{n};
  std::exception_ptr error;
  std::mutex mutex;
  RunOnThreads(threads, [&](int) {
    for (;;) {
      const size_t begin = kBlock * next_block++;
      if (begin >= n || begin > first_error.load()) return;
      const size_t end = std::min(n, begin + kBlock);
      for (size_t i = begin; i < end; ++i) {
        try {
          fn(i, i > begin);
        } catch (...) {
          std::lock_guard<std::mutex> lock(mutex);
          if (i < first_error) {
            first_error = i;
            error = std::current_exception();
          }
          break;
        }
      }
    }
  });
  if (error) std::rethrow_exception(error);
}

// Runs Work of every task on `num_threads` threads, tables in order: the
// threads share a table's slices, then move on.
void RunTableTasks(const std::vector<std::unique_ptr<TableTask>>& tasks,
                   int num_threads) {
  if (!nj::FastFrontEndEnabled()) return;
  std::exception_ptr error;
  std::mutex error_mutex;
  RunOnThreads(LoaderThreads(num_threads), [&](int) {
    try {
      nj::SliceParser parser;
      nj::Slice slice;
      for (const auto& task : tasks) task->Work(&parser, &slice);
    } catch (...) {  // only allocation failures get here
      std::lock_guard<std::mutex> lock(error_mutex);
      if (!error) error = std::current_exception();
    }
  });
  if (error) std::rethrow_exception(error);
}

SensorModality ParseModality(const std::string& s) {
  if (s == "camera") return SensorModality::kCamera;
  if (s == "lidar") return SensorModality::kLidar;
  if (s == "radar") return SensorModality::kRadar;
  return SensorModality::kUnknown;
}

// calibrated_sensor's camera_intrinsic: absent, null or [] (no K), or 3x3.
void ReadIntrinsic(const RecordReader& r, NuscenesCalibratedSensor* c) {
  const JsonField* k = r.Optional("camera_intrinsic");
  if (!k || k->kind == JsonField::kNull) return;
  if (k->kind != JsonField::kArray || k->array_of_other ||
      !k->strings.empty()) {
    r.Error("camera_intrinsic is not a 3x3 matrix or []");
  }
  if (k->numbers.empty() && k->row_sizes.empty()) return;
  const bool ok = k->row_sizes.size() == 3 && k->row_sizes[0] == 3 &&
                  k->row_sizes[1] == 3 && k->row_sizes[2] == 3 &&
                  k->numbers.size() == 9;
  if (!ok) {
    r.Error("camera_intrinsic is not 3x3 (got ", k->row_sizes.size(), " rows, ",
            k->numbers.size(), " values)");
  }
  for (int i = 0; i < 9; ++i) {
    if (!std::isfinite(k->numbers[i]))
      r.Error("camera_intrinsic has a non-finite value");
    c->camera_intrinsic(i / 3, i % 3) = k->numbers[i];
  }
  c->has_intrinsic = true;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

NuscenesToken NuscenesToken::FromString(const std::string& text) {
  return TokenFromChars(text.data(), text.size());
}

std::string NuscenesToken::ToString() const {
  if (empty()) return std::string();
  if (hi == kInternTag) {
    TokenInterner& interner = Interner();
    std::lock_guard<std::mutex> lock(interner.mutex);
    return lo < interner.strings.size() ? interner.strings[lo]
                                        : std::string("<bad token>");
  }
  static const char kHex[] = "0123456789abcdef";
  std::string s(32, '0');
  for (int i = 0; i < 16; ++i) s[15 - i] = kHex[(hi >> (4 * i)) & 15];
  for (int i = 0; i < 16; ++i) s[31 - i] = kHex[(lo >> (4 * i)) & 15];
  return s;
}

std::string ToString(SensorModality modality) {
  switch (modality) {
    case SensorModality::kCamera:
      return "camera";
    case SensorModality::kLidar:
      return "lidar";
    case SensorModality::kRadar:
      return "radar";
    default:
      return "unknown";
  }
}

std::vector<Eigen::Vector3d> NuscenesBox::Corners(double wlh_factor) const {
  const double w = wlh.x() * wlh_factor, l = wlh.y() * wlh_factor,
               h = wlh.z() * wlh_factor;
  static const double kX[8] = {1, 1, 1, 1, -1, -1, -1, -1};
  static const double kY[8] = {1, -1, -1, 1, 1, -1, -1, 1};
  static const double kZ[8] = {1, 1, -1, -1, 1, 1, -1, -1};
  const Eigen::Matrix3d R = orientation.toRotationMatrix();
  std::vector<Eigen::Vector3d> corners(8);
  for (int i = 0; i < 8; ++i) {
    corners[i] =
        R * Eigen::Vector3d(l / 2 * kX[i], w / 2 * kY[i], h / 2 * kZ[i]) +
        center;
  }
  return corners;
}

NuscenesBox NuscenesBox::Transformed(const Rigid3d& b_from_a) const {
  NuscenesBox out = *this;
  out.center = b_from_a * center;
  out.orientation = (b_from_a.rotation * orientation).normalized();
  return out;
}

void NuscenesOptions::Check() const {
  GEODRIVE_CHECK_INPUT(!dataroot.empty(),
                       "nuScenes options: dataroot is empty");
  GEODRIVE_CHECK_INPUT(!version.empty(), "nuScenes options: version is empty");
  GEODRIVE_CHECK_INPUT(version.find("..") == std::string::npos &&
                           version.find('/') == std::string::npos,
                       "nuScenes options: version must be a folder name, got '",
                       version, "'");
  GEODRIVE_CHECK_INPUT(
      quaternion_norm_tol > 0 && quaternion_norm_tol < 0.5,
      "nuScenes options: quaternion_norm_tol must be in (0, 0.5)");
  GEODRIVE_CHECK_INPUT(num_threads >= 0 && num_threads <= 256,
                       "nuScenes options: num_threads must be in 0..256");
}

std::string NuscenesLoadSummary::BriefReport() const {
  std::ostringstream os;
  os << std::fixed << std::setprecision(2) << "loaded " << json_bytes / 1e6
     << " MB of JSON in " << seconds << " s";
  if (!missing_tables.empty()) {
    os << "; optional tables missing (references to them are unknown):";
    for (const auto& t : missing_tables) os << " " << t;
  }
  return os.str();
}

Nuscenes::Nuscenes(const NuscenesOptions& options) : options_(options) {
  options_.Check();
  namespace fs = std::filesystem;
  std::error_code ec;
  GEODRIVE_CHECK_INPUT(fs::is_directory(options_.dataroot, ec),
                       options_.dataroot,
                       ": nuScenes dataroot is not a directory");
  GEODRIVE_CHECK_INPUT(fs::is_directory(VersionDir(), ec), VersionDir(),
                       ": nuScenes version folder is missing");
  const auto start = std::chrono::steady_clock::now();
  Load();
  BuildChains();
  summary_.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
}

std::string Nuscenes::VersionDir() const {
  return (std::filesystem::path(options_.dataroot) / options_.version).string();
}

namespace {

// Reference tokens kept during loading, resolved once every table is in memory.
struct PendingRefs {
  std::vector<NuscenesToken> tokens;  // row-major [row][k]
  int per_row = 0;
};

}  // namespace

// Loader state: table paths, the table tasks (in load order) and the
// references pending resolution.
struct Nuscenes::LoadState {
  PendingRefs refs[kNumTables];
  std::vector<std::vector<NuscenesToken>> ann_attributes;
  std::vector<std::vector<NuscenesToken>> map_logs;
  std::string paths[kNumTables];
  bool missing[kNumTables] = {};
  std::vector<std::unique_ptr<TableTask>> tasks;

  // Adds table t's task: `fn(const RecordReader&, TableRows<Row>*)` converts
  // a record; rows go to `rows`, `per_row` references per row to refs[t],
  // per-row token lists to `lists`.
  template <typename Row, typename Fn>
  void Add(int t,
           std::vector<Row>* rows,
           Fn fn,
           int per_row = 0,
           std::vector<std::vector<NuscenesToken>>* lists = nullptr) {
    refs[t].per_row = per_row;
    tasks.push_back(std::make_unique<TypedTableTask<Row, Fn>>(
        paths[t], missing[t], std::move(fn), rows,
        per_row > 0 ? &refs[t].tokens : nullptr, lists));
  }
};

void Nuscenes::Load() {
  LoadState state;
  for (int t = 0; t < kNumTables; ++t) {
    state.paths[t] = (std::filesystem::path(VersionDir()) /
                      (std::string(kTableNames[t]) + ".json"))
                         .string();
  }
  // Fail fast on a missing required table before parsing the big ones; an
  // optional one is noted and treated as empty.
  for (int t = 0; t < kNumTables; ++t) {
    std::error_code ec;
    if (std::filesystem::exists(state.paths[t], ec)) continue;
    if (!IsOptionalTable(t)) {
      ThrowInputError(state.paths[t], "missing table file (required; the ",
                      "optional ones are attribute, visibility, log, map)");
    }
    state.missing[t] = true;
    summary_.missing_tables.push_back(kTableNames[t]);
  }
  AddDescriptionTables(&state);
  AddCaptureTables(&state);
  RunTableTasks(state.tasks, options_.num_threads);
  // In load order: the first table with an error throws it.
  size_t bytes = 0;
  for (const auto& task : state.tasks) bytes += task->Finish();
  state.tasks.clear();
  summary_.json_bytes = bytes;
  Resolve(&state);
}

// Categories, attributes, visibilities, instances, sensors, calibrations, ego
// poses, logs and maps.
void Nuscenes::AddDescriptionTables(LoadState* state) {
  const double qtol = options_.quaternion_norm_tol;
  using Tokens = std::vector<NuscenesToken>;
  state->Add(kCategory, &categories_,
             [](const RecordReader& r, TableRows<NuscenesCategory>* out) {
               NuscenesCategory c;
               c.token = r.token();
               c.name = r.String("name");
               c.description = r.OptionalString("description");
               c.index = static_cast<int>(r.OptionalInt("index", -1));
               out->rows.push_back(std::move(c));
             });
  state->Add(kAttribute, &attributes_,
             [](const RecordReader& r, TableRows<NuscenesAttribute>* out) {
               NuscenesAttribute a;
               a.token = r.token();
               a.name = r.String("name");
               a.description = r.OptionalString("description");
               out->rows.push_back(std::move(a));
             });
  state->Add(kVisibility, &visibilities_,
             [](const RecordReader& r, TableRows<NuscenesVisibility>* out) {
               NuscenesVisibility v;
               v.token = r.token();
               v.level = r.String("level");
               v.description = r.OptionalString("description");
               out->rows.push_back(std::move(v));
             });
  state->Add(
      kInstance, &instances_,
      [](const RecordReader& r, TableRows<NuscenesInstance>* out) {
        NuscenesInstance in;
        in.token = r.token();
        in.nbr_annotations =
            static_cast<int>(r.OptionalInt("nbr_annotations", 0));
        out->refs.push_back(r.Ref("category_token"));
        out->refs.push_back(r.Ref("first_annotation_token"));
        out->refs.push_back(r.Ref("last_annotation_token"));
        out->rows.push_back(in);
      },
      3);
  state->Add(kSensor, &sensors_,
             [](const RecordReader& r, TableRows<NuscenesSensor>* out) {
               NuscenesSensor s;
               s.token = r.token();
               s.channel = r.String("channel");
               s.modality = ParseModality(r.String("modality"));
               if (s.modality == SensorModality::kUnknown)
                 r.Error("unknown sensor modality");
               out->rows.push_back(std::move(s));
             });
  state->Add(
      kCalibratedSensor, &calibrated_sensors_,
      [qtol](const RecordReader& r, TableRows<NuscenesCalibratedSensor>* out) {
        NuscenesCalibratedSensor c;
        c.token = r.token();
        c.ego_from_sensor =
            Rigid3d(r.Quat("rotation", qtol), r.Vec3("translation"));
        out->refs.push_back(r.Ref("sensor_token"));
        ReadIntrinsic(r, &c);
        out->rows.push_back(c);
      },
      1);
  state->Add(kEgoPose, &ego_poses_,
             [qtol](const RecordReader& r, TableRows<NuscenesEgoPose>* out) {
               NuscenesEgoPose e;
               e.token = r.token();
               e.timestamp = r.Int("timestamp");
               e.global_from_ego =
                   Rigid3d(r.Quat("rotation", qtol), r.Vec3("translation"));
               out->rows.push_back(e);
             });
  state->Add(kLog, &logs_,
             [](const RecordReader& r, TableRows<NuscenesLog>* out) {
               NuscenesLog l;
               l.token = r.token();
               l.logfile = r.OptionalString("logfile");
               l.vehicle = r.OptionalString("vehicle");
               l.date_captured = r.OptionalString("date_captured");
               l.location = r.OptionalString("location");
               out->rows.push_back(std::move(l));
             });
  state->Add(
      kMap, &maps_,
      [](const RecordReader& r, TableRows<NuscenesMap>* out) {
        NuscenesMap m;
        m.token = r.token();
        m.category = r.OptionalString("category");
        m.filename = r.RelativePath("filename");
        Tokens logs = r.RefList("log_tokens");
        out->lists.push_back(std::move(logs));
        out->rows.push_back(std::move(m));
      },
      0, &state->map_logs);
}

// Scenes, samples, sample_data and annotations.
void Nuscenes::AddCaptureTables(LoadState* state) {
  const double qtol = options_.quaternion_norm_tol;
  state->Add(
      kScene, &scenes_,
      [](const RecordReader& r, TableRows<NuscenesScene>* out) {
        NuscenesScene s;
        s.token = r.token();
        s.name = r.String("name");
        s.description = r.OptionalString("description");
        s.nbr_samples = static_cast<int>(r.OptionalInt("nbr_samples", 0));
        out->refs.push_back(r.Ref("log_token"));
        out->refs.push_back(r.Ref("first_sample_token"));
        out->refs.push_back(r.Ref("last_sample_token"));
        out->rows.push_back(std::move(s));
      },
      3);
  state->Add(
      kSample, &samples_,
      [](const RecordReader& r, TableRows<NuscenesSample>* out) {
        NuscenesSample s;
        s.token = r.token();
        s.timestamp = r.Int("timestamp");
        out->refs.push_back(r.Ref("scene_token"));
        out->refs.push_back(r.Ref("prev"));
        out->refs.push_back(r.Ref("next"));
        out->rows.push_back(std::move(s));
      },
      3);
  state->Add(
      kSampleData, &sample_data_,
      [](const RecordReader& r, TableRows<NuscenesSampleData>* out) {
        NuscenesSampleData d;
        d.token = r.token();
        d.timestamp = r.Int("timestamp");
        d.width = static_cast<int32_t>(r.OptionalInt("width", 0));
        d.height = static_cast<int32_t>(r.OptionalInt("height", 0));
        if (d.width < 0 || d.height < 0 || d.width > 65536 ||
            d.height > 65536) {
          r.Error("invalid image size ", d.width, "x", d.height);
        }
        d.is_key_frame = r.Bool("is_key_frame");
        d.fileformat = r.OptionalString("fileformat");
        d.filename = r.RelativePath("filename");
        out->refs.push_back(r.Ref("sample_token"));
        out->refs.push_back(r.Ref("ego_pose_token"));
        out->refs.push_back(r.Ref("calibrated_sensor_token"));
        out->refs.push_back(r.Ref("prev"));
        out->refs.push_back(r.Ref("next"));
        out->rows.push_back(std::move(d));
      },
      5);
  state->Add(
      kSampleAnnotation, &sample_annotations_,
      [qtol](const RecordReader& r, TableRows<NuscenesSampleAnnotation>* out) {
        NuscenesSampleAnnotation a;
        a.token = r.token();
        a.translation = r.Vec3("translation");
        a.size = r.Vec3("size");
        if (a.size.minCoeff() < 0) r.Error("negative box size");
        a.rotation = r.Quat("rotation", qtol);
        a.num_lidar_pts = static_cast<int>(r.OptionalInt("num_lidar_pts", 0));
        a.num_radar_pts = static_cast<int>(r.OptionalInt("num_radar_pts", 0));
        out->refs.push_back(r.Ref("sample_token"));
        out->refs.push_back(r.Ref("instance_token"));
        out->refs.push_back(r.Ref("visibility_token"));
        out->refs.push_back(r.Ref("prev"));
        out->refs.push_back(r.Ref("next"));
        out->lists.push_back(r.RefList("attribute_tokens"));
        out->rows.push_back(std::move(a));
      },
      5, &state->ann_attributes);
}

// Open-addressing token -> row index of every table (duplicate tokens are an
// error naming the table).
void Nuscenes::BuildTokenIndices(const LoadState* state) {
  // One table per thread; the first table (in table order) with a duplicate
  // throws, as a serial pass would.
  std::exception_ptr errors[kNumTables];
  std::atomic<int> next{0};
  RunOnThreads(LoaderThreads(options_.num_threads), [&](int) {
    for (int table = next++; table < kNumTables; table = next++) {
      try {
        BuildTokenIndex(table, state->paths[table]);
      } catch (...) {
        errors[table] = std::current_exception();
      }
    }
  });
  for (const auto& error : errors) {
    if (error) std::rethrow_exception(error);
  }
}

void Nuscenes::BuildTokenIndex(int table, const std::string& path) {
  const size_t n = TableRowCount(table);
  TokenIndex& index = index_[table];
  size_t cap = 16;
  while (cap < 2 * n) cap <<= 1;
  index.slots.assign(cap, kNoIndex);
  index.mask = cap - 1;
  constexpr size_t kAhead = 16;  // slots are random accesses: prefetch them
  for (size_t i = 0; i < n; ++i) {
    if (i + kAhead < n) {
      const NuscenesToken& ahead =
          RowToken(table, static_cast<int32_t>(i + kAhead));
      __builtin_prefetch(&index.slots[HashToken(ahead) & index.mask]);
    }
    const NuscenesToken& t = RowToken(table, static_cast<int32_t>(i));
    uint64_t h = HashToken(t) & index.mask;
    while (index.slots[h] != kNoIndex) {
      if (RowToken(table, index.slots[h]) == t) {
        ThrowInputError(path, "record ", t.ToString(), ": duplicate token");
      }
      h = (h + 1) & index.mask;
    }
    index.slots[h] = static_cast<int32_t>(i);
  }
}

size_t Nuscenes::TableRowCount(int table) const {
  switch (table) {
    case kCategory:
      return categories_.size();
    case kAttribute:
      return attributes_.size();
    case kVisibility:
      return visibilities_.size();
    case kInstance:
      return instances_.size();
    case kSensor:
      return sensors_.size();
    case kCalibratedSensor:
      return calibrated_sensors_.size();
    case kEgoPose:
      return ego_poses_.size();
    case kLog:
      return logs_.size();
    case kScene:
      return scenes_.size();
    case kSample:
      return samples_.size();
    case kSampleData:
      return sample_data_.size();
    case kSampleAnnotation:
      return sample_annotations_.size();
    default:
      return maps_.size();
  }
}

const NuscenesToken& Nuscenes::RowToken(int table, int32_t i) const {
  switch (table) {
    case kCategory:
      return categories_[i].token;
    case kAttribute:
      return attributes_[i].token;
    case kVisibility:
      return visibilities_[i].token;
    case kInstance:
      return instances_[i].token;
    case kSensor:
      return sensors_[i].token;
    case kCalibratedSensor:
      return calibrated_sensors_[i].token;
    case kEgoPose:
      return ego_poses_[i].token;
    case kLog:
      return logs_[i].token;
    case kScene:
      return scenes_[i].token;
    case kSample:
      return samples_[i].token;
    case kSampleData:
      return sample_data_[i].token;
    case kSampleAnnotation:
      return sample_annotations_[i].token;
    default:
      return maps_[i].token;
  }
}

// A reference of `table`'s record whose token is `self` to a row of `target`
// (a guess `near` tried first: FindRowNear); kNoIndex for an empty optional
// one or a missing optional table. Throws naming the file otherwise.
int32_t Nuscenes::ResolveRef(const LoadState& state,
                             int table,
                             const NuscenesToken& self,
                             const char* field,
                             int target,
                             const NuscenesToken& ref,
                             bool required,
                             int32_t near) const {
  if (state.missing[target]) return kNoIndex;  // optional table absent
  if (ref.empty()) {
    if (required) {
      ThrowInputError(state.paths[table], "record ", self.ToString(), ": ",
                      field, " is empty");
    }
    return kNoIndex;
  }
  const int32_t i = FindRowNear(target, ref, near);
  if (i == kNoIndex) {
    ThrowInputError(state.paths[table], "record ", self.ToString(), ": ", field,
                    " ", ref.ToString(), " does not resolve in ",
                    kTableNames[target], ".json");
  }
  return i;
}

void Nuscenes::Resolve(LoadState* state) {
  BuildTokenIndices(state);

  // Resolves a reference of `table`'s record `row` (whose token is `self`) to a
  // row of `target`: ResolveRef.
  auto resolve = [&](auto&&... args) { return ResolveRef(*state, args...); };

  {
    const auto& p = state->refs[kInstance].tokens;
    for (size_t i = 0; i < instances_.size(); ++i) {
      auto& in = instances_[i];
      in.category = resolve(kInstance, in.token, "category_token", kCategory,
                            p[3 * i], true);
      in.first_annotation =
          resolve(kInstance, in.token, "first_annotation_token",
                  kSampleAnnotation, p[3 * i + 1], false);
      in.last_annotation = resolve(kInstance, in.token, "last_annotation_token",
                                   kSampleAnnotation, p[3 * i + 2], false);
    }
  }
  {
    const auto& p = state->refs[kCalibratedSensor].tokens;
    for (size_t i = 0; i < calibrated_sensors_.size(); ++i) {
      auto& c = calibrated_sensors_[i];
      c.sensor = resolve(kCalibratedSensor, c.token, "sensor_token", kSensor,
                         p[i], true);
    }
  }
  for (size_t m = 0; m < maps_.size(); ++m) {
    for (const auto& t : state->map_logs[m]) {
      const int32_t l =
          resolve(kMap, maps_[m].token, "log_tokens", kLog, t, true);
      if (l == kNoIndex) continue;  // log.json missing
      maps_[m].logs.push_back(l);
      logs_[l].map = static_cast<int32_t>(m);  // devkit: log['map_token']
    }
  }
  {
    const auto& p = state->refs[kScene].tokens;
    for (size_t i = 0; i < scenes_.size(); ++i) {
      auto& s = scenes_[i];
      s.log = resolve(kScene, s.token, "log_token", kLog, p[3 * i], true);
      s.first_sample = resolve(kScene, s.token, "first_sample_token", kSample,
                               p[3 * i + 1], true);
      s.last_sample = resolve(kScene, s.token, "last_sample_token", kSample,
                              p[3 * i + 2], true);
    }
  }
  const size_t num_sensors = sensors_.size();
  const int threads = options_.num_threads;
  {
    const auto& p = state->refs[kSample].tokens;
    const int targets[] = {-1, kSample, kSample};
    ForEachRow(samples_.size(), threads, [&](size_t i, bool after) {
      PrefetchRefs(p, targets, 3, i);
      auto& s = samples_[i];
      s.scene = resolve(kSample, s.token, "scene_token", kScene, p[3 * i], true,
                        after ? samples_[i - 1].scene : kNoIndex);
      s.prev = resolve(kSample, s.token, "prev", kSample, p[3 * i + 1], false);
      s.next = resolve(kSample, s.token, "next", kSample, p[3 * i + 2], false);
      s.data.assign(num_sensors, kNoIndex);
    });
  }
  ResolveSampleData(state, threads);
  ResolveAnnotations(state, threads);
}

// The first of two passes over `table`'s prev/next references (five per
// row, next the last): stores each row's next (kNoIndex when empty or
// unresolved: the second pass throws that error, in file order) and, as a
// guess, the row's index in the prev of the row its next points to. The
// second pass then finds a well-formed chain's prev with one comparison
// instead of a hash probe, whatever the file order. Two rows naming the same
// next both store (atomically; a guess is only ever compared).
template <typename Row>
void Nuscenes::ResolveNextAndGuessPrev(int table,
                                       const std::vector<NuscenesToken>& refs,
                                       int threads,
                                       std::vector<Row>* rows) const {
  const int next_only[] = {-1, -1, -1, -1, table};  // prefetched: next only
  ForEachRow(rows->size(), threads, [&](size_t i, bool) {
    PrefetchRefs(refs, next_only, 5, i);
    const int32_t j = FindRow(table, refs[5 * i + 4]);
    (*rows)[i].next = j;
    if (j != kNoIndex) {
      __atomic_store_n(&(*rows)[j].prev, static_cast<int32_t>(i),
                       __ATOMIC_RELAXED);
    }
  });
}

// sample_data's references, and each sample's key frames.
void Nuscenes::ResolveSampleData(LoadState* state, int threads) {
  auto resolve = [&](auto&&... args) { return ResolveRef(*state, args...); };
  auto& p = state->refs[kSampleData].tokens;
  ResolveNextAndGuessPrev(kSampleData, p, threads, &sample_data_);
  // Only references found by hash are prefetched (-1: found by a guess).
  const int targets[] = {kSample, -1, -1, -1, -1};
  ForEachRow(sample_data_.size(), threads, [&](size_t i, bool after) {
    PrefetchRefs(p, targets, 5, i);
    auto& d = sample_data_[i];
    const NuscenesSampleData* before = after ? &sample_data_[i - 1] : nullptr;
    d.sample = resolve(kSampleData, d.token, "sample_token", kSample, p[5 * i],
                       true, before ? before->sample : kNoIndex);
    d.ego_pose =
        resolve(kSampleData, d.token, "ego_pose_token", kEgoPose, p[5 * i + 1],
                true, before ? before->ego_pose : kNoIndex);
    d.calibrated_sensor = resolve(
        kSampleData, d.token, "calibrated_sensor_token", kCalibratedSensor,
        p[5 * i + 2], true, before ? before->calibrated_sensor : kNoIndex);
    // The first pass left the guess in prev: near + 1 is tried first.
    d.prev = resolve(kSampleData, d.token, "prev", kSampleData, p[5 * i + 3],
                     false, d.prev - 1);
    if (d.next == kNoIndex) {  // empty, or an error to throw in file order
      d.next = resolve(kSampleData, d.token, "next", kSampleData, p[5 * i + 4],
                       false);
    }
    d.sensor = calibrated_sensors_[d.calibrated_sensor].sensor;
  });
  std::vector<NuscenesToken>().swap(p);
  for (size_t i = 0; i < sample_data_.size(); ++i) {
    const auto& d = sample_data_[i];
    if (d.is_key_frame)
      samples_[d.sample].data[d.sensor] = static_cast<int32_t>(i);
  }
}

// sample_annotation's references, and each sample's annotations.
void Nuscenes::ResolveAnnotations(LoadState* state, int threads) {
  auto resolve = [&](auto&&... args) { return ResolveRef(*state, args...); };
  auto& p = state->refs[kSampleAnnotation].tokens;
  ResolveNextAndGuessPrev(kSampleAnnotation, p, threads, &sample_annotations_);
  const int targets[] = {kSample, -1, -1, -1, -1};
  ForEachRow(sample_annotations_.size(), threads, [&](size_t i, bool after) {
    PrefetchRefs(p, targets, 5, i);
    auto& a = sample_annotations_[i];
    const NuscenesSampleAnnotation* before =
        after ? &sample_annotations_[i - 1] : nullptr;
    a.sample = resolve(kSampleAnnotation, a.token, "sample_token", kSample,
                       p[5 * i], true, before ? before->sample : kNoIndex);
    a.instance =
        resolve(kSampleAnnotation, a.token, "instance_token", kInstance,
                p[5 * i + 1], true, before ? before->instance : kNoIndex);
    a.visibility =
        resolve(kSampleAnnotation, a.token, "visibility_token", kVisibility,
                p[5 * i + 2], false, before ? before->visibility : kNoIndex);
    a.prev = resolve(kSampleAnnotation, a.token, "prev", kSampleAnnotation,
                     p[5 * i + 3], false, a.prev - 1);
    if (a.next == kNoIndex) {  // empty, or an error to throw in file order
      a.next = resolve(kSampleAnnotation, a.token, "next", kSampleAnnotation,
                       p[5 * i + 4], false);
    }
    for (const auto& t : state->ann_attributes[i]) {
      const int32_t at = resolve(kSampleAnnotation, a.token, "attribute_tokens",
                                 kAttribute, t, true);
      if (at != kNoIndex) a.attributes.push_back(at);
    }
    a.category = instances_[a.instance].category;
  });
  for (size_t i = 0; i < sample_annotations_.size(); ++i) {
    samples_[sample_annotations_[i].sample].anns.push_back(
        static_cast<int32_t>(i));
  }
}

int32_t Nuscenes::Find(const std::string& table,
                       const NuscenesToken& token) const {
  const int t = TableFromName(table);
  GEODRIVE_CHECK_INPUT(t >= 0, "nuScenes: unknown table '", table, "'");
  return FindRow(t, token);
}

void Nuscenes::PrefetchRefs(const std::vector<NuscenesToken>& refs,
                            const int* targets,
                            int per_row,
                            size_t row) const {
  // Two steps ahead: the index slot of row + 16's references, then the
  // target row's token of row + 8's (its slot was fetched 8 rows ago).
  constexpr size_t kSlotAhead = 16, kRowAhead = 8;
  const size_t rows = refs.size() / per_row;
  for (int k = 0; k < per_row; ++k) {
    if (targets[k] < 0) continue;
    const TokenIndex& index = index_[targets[k]];
    if (index.slots.empty()) continue;
    if (row + kSlotAhead < rows) {
      const NuscenesToken& t = refs[(row + kSlotAhead) * per_row + k];
      if (!t.empty())
        __builtin_prefetch(&index.slots[HashToken(t) & index.mask]);
    }
    if (row + kRowAhead < rows) {
      const NuscenesToken& t = refs[(row + kRowAhead) * per_row + k];
      if (t.empty()) continue;
      const int32_t slot = index.slots[HashToken(t) & index.mask];
      if (slot != kNoIndex) __builtin_prefetch(&RowToken(targets[k], slot));
    }
  }
}

int32_t Nuscenes::FindRow(int t, const NuscenesToken& token) const {
  const TokenIndex& index = index_[t];
  if (index.slots.empty() || token.empty()) return kNoIndex;
  uint64_t h = HashToken(token) & index.mask;
  while (index.slots[h] != kNoIndex) {
    if (RowToken(t, index.slots[h]) == token) return index.slots[h];
    h = (h + 1) & index.mask;
  }
  return kNoIndex;
}

int32_t Nuscenes::FindRowNear(int t,
                              const NuscenesToken& token,
                              int32_t near) const {
  if (token.empty()) return kNoIndex;
  const int64_t rows = static_cast<int64_t>(TableRowCount(t));
  for (const int64_t guess : {int64_t{near} + 1, int64_t{near}}) {
    if (guess >= 0 && guess < rows &&
        RowToken(t, static_cast<int32_t>(guess)) == token) {
      return static_cast<int32_t>(guess);
    }
  }
  return FindRow(t, token);
}

int32_t Nuscenes::Find(const std::string& table,
                       const std::string& token) const {
  return Find(table, NuscenesToken::FromString(token));
}

int32_t Nuscenes::FindSensor(const std::string& channel) const {
  for (size_t i = 0; i < sensors_.size(); ++i) {
    if (sensors_[i].channel == channel) return static_cast<int32_t>(i);
  }
  return kNoIndex;
}

int32_t Nuscenes::FindScene(const std::string& name) const {
  for (size_t i = 0; i < scenes_.size(); ++i) {
    if (scenes_[i].name == name) return static_cast<int32_t>(i);
  }
  return kNoIndex;
}

const std::string& Nuscenes::Channel(int32_t sd) const {
  return sensors_[sample_data_.at(sd).sensor].channel;
}

SensorModality Nuscenes::Modality(int32_t sd) const {
  return sensors_[sample_data_.at(sd).sensor].modality;
}

const std::string& Nuscenes::CategoryName(int32_t annotation) const {
  return categories_[sample_annotations_.at(annotation).category].name;
}

void Nuscenes::BuildChains() {
  const size_t num_sensors = sensors_.size();
  chains_.assign(scenes_.size() * num_sensors, {});
  const std::string sd_path =
      (std::filesystem::path(VersionDir()) / "sample_data.json").string();
  auto scene_of = [&](int32_t sd) {
    return samples_[sample_data_[sd].sample].scene;
  };
  for (size_t scene = 0; scene < scenes_.size(); ++scene) {
    // Visit the scene's samples in order (bounded against cycles).
    std::vector<int32_t> heads(num_sensors, kNoIndex);
    int32_t s = scenes_[scene].first_sample;
    for (size_t guard = 0; s != kNoIndex && guard <= samples_.size(); ++guard) {
      if (samples_[s].scene != static_cast<int32_t>(scene)) break;
      for (size_t k = 0; k < num_sensors; ++k) {
        if (heads[k] == kNoIndex && samples_[s].data[k] != kNoIndex)
          heads[k] = samples_[s].data[k];
      }
      if (s == scenes_[scene].last_sample) break;
      s = samples_[s].next;
    }
    for (size_t k = 0; k < num_sensors; ++k) {
      int32_t head = heads[k];
      if (head == kNoIndex) continue;
      size_t guard = 0;
      while (sample_data_[head].prev != kNoIndex &&
             scene_of(sample_data_[head].prev) == static_cast<int32_t>(scene) &&
             guard++ <= sample_data_.size()) {
        head = sample_data_[head].prev;
      }
      auto& chain = chains_[scene * num_sensors + k];
      for (int32_t d = head;
           d != kNoIndex && scene_of(d) == static_cast<int32_t>(scene);
           d = sample_data_[d].next) {
        if (sample_data_[d].sensor != static_cast<int32_t>(k)) {
          ThrowInputError(sd_path, "record ", sample_data_[d].token.ToString(),
                          ": prev/next chain mixes channels ",
                          sensors_[k].channel, " and ",
                          sensors_[sample_data_[d].sensor].channel);
        }
        if (options_.check_chain_order && !chain.empty() &&
            sample_data_[d].timestamp <= sample_data_[chain.back()].timestamp) {
          ThrowInputError(
              sd_path, "record ", sample_data_[d].token.ToString(),
              ": timestamp does not increase along the prev/next chain");
        }
        // A doubly linked chain: the next record points back here. A fork
        // (two records whose next is the same, or a next that skips one)
        // would silently drop the records off this path.
        if (!chain.empty() && sample_data_[d].prev != chain.back()) {
          ThrowInputError(
              sd_path, "record ", sample_data_[d].token.ToString(),
              ": prev/next chain forks (record ",
              sample_data_[chain.back()].token.ToString(),
              " has it as next, but its prev is ",
              sample_data_[d].prev == kNoIndex
                  ? std::string("empty")
                  : sample_data_[sample_data_[d].prev].token.ToString(),
              ")");
        }
        chain.push_back(d);
        if (chain.size() > sample_data_.size()) {
          ThrowInputError(sd_path, "record ", sample_data_[d].token.ToString(),
                          ": prev/next chain has a cycle");
        }
      }
    }
  }
  // Every record of a scene and channel is on its chain: one left off (a
  // fork, a broken link) is named, not dropped.
  std::vector<size_t> rows(chains_.size(), 0);
  for (size_t d = 0; d < sample_data_.size(); ++d) {
    const int32_t sample = sample_data_[d].sample;
    if (sample == kNoIndex || samples_[sample].scene == kNoIndex ||
        sample_data_[d].sensor == kNoIndex)
      continue;
    ++rows[static_cast<size_t>(samples_[sample].scene) * num_sensors +
           sample_data_[d].sensor];
  }
  for (size_t i = 0; i < chains_.size(); ++i) {
    if (rows[i] == chains_[i].size()) continue;
    std::vector<bool> on(sample_data_.size(), false);
    for (int32_t d : chains_[i]) on[d] = true;
    for (size_t d = 0; d < sample_data_.size(); ++d) {
      const int32_t sample = sample_data_[d].sample;
      if (on[d] || sample == kNoIndex || samples_[sample].scene == kNoIndex ||
          sample_data_[d].sensor == kNoIndex ||
          static_cast<size_t>(samples_[sample].scene) * num_sensors +
                  sample_data_[d].sensor !=
              i)
        continue;
      ThrowInputError(sd_path, "record ", sample_data_[d].token.ToString(),
                      " (", sensors_[sample_data_[d].sensor].channel,
                      ", scene ", scenes_[i / num_sensors].name,
                      ") is not on its channel's prev/next chain (",
                      chains_[i].size(), " of ", rows[i],
                      " records linked): a fork or a broken link");
    }
  }
}

const std::vector<int32_t>& Nuscenes::Chain(int32_t scene,
                                            int32_t sensor) const {
  static const std::vector<int32_t> kEmpty;
  if (scene < 0 || sensor < 0 ||
      scene >= static_cast<int32_t>(scenes_.size()) ||
      sensor >= static_cast<int32_t>(sensors_.size())) {
    return kEmpty;
  }
  return chains_[static_cast<size_t>(scene) * sensors_.size() + sensor];
}

std::vector<int32_t> Nuscenes::Chain(int32_t scene,
                                     const std::string& channel) const {
  return Chain(scene, FindSensor(channel));
}

Rigid3d Nuscenes::GlobalFromEgo(int32_t sd) const {
  return ego_poses_[sample_data_.at(sd).ego_pose].global_from_ego;
}

Rigid3d Nuscenes::EgoFromSensor(int32_t sd) const {
  return calibrated_sensors_[sample_data_.at(sd).calibrated_sensor]
      .ego_from_sensor;
}

Rigid3d Nuscenes::WorldFromSensor(int32_t sd) const {
  return GlobalFromEgo(sd) * EgoFromSensor(sd);
}

PinholeCamera Nuscenes::Camera(int32_t sd) const {
  const auto& d = sample_data_.at(sd);
  const auto& cs = calibrated_sensors_[d.calibrated_sensor];
  if (!cs.has_intrinsic) {
    ThrowInputError(
        (std::filesystem::path(VersionDir()) / "calibrated_sensor.json")
            .string(),
        "record ", cs.token.ToString(),
        ": no camera_intrinsic for sample_data ", d.token.ToString(), " (",
        Channel(sd), ")");
  }
  PinholeCamera camera =
      PinholeCamera::FromK(cs.camera_intrinsic, d.width, d.height);
  camera.Check("sample_data " + d.token.ToString());
  return camera;
}

std::string Nuscenes::DataPath(int32_t sd) const {
  return (std::filesystem::path(options_.dataroot) /
          sample_data_.at(sd).filename)
      .string();
}

PointCloud Nuscenes::LoadLidar(int32_t sd) const {
  const std::string path = DataPath(sd);
  try {
    return ReadNuscenesLidarBin(path);
  } catch (const InputError& e) {
    std::string what = e.what();
    if (what.find(path) == std::string::npos) what = path + ": " + what;
    throw InputError(what + " (sample_data record " +
                     sample_data_[sd].token.ToString() + ")");
  }
}

NuscenesBox Nuscenes::GetBox(int32_t annotation) const {
  const auto& a = sample_annotations_.at(annotation);
  NuscenesBox box;
  box.center = a.translation;
  box.wlh = a.size;
  box.orientation = a.rotation;
  box.annotation = annotation;
  box.instance = a.instance;
  box.category = a.category;
  return box;
}

std::vector<NuscenesBox> Nuscenes::GetBoxes(int32_t sd) const {
  const auto& d = sample_data_.at(sd);
  const auto& curr = samples_[d.sample];
  std::vector<NuscenesBox> boxes;
  boxes.reserve(curr.anns.size());
  if (curr.prev == kNoIndex || d.is_key_frame) {
    for (int32_t a : curr.anns) boxes.push_back(GetBox(a));
    return boxes;
  }
  const auto& prev = samples_[curr.prev];
  std::unordered_map<int32_t, int32_t> prev_by_instance;
  for (int32_t a : prev.anns)
    prev_by_instance[sample_annotations_[a].instance] = a;
  const double t0 = static_cast<double>(prev.timestamp);
  const double t1 = static_cast<double>(curr.timestamp);
  const double t = std::max(t0, std::min(t1, static_cast<double>(d.timestamp)));
  const double amount = t1 > t0 ? (t - t0) / (t1 - t0) : 0.0;
  for (int32_t a : curr.anns) {
    NuscenesBox box = GetBox(a);
    auto it = prev_by_instance.find(sample_annotations_[a].instance);
    if (it != prev_by_instance.end()) {
      const auto& pa = sample_annotations_[it->second];
      // np.interp(t, [t0, t1], [c0, c1]) per coordinate (t clamped above).
      box.center =
          pa.translation +
          amount * (sample_annotations_[a].translation - pa.translation);
      box.orientation =
          pa.rotation.slerp(amount, sample_annotations_[a].rotation)
              .normalized();
    }
    boxes.push_back(box);
  }
  return boxes;
}

}  // namespace geodrive

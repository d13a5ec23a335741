#include "dataset/nuscenes.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <unordered_map>

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

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

// Parses 32 lowercase hex digits; false otherwise.
bool ParseHexToken(const char* s, size_t n, NuscenesToken* token) {
  if (n != 32) return false;
  uint64_t words[2] = {0, 0};
  for (size_t i = 0; i < 32; ++i) {
    const int v = HexValue(s[i]);
    if (v < 0) return false;
    words[i / 16] = (words[i / 16] << 4) | static_cast<uint64_t>(v);
  }
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

// ---------------------------------------------------------------------------------------------
// Streaming JSON: a SAX handler that turns a top-level array of flat objects
// into records.

struct JsonField {
  enum Kind { kNull, kBool, kNumber, kString, kArray, kOther };
  std::string key;
  Kind kind = kNull;
  bool boolean = false;
  double number = 0;
  int64_t integer = 0;
  bool is_integer = false;
  std::string str;
  std::vector<double> numbers;  // array elements (flattened for nested arrays)
  std::vector<std::string> strings;  // array string elements
  std::vector<int>
      row_sizes;  // for arrays of arrays: the size of each inner array
  bool array_of_other =
      false;  // array holding something else (objects, bools, ...)
};

struct JsonRecord {
  std::vector<JsonField> fields;
  size_t size = 0;
  const JsonField* Find(const char* key) const {
    for (size_t i = 0; i < size; ++i) {
      if (fields[i].key == key) return &fields[i];
    }
    return nullptr;
  }
};

class RecordSink {
 public:
  virtual ~RecordSink() = default;
  virtual void OnRecord(const JsonRecord& record) = 0;
};

class TableSax {
 public:
  using json = nlohmann::json;
  TableSax(const std::string& path, RecordSink* sink)
      : path_(path), sink_(sink) {}

  const std::string& last_token() const { return last_token_; }
  size_t records() const { return records_; }
  bool finished() const { return finished_; }

  bool null() { return Scalar(JsonField::kNull); }
  bool boolean(bool v) {
    if (InArray()) return ArrayOther();
    JsonField* f = Current();
    if (!f) return true;
    f->kind = JsonField::kBool;
    f->boolean = v;
    return true;
  }
  bool number_integer(json::number_integer_t v) {
    return Number(static_cast<double>(v), v, true);
  }
  bool number_unsigned(json::number_unsigned_t v) {
    return Number(static_cast<double>(v), static_cast<int64_t>(v),
                  v <= INT64_MAX);
  }
  bool number_float(json::number_float_t v, const json::string_t&) {
    return Number(v, 0, false);
  }
  bool string(json::string_t& v) {
    if (skip_ > 0) return true;
    if (InArray()) {
      if (array_depth_ == 1) {
        field_->strings.emplace_back(std::move(v));
      } else {
        field_->array_of_other = true;
      }
      return true;
    }
    JsonField* f = Current();
    if (!f) {
      if (depth_ == 0) Fail("expected a JSON array of records, got a string");
      return true;
    }
    f->kind = JsonField::kString;
    f->str.swap(v);
    return true;
  }
  bool binary(json::binary_t&) { return true; }
  bool start_object(std::size_t) {
    if (skip_ > 0 || InArray() || depth_ >= 2) {
      if (InArray()) field_->array_of_other = true;
      if (field_ && !InArray()) field_->kind = JsonField::kOther;
      ++skip_;
      return true;
    }
    if (depth_ == 0) Fail("expected a JSON array of records, got an object");
    depth_ = 2;
    record_.size = 0;
    field_ = nullptr;
    return true;
  }
  bool key(json::string_t& k) {
    if (skip_ > 0) return true;
    if (record_.size == record_.fields.size()) record_.fields.emplace_back();
    field_ = &record_.fields[record_.size++];
    field_->key.swap(k);
    field_->kind = JsonField::kNull;
    field_->numbers.clear();
    field_->strings.clear();
    field_->row_sizes.clear();
    field_->array_of_other = false;
    field_->is_integer = false;
    return true;
  }
  bool end_object() {
    if (skip_ > 0) {
      --skip_;
      return true;
    }
    depth_ = 1;
    field_ = nullptr;
    const JsonField* token = record_.Find("token");
    if (token && token->kind == JsonField::kString) last_token_ = token->str;
    sink_->OnRecord(record_);
    ++records_;
    return true;
  }
  bool start_array(std::size_t) {
    if (skip_ > 0) {
      ++skip_;
      return true;
    }
    if (depth_ == 0) {
      depth_ = 1;
      return true;
    }
    if (depth_ == 1)
      Fail("expected a record object inside the top-level array, got an array");
    if (!field_) return true;
    if (array_depth_ == 0) {
      field_->kind = JsonField::kArray;
      array_depth_ = 1;
    } else if (array_depth_ == 1) {
      field_->row_sizes.push_back(0);
      array_depth_ = 2;
    } else {
      field_->array_of_other = true;
      ++skip_;
    }
    return true;
  }
  bool end_array() {
    if (skip_ > 0) {
      --skip_;
      return true;
    }
    if (array_depth_ > 0) {
      --array_depth_;
      return true;
    }
    if (depth_ == 1) {
      depth_ = 0;
      finished_ = true;
    }
    return true;
  }
  bool parse_error(std::size_t position,
                   const std::string&,
                   const nlohmann::detail::exception& e) {
    std::string what = e.what();
    // nlohmann prefixes "[json.exception.parse_error.101] parse error at line
    // 1, column 2: ".
    const size_t colon = what.find(": ");
    if (colon != std::string::npos) what = what.substr(colon + 2);
    std::ostringstream os;
    os << "malformed JSON at byte " << position;
    const JsonField* current = depth_ == 2 ? record_.Find("token") : nullptr;
    if (current && current->kind == JsonField::kString &&
        !current->str.empty()) {
      os << " (in record " << current->str << ")";
    } else if (!last_token_.empty()) {
      os << " (after record " << last_token_ << ")";
    } else {
      os << " (before the first record)";
    }
    os << ": " << what;
    ThrowInputError(path_, os.str());
  }

 private:
  [[noreturn]] void Fail(const std::string& what) {
    ThrowInputError(path_, what);
  }
  bool InArray() const {
    return skip_ == 0 && field_ != nullptr && array_depth_ > 0;
  }
  JsonField* Current() {
    if (skip_ > 0 || depth_ != 2) return nullptr;
    return field_;
  }
  bool ArrayOther() {
    field_->array_of_other = true;
    return true;
  }
  bool Scalar(JsonField::Kind kind) {
    if (skip_ > 0) return true;
    if (InArray()) return ArrayOther();
    JsonField* f = Current();
    if (f) f->kind = kind;
    if (!f && depth_ == 0) Fail("expected a JSON array of records");
    return true;
  }
  bool Number(double v, int64_t i, bool is_integer) {
    if (skip_ > 0) return true;
    if (InArray()) {
      field_->numbers.push_back(v);
      if (array_depth_ == 2) ++field_->row_sizes.back();
      return true;
    }
    JsonField* f = Current();
    if (!f) {
      if (depth_ == 0) Fail("expected a JSON array of records, got a number");
      return true;
    }
    f->kind = JsonField::kNumber;
    f->number = v;
    f->integer = i;
    f->is_integer = is_integer;
    return true;
  }

  std::string path_;
  RecordSink* sink_;
  JsonRecord record_;
  JsonField* field_ = nullptr;
  int depth_ = 0;        // 0 outside, 1 in the top array, 2 in a record
  int array_depth_ = 0;  // nesting of arrays inside the current field
  int skip_ = 0;         // > 0 while inside an unsupported nested value
  size_t records_ = 0;
  bool finished_ = false;
  std::string last_token_;
};

// Streams one table file through `sink`; returns the file size.
size_t ParseTableFile(const std::string& path, RecordSink* sink) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec)) ThrowInputError(path, "missing table file");
  if (fs::is_directory(path, ec))
    ThrowInputError(path, "is a directory, expected a JSON table");
  const size_t bytes = fs::file_size(path, ec);
  std::ifstream in;
  std::vector<char> buffer(1 << 20);
  in.rdbuf()->pubsetbuf(buffer.data(),
                        static_cast<std::streamsize>(buffer.size()));
  in.open(path, std::ios::binary);
  if (!in) ThrowInputError(path, "cannot open table file");
  TableSax sax(path, sink);
  const bool ok = nlohmann::json::sax_parse(in, &sax);
  if (!ok || !sax.finished()) {
    ThrowInputError(
        path, "malformed JSON: not a complete array of records (after record ",
        sax.last_token().empty() ? std::string("<none>") : sax.last_token(),
        ")");
  }
  return bytes;
}

// ---------------------------------------------------------------------------------------------
// Field accessors with errors naming the table file and the record token.

class RecordReader {
 public:
  RecordReader(const std::string& path, const JsonRecord& record)
      : path_(path), record_(record) {
    const JsonField* f = record.Find("token");
    if (!f) Fail("a record has no 'token' field");
    if (f->kind != JsonField::kString || f->str.empty())
      Fail("a record has an invalid 'token'");
    token_str_ = &f->str;
    token_ = TokenFromChars(f->str.data(), f->str.size());
  }
  const NuscenesToken& token() const { return token_; }
  const std::string& token_str() const { return *token_str_; }

  template <typename... Args>
  [[noreturn]] void Error(const Args&... args) const {
    ThrowInputError(path_, "record ", *token_str_, ": ", args...);
  }

  const JsonField& Get(const char* key, JsonField::Kind kind) const {
    const JsonField* f = record_.Find(key);
    if (!f) Error("missing field '", key, "'");
    if (f->kind != kind) Error("field '", key, "' has the wrong type");
    return *f;
  }
  const JsonField* Optional(const char* key) const { return record_.Find(key); }

  std::string String(const char* key) const {
    return Get(key, JsonField::kString).str;
  }
  std::string OptionalString(const char* key) const {
    const JsonField* f = record_.Find(key);
    return f && f->kind == JsonField::kString ? f->str : std::string();
  }
  // A token reference; null and "" are the empty token.
  NuscenesToken Ref(const char* key) const {
    const JsonField* f = record_.Find(key);
    if (!f) Error("missing field '", key, "'");
    if (f->kind == JsonField::kNull) return NuscenesToken();
    if (f->kind != JsonField::kString)
      Error("field '", key, "' is not a token string");
    return TokenFromChars(f->str.data(), f->str.size());
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
    size_t start = 0;
    while (start <= p.size()) {
      size_t end = p.find_first_of("/\\", start);
      if (end == std::string::npos) end = p.size();
      if (p.compare(start, end - start, "..") == 0 && end - start == 2) {
        Error("field '", key, "' contains '..' (", p,
              "); a dataset cannot point outside its root");
      }
      start = end + 1;
    }
    return p;
  }

 private:
  [[noreturn]] void Fail(const std::string& what) const {
    ThrowInputError(path_, what);
  }
  const std::string& path_;
  const JsonRecord& record_;
  const std::string* token_str_ = nullptr;
  NuscenesToken token_;
};

// A sink that calls a lambda with a RecordReader.
template <typename Fn>
class LambdaSink : public RecordSink {
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

template <typename Fn>
size_t ParseTable(const std::string& path, Fn fn) {
  LambdaSink<Fn> sink(path, std::move(fn));
  return ParseTableFile(path, &sink);
}

SensorModality ParseModality(const std::string& s) {
  if (s == "camera") return SensorModality::kCamera;
  if (s == "lidar") return SensorModality::kLidar;
  if (s == "radar") return SensorModality::kRadar;
  return SensorModality::kUnknown;
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

// Loader state: table paths and the references pending resolution.
struct Nuscenes::LoadState {
  PendingRefs refs[kNumTables];
  std::vector<std::vector<NuscenesToken>> ann_attributes;
  std::vector<std::vector<NuscenesToken>> map_logs;
  std::string paths[kNumTables];
  bool missing[kNumTables] = {};

  // Parses table t unless it is a missing optional table; returns its bytes.
  template <typename Fn>
  size_t Parse(int t, Fn fn) {
    return missing[t] ? size_t{0} : ParseTable(paths[t], fn);
  }
  // The pending references of `table`, `per_row` per record.
  PendingRefs& Refs(int table, int per_row) {
    refs[table].per_row = per_row;
    return refs[table];
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
  size_t bytes = LoadDescriptionTables(&state);
  bytes += LoadCaptureTables(&state);
  summary_.json_bytes = bytes;
  Resolve(&state);
}

// Categories, attributes, visibilities, instances, sensors, calibrations, ego
// poses, logs and maps.
size_t Nuscenes::LoadDescriptionTables(LoadState* state) {
  const double qtol = options_.quaternion_norm_tol;
  size_t bytes = 0;
  bytes += state->Parse(kCategory, [&](const RecordReader& r) {
    NuscenesCategory c;
    c.token = r.token();
    c.name = r.String("name");
    c.description = r.OptionalString("description");
    c.index = static_cast<int>(r.OptionalInt("index", -1));
    categories_.push_back(std::move(c));
  });
  bytes += state->Parse(kAttribute, [&](const RecordReader& r) {
    NuscenesAttribute a;
    a.token = r.token();
    a.name = r.String("name");
    a.description = r.OptionalString("description");
    attributes_.push_back(std::move(a));
  });
  bytes += state->Parse(kVisibility, [&](const RecordReader& r) {
    NuscenesVisibility v;
    v.token = r.token();
    v.level = r.String("level");
    v.description = r.OptionalString("description");
    visibilities_.push_back(std::move(v));
  });
  {
    PendingRefs& p = state->Refs(kInstance, 3);
    bytes += state->Parse(kInstance, [&](const RecordReader& r) {
      NuscenesInstance in;
      in.token = r.token();
      in.nbr_annotations =
          static_cast<int>(r.OptionalInt("nbr_annotations", 0));
      p.tokens.push_back(r.Ref("category_token"));
      p.tokens.push_back(r.Ref("first_annotation_token"));
      p.tokens.push_back(r.Ref("last_annotation_token"));
      instances_.push_back(in);
    });
  }
  bytes += state->Parse(kSensor, [&](const RecordReader& r) {
    NuscenesSensor s;
    s.token = r.token();
    s.channel = r.String("channel");
    s.modality = ParseModality(r.String("modality"));
    if (s.modality == SensorModality::kUnknown)
      r.Error("unknown sensor modality");
    sensors_.push_back(std::move(s));
  });
  {
    PendingRefs& p = state->Refs(kCalibratedSensor, 1);
    bytes += state->Parse(kCalibratedSensor, [&](const RecordReader& r) {
      NuscenesCalibratedSensor c;
      c.token = r.token();
      c.ego_from_sensor =
          Rigid3d(r.Quat("rotation", qtol), r.Vec3("translation"));
      p.tokens.push_back(r.Ref("sensor_token"));
      const JsonField* k = r.Optional("camera_intrinsic");
      if (k && k->kind != JsonField::kNull) {
        if (k->kind != JsonField::kArray || k->array_of_other ||
            !k->strings.empty()) {
          r.Error("camera_intrinsic is not a 3x3 matrix or []");
        }
        if (!k->numbers.empty() || !k->row_sizes.empty()) {
          const bool ok = k->row_sizes.size() == 3 && k->row_sizes[0] == 3 &&
                          k->row_sizes[1] == 3 && k->row_sizes[2] == 3 &&
                          k->numbers.size() == 9;
          if (!ok) {
            r.Error("camera_intrinsic is not 3x3 (got ", k->row_sizes.size(),
                    " rows, ", k->numbers.size(), " values)");
          }
          for (int i = 0; i < 9; ++i) {
            if (!std::isfinite(k->numbers[i]))
              r.Error("camera_intrinsic has a non-finite value");
            c.camera_intrinsic(i / 3, i % 3) = k->numbers[i];
          }
          c.has_intrinsic = true;
        }
      }
      calibrated_sensors_.push_back(c);
    });
  }
  {
    ego_poses_.reserve(1 << 16);
    bytes += state->Parse(kEgoPose, [&](const RecordReader& r) {
      NuscenesEgoPose e;
      e.token = r.token();
      e.timestamp = r.Int("timestamp");
      e.global_from_ego =
          Rigid3d(r.Quat("rotation", qtol), r.Vec3("translation"));
      ego_poses_.push_back(e);
    });
  }
  bytes += state->Parse(kLog, [&](const RecordReader& r) {
    NuscenesLog l;
    l.token = r.token();
    l.logfile = r.OptionalString("logfile");
    l.vehicle = r.OptionalString("vehicle");
    l.date_captured = r.OptionalString("date_captured");
    l.location = r.OptionalString("location");
    logs_.push_back(std::move(l));
  });
  bytes += state->Parse(kMap, [&](const RecordReader& r) {
    NuscenesMap m;
    m.token = r.token();
    m.category = r.OptionalString("category");
    m.filename = r.RelativePath("filename");
    state->map_logs.push_back(r.RefList("log_tokens"));
    maps_.push_back(std::move(m));
  });
  return bytes;
}

// Scenes, samples, sample_data and annotations.
size_t Nuscenes::LoadCaptureTables(LoadState* state) {
  const double qtol = options_.quaternion_norm_tol;
  size_t bytes = 0;
  {
    PendingRefs& p = state->Refs(kScene, 3);
    bytes += state->Parse(kScene, [&](const RecordReader& r) {
      NuscenesScene s;
      s.token = r.token();
      s.name = r.String("name");
      s.description = r.OptionalString("description");
      s.nbr_samples = static_cast<int>(r.OptionalInt("nbr_samples", 0));
      p.tokens.push_back(r.Ref("log_token"));
      p.tokens.push_back(r.Ref("first_sample_token"));
      p.tokens.push_back(r.Ref("last_sample_token"));
      scenes_.push_back(std::move(s));
    });
  }
  {
    PendingRefs& p = state->Refs(kSample, 3);
    bytes += state->Parse(kSample, [&](const RecordReader& r) {
      NuscenesSample s;
      s.token = r.token();
      s.timestamp = r.Int("timestamp");
      p.tokens.push_back(r.Ref("scene_token"));
      p.tokens.push_back(r.Ref("prev"));
      p.tokens.push_back(r.Ref("next"));
      samples_.push_back(std::move(s));
    });
  }
  {
    PendingRefs& p = state->Refs(kSampleData, 5);
    sample_data_.reserve(1 << 16);
    bytes += state->Parse(kSampleData, [&](const RecordReader& r) {
      NuscenesSampleData d;
      d.token = r.token();
      d.timestamp = r.Int("timestamp");
      d.width = static_cast<int32_t>(r.OptionalInt("width", 0));
      d.height = static_cast<int32_t>(r.OptionalInt("height", 0));
      if (d.width < 0 || d.height < 0 || d.width > 65536 || d.height > 65536) {
        r.Error("invalid image size ", d.width, "x", d.height);
      }
      d.is_key_frame = r.Bool("is_key_frame");
      d.fileformat = r.OptionalString("fileformat");
      d.filename = r.RelativePath("filename");
      p.tokens.push_back(r.Ref("sample_token"));
      p.tokens.push_back(r.Ref("ego_pose_token"));
      p.tokens.push_back(r.Ref("calibrated_sensor_token"));
      p.tokens.push_back(r.Ref("prev"));
      p.tokens.push_back(r.Ref("next"));
      sample_data_.push_back(std::move(d));
    });
  }
  {
    PendingRefs& p = state->Refs(kSampleAnnotation, 5);
    bytes += state->Parse(kSampleAnnotation, [&](const RecordReader& r) {
      NuscenesSampleAnnotation a;
      a.token = r.token();
      a.translation = r.Vec3("translation");
      a.size = r.Vec3("size");
      if (a.size.minCoeff() < 0) r.Error("negative box size");
      a.rotation = r.Quat("rotation", qtol);
      a.num_lidar_pts = static_cast<int>(r.OptionalInt("num_lidar_pts", 0));
      a.num_radar_pts = static_cast<int>(r.OptionalInt("num_radar_pts", 0));
      p.tokens.push_back(r.Ref("sample_token"));
      p.tokens.push_back(r.Ref("instance_token"));
      p.tokens.push_back(r.Ref("visibility_token"));
      p.tokens.push_back(r.Ref("prev"));
      p.tokens.push_back(r.Ref("next"));
      state->ann_attributes.push_back(r.RefList("attribute_tokens"));
      sample_annotations_.push_back(std::move(a));
    });
  }
  return bytes;
}

// Open-addressing token -> row index of every table (duplicate tokens are an
// error naming the table).
void Nuscenes::BuildTokenIndices(const LoadState* state) {
  // Token indices.
  auto build = [&](int table, size_t n, auto token_of) {
    TokenIndex& index = index_[table];
    size_t cap = 16;
    while (cap < 2 * n) cap <<= 1;
    index.slots.assign(cap, kNoIndex);
    index.mask = cap - 1;
    for (size_t i = 0; i < n; ++i) {
      const NuscenesToken& t = token_of(static_cast<int32_t>(i));
      uint64_t h = HashToken(t) & index.mask;
      while (index.slots[h] != kNoIndex) {
        if (token_of(index.slots[h]) == t) {
          ThrowInputError(state->paths[table], "record ", t.ToString(),
                          ": duplicate token");
        }
        h = (h + 1) & index.mask;
      }
      index.slots[h] = static_cast<int32_t>(i);
    }
  };
#define GEODRIVE_BUILD_INDEX(table, rows) \
  build(table, rows.size(),               \
        [&](int32_t i) -> const NuscenesToken& { return rows[i].token; })
  GEODRIVE_BUILD_INDEX(kCategory, categories_);
  GEODRIVE_BUILD_INDEX(kAttribute, attributes_);
  GEODRIVE_BUILD_INDEX(kVisibility, visibilities_);
  GEODRIVE_BUILD_INDEX(kInstance, instances_);
  GEODRIVE_BUILD_INDEX(kSensor, sensors_);
  GEODRIVE_BUILD_INDEX(kCalibratedSensor, calibrated_sensors_);
  GEODRIVE_BUILD_INDEX(kEgoPose, ego_poses_);
  GEODRIVE_BUILD_INDEX(kLog, logs_);
  GEODRIVE_BUILD_INDEX(kScene, scenes_);
  GEODRIVE_BUILD_INDEX(kSample, samples_);
  GEODRIVE_BUILD_INDEX(kSampleData, sample_data_);
  GEODRIVE_BUILD_INDEX(kSampleAnnotation, sample_annotations_);
  GEODRIVE_BUILD_INDEX(kMap, maps_);
#undef GEODRIVE_BUILD_INDEX
}

void Nuscenes::Resolve(LoadState* state) {
  BuildTokenIndices(state);

  // Resolves a reference of `table`'s record `row` (whose token is `self`) to a
  // row of `target`.
  auto resolve = [&](int table, const NuscenesToken& self, const char* field,
                     int target, const NuscenesToken& ref,
                     bool required) -> int32_t {
    if (state->missing[target]) return kNoIndex;  // optional table absent
    if (ref.empty()) {
      if (required) {
        ThrowInputError(state->paths[table], "record ", self.ToString(), ": ",
                        field, " is empty");
      }
      return kNoIndex;
    }
    const int32_t i = Find(kTableNames[target], ref);
    if (i == kNoIndex) {
      ThrowInputError(state->paths[table], "record ", self.ToString(), ": ",
                      field, " ", ref.ToString(), " does not resolve in ",
                      kTableNames[target], ".json");
    }
    return i;
  };

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
  {
    const auto& p = state->refs[kSample].tokens;
    for (size_t i = 0; i < samples_.size(); ++i) {
      auto& s = samples_[i];
      s.scene =
          resolve(kSample, s.token, "scene_token", kScene, p[3 * i], true);
      s.prev = resolve(kSample, s.token, "prev", kSample, p[3 * i + 1], false);
      s.next = resolve(kSample, s.token, "next", kSample, p[3 * i + 2], false);
      s.data.assign(num_sensors, kNoIndex);
    }
  }
  {
    auto& p = state->refs[kSampleData].tokens;
    for (size_t i = 0; i < sample_data_.size(); ++i) {
      auto& d = sample_data_[i];
      d.sample = resolve(kSampleData, d.token, "sample_token", kSample,
                         p[5 * i], true);
      d.ego_pose = resolve(kSampleData, d.token, "ego_pose_token", kEgoPose,
                           p[5 * i + 1], true);
      d.calibrated_sensor =
          resolve(kSampleData, d.token, "calibrated_sensor_token",
                  kCalibratedSensor, p[5 * i + 2], true);
      d.prev = resolve(kSampleData, d.token, "prev", kSampleData, p[5 * i + 3],
                       false);
      d.next = resolve(kSampleData, d.token, "next", kSampleData, p[5 * i + 4],
                       false);
      d.sensor = calibrated_sensors_[d.calibrated_sensor].sensor;
      if (d.is_key_frame)
        samples_[d.sample].data[d.sensor] = static_cast<int32_t>(i);
    }
    std::vector<NuscenesToken>().swap(p);
  }
  {
    auto& p = state->refs[kSampleAnnotation].tokens;
    for (size_t i = 0; i < sample_annotations_.size(); ++i) {
      auto& a = sample_annotations_[i];
      a.sample = resolve(kSampleAnnotation, a.token, "sample_token", kSample,
                         p[5 * i], true);
      a.instance = resolve(kSampleAnnotation, a.token, "instance_token",
                           kInstance, p[5 * i + 1], true);
      a.visibility = resolve(kSampleAnnotation, a.token, "visibility_token",
                             kVisibility, p[5 * i + 2], false);
      a.prev = resolve(kSampleAnnotation, a.token, "prev", kSampleAnnotation,
                       p[5 * i + 3], false);
      a.next = resolve(kSampleAnnotation, a.token, "next", kSampleAnnotation,
                       p[5 * i + 4], false);
      for (const auto& t : state->ann_attributes[i]) {
        const int32_t at = resolve(kSampleAnnotation, a.token,
                                   "attribute_tokens", kAttribute, t, true);
        if (at != kNoIndex) a.attributes.push_back(at);
      }
      a.category = instances_[a.instance].category;
      samples_[a.sample].anns.push_back(static_cast<int32_t>(i));
    }
  }
}

int32_t Nuscenes::Find(const std::string& table,
                       const NuscenesToken& token) const {
  const int t = TableFromName(table);
  GEODRIVE_CHECK_INPUT(t >= 0, "nuScenes: unknown table '", table, "'");
  const TokenIndex& index = index_[t];
  if (index.slots.empty() || token.empty()) return kNoIndex;
  auto token_of = [&](int32_t i) -> const NuscenesToken& {
    switch (t) {
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
  };
  uint64_t h = HashToken(token) & index.mask;
  while (index.slots[h] != kNoIndex) {
    if (token_of(index.slots[h]) == token) return index.slots[h];
    h = (h + 1) & index.mask;
  }
  return kNoIndex;
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
        chain.push_back(d);
        if (chain.size() > sample_data_.size()) {
          ThrowInputError(sd_path, "record ", sample_data_[d].token.ToString(),
                          ": prev/next chain has a cycle");
        }
      }
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

// The reference JSON front end of the nuScenes table reader: nlohmann's SAX
// parser streams a table file (InputFileStream with a 1 MiB buffer, no DOM)
// into JsonRecords. This was the reader's only front end until the simdjson one
// (nuscenes_json_simd.cc); it stays as the behaviour of record for input the
// fast front end does not take (bad JSON above all: its errors are the
// reader's JSON errors). See nuscenes_json.h.

#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>

#include "dataset/internal/nuscenes_json.h"
#include "geometry/util/input_file.h"
#include "geometry/util/json_depth.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace nuscenes_json {
namespace {

// A SAX handler that turns a top-level array of flat objects into records.
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
    f->text_in_str = true;
    return true;
  }
  bool binary(json::binary_t&) { return true; }
  bool start_object(std::size_t) {
    Enter();
    if (skip_ > 0 || InArray() || depth_ >= 2) {
      if (InArray()) field_->array_of_other = true;
      if (field_ && !InArray()) field_->kind = JsonField::kOther;
      ++skip_;
      return true;
    }
    if (depth_ == 0) Fail("expected a JSON array of records, got an object");
    depth_ = 2;
    record_.Clear();
    field_ = nullptr;
    return true;
  }
  bool key(json::string_t& k) {
    if (skip_ > 0) return true;
    field_ = record_.Add(k.data(), k.size());
    return true;
  }
  bool end_object() {
    --nesting_;
    if (skip_ > 0) {
      --skip_;
      return true;
    }
    depth_ = 1;
    field_ = nullptr;
    record_.PointTextsAtStrings();
    record_.Finish();
    const JsonField* token = record_.Find("token");
    if (token && token->kind == JsonField::kString) last_token_ = token->text;
    sink_->OnRecord(record_);
    ++records_;
    return true;
  }
  bool start_array(std::size_t) {
    Enter();
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
    --nesting_;
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
    os << "malformed JSON at byte " << position << Where() << ": " << what;
    ThrowInputError(path_, os.str());
  }

 private:
  // " (in record T)", " (after record T)" or " (before the first record)".
  std::string Where() {
    const JsonField* current = depth_ == 2 ? record_.Find("token") : nullptr;
    if (current && current->kind == JsonField::kString &&
        !current->str.empty()) {
      return " (in record " + current->str + ")";
    }
    if (!last_token_.empty()) return " (after record " + last_token_ + ")";
    return " (before the first record)";
  }
  // An array or object opens: deeper than kMaxJsonDepth is an error (the
  // fast front end leaves such tables to this one).
  void Enter() {
    if (++nesting_ > kMaxJsonDepth) {
      ThrowInputError(path_, "JSON nested more than ", kMaxJsonDepth,
                      " arrays/objects deep", Where());
    }
  }
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
  int nesting_ = 0;      // arrays and objects open (the top-level one is 1)
  size_t records_ = 0;
  bool finished_ = false;
  std::string last_token_;
};

}  // namespace

size_t ParseTableFileSax(const std::string& path, RecordSink* sink) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec)) ThrowInputError(path, "missing table file");
  if (fs::is_directory(path, ec))
    ThrowInputError(path, "is a directory, expected a JSON table");
  InputFileStream in(path, size_t{1} << 20);  // refuses a FIFO or device
  const size_t bytes = static_cast<size_t>(in.size());
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

}  // namespace nuscenes_json
}  // namespace geodrive

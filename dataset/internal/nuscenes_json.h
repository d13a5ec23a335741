#pragma once
// Internal to dataset/nuscenes.cc: the two JSON front ends of the nuScenes
// table reader and the flat record they both fill.
//
// A nuScenes table is one top-level JSON array of flat objects. Both front
// ends turn each object into a JsonRecord (fields in file order, values
// classified as null / bool / number / string / array / other) and hand it to
// a RecordSink; the sink (Nuscenes' RecordReader) owns every check and every
// error message about fields, so the two front ends cannot disagree on them.
//
//  - The reference front end (nuscenes_json_sax.cc) streams a file through
//    nlohmann's SAX parser. It is the behaviour of record: it accepts exactly
//    what the reader has always accepted and its errors are the reader's JSON
//    errors ("malformed JSON at byte N (in record T): ...").
//  - The fast front end (nuscenes_json_simd.cc) cuts a file into slices of
//    whole records (TableSlicer) and parses each slice with simdjson's On
//    Demand API (SliceParser), several slices at a time on different threads.
//    It only handles input it can mirror exactly; on anything else (bad JSON,
//    a top-level value that is not an array of objects, numbers simdjson
//    rejects, a record boundary it cannot find) it reports failure and the
//    caller re-parses that table with the reference front end, which then
//    gives the reader's usual error (or, for input only nlohmann accepts, the
//    usual records). Why slices: see nuscenes_json_simd.cc.

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

namespace geodrive {
namespace nuscenes_json {

// One field of a record: its key and its value, classified.
struct JsonField {
  enum Kind { kNull, kBool, kNumber, kString, kArray, kOther };
  std::string key;
  // The key holds no '\\' or '"' and has at most 32 bytes (set with it); then
  // key32 holds it, zero-padded, for 32-byte comparisons.
  bool key_plain = false;
  alignas(16) char key32[32] = {};
  Kind kind = kNull;
  bool boolean = false;
  double number = 0;
  int64_t integer = 0;
  bool is_integer = false;  // the number is an integer in the int64 range
  // A string value (kString). The fast front end points `text` into
  // simdjson's string buffer (valid until the record has been handed on:
  // no copy); the reference one keeps the string in `str`, and
  // JsonRecord::PointTextsAtStrings points `text` at it.
  std::string_view text;
  std::string str;
  bool text_in_str = false;
  std::vector<double> numbers;  // array elements (flattened for nested arrays)
  std::vector<std::string> strings;  // array string elements (top level only)
  std::vector<int> row_sizes;   // arrays of arrays: the size of each inner one
  bool array_of_other = false;  // the array holds something else (objects,
                                // bools, nulls, strings in inner arrays, ...)

  // Resets everything but the key (buffers keep their capacity). Inline: it
  // runs for every field of every record.
  void ResetValue() {
    kind = kNull;
    boolean = false;
    number = 0;
    integer = 0;
    is_integer = false;
    text = std::string_view();
    text_in_str = false;
    if (!str.empty()) str.clear();
    if (!numbers.empty()) numbers.clear();
    if (!strings.empty()) strings.clear();
    if (!row_sizes.empty()) row_sizes.clear();
    array_of_other = false;
  }
};

// One flat record: fields in file order (keys may repeat; Find returns the
// first). A front end calls Clear(), Add() per field, then Finish() before
// handing the record on.
class JsonRecord {
 public:
  // The first field named `key`, or nullptr. `key` must be a string literal
  // (or outlive the record unchanged): Find remembers answers by its address.
  const JsonField* Find(const char* key) const {
    // The memo: the i-th Find of a finished record remembers its key (by
    // address: callers pass literals) and answer for the current key layout.
    if (finished_ && memo_next_ < memo_.size()) {
      const Memo& memo = memo_[memo_next_];
      if (memo.key == key && memo.layout == layout_) {
        ++memo_next_;
        return memo.index < 0 ? nullptr : &fields_[memo.index];
      }
    }
    return FindAndRemember(key);
  }
  // Appends a field named `key` (reusing the storage of an earlier record's
  // field) and returns it with its value reset.
  JsonField* Add(const char* key, size_t key_size) {
    finished_ = false;
    if (size_ < fields_.size()) {
      JsonField& f = fields_[size_];
      if (f.key.size() == key_size &&
          std::memcmp(f.key.data(), key, key_size) == 0) {
        ++size_;
        f.ResetValue();
        return &f;
      }
    }
    return AddNewKey(key, key_size);
  }
  // The field Add would reuse next, if its key is plain (no '\\' or '"': raw
  // JSON key bytes equal to it, then a quote, are exactly that key), else
  // nullptr. With AddSameKey, a front end can recognise a record's key by
  // comparing raw bytes, without unescaping it.
  const JsonField* NextPlainKey() const {
    if (size_ >= fields_.size() || !fields_[size_].key_plain) return nullptr;
    return &fields_[size_];
  }
  // Add(NextPlainKey()).
  JsonField* AddSameKey() {
    finished_ = false;
    JsonField& f = fields_[size_++];
    f.ResetValue();
    return &f;
  }
  void Clear();
  // For a front end that keeps strings in JsonField::str (the reference
  // one): points every such field's text at its str. Call before Finish,
  // once no field is added any more (adding may move the fields).
  void PointTextsAtStrings();
  void Finish();
  size_t size() const { return size_; }
  const JsonField& field(size_t i) const { return fields_[i]; }

 private:
  // The slow paths of Find and Add: a scan of the fields (and the memo entry
  // set), and a key that differs from the previous record's at this place.
  const JsonField* FindAndRemember(const char* key) const;
  JsonField* AddNewKey(const char* key, size_t key_size);

  std::vector<JsonField> fields_;
  size_t size_ = 0, previous_size_ = 0;
  // Find's memo. Records of one table nearly always have the same keys in the
  // same order, so Find(key) nearly always has the previous record's answer.
  // layout_ changes whenever the key sequence differs from the previous
  // record's; the i-th Find of a finished record checks the i-th memo entry
  // (same key address, same layout) before scanning the fields.
  uint64_t layout_ = 1;
  bool layout_changed_ = false, finished_ = false;
  struct Memo {
    const char* key = nullptr;
    uint64_t layout = 0;
    int index = -1;  // -1: absent
  };
  mutable std::vector<Memo> memo_;
  mutable size_t memo_next_ = 0;
};

class RecordSink {
 public:
  virtual ~RecordSink() = default;
  virtual void OnRecord(const JsonRecord& record) = 0;
};

// The reference front end: streams one table file through `sink`; returns its
// size in bytes. Throws InputError naming the file (missing, a directory,
// unreadable, malformed JSON, not an array of records).
size_t ParseTableFileSax(const std::string& path, RecordSink* sink);

// ---- The fast front end.

// One slice of a table: a JSON document "[" + whole records + "]" in a
// buffer padded for simdjson.
struct Slice {
  std::vector<char> buffer;  // the padded storage
  size_t begin = 0;          // the document is buffer[begin, begin + size)
  size_t size = 0;
  size_t index = 0;  // 0, 1, ... in file order
};

// Cuts a table file into slices of whole records of about `slice_bytes`
// each, read with pread into the caller's buffer: the file is never in memory
// as a whole. Next() is thread-safe; slices are claimed in file order (their
// bytes are read after the claim, by the claiming thread). A slice
// boundary is a "}" , "{" sequence between records; one found inside a string
// or a nested value makes simdjson reject the slice (and so the table falls
// back to the reference front end), never gives wrong records.
class TableSlicer {
 public:
  TableSlicer(const std::string& path, size_t slice_bytes);
  ~TableSlicer();
  TableSlicer(const TableSlicer&) = delete;
  TableSlicer& operator=(const TableSlicer&) = delete;

  // Fills `slice` with the next slice. False when the file is done or when it
  // cannot be sliced (then failed() is true: re-parse with the reference
  // front end).
  bool Next(Slice* slice);
  bool failed() const;
  // The file size (0 if it could not be opened).
  size_t file_bytes() const { return file_bytes_; }

 private:
  bool ReadHeader(std::vector<char>* buffer);
  bool FindSliceEnd(size_t* end, size_t* next);
  bool Fail();

  mutable std::mutex mutex_;
  int fd_ = -1;
  size_t file_bytes_ = 0;
  size_t slice_bytes_;
  size_t offset_ = 0;  // file offset of the next record's "{"
  size_t next_index_ = 0;
  bool started_ = false, done_ = false, failed_ = false;
  std::vector<char> tail_;  // FindSliceEnd's window tail
};

// Parses slices with simdjson On Demand; one per thread (it owns simdjson's
// parser and its buffers).
class SliceParser {
 public:
  SliceParser();
  ~SliceParser();
  SliceParser(const SliceParser&) = delete;
  SliceParser& operator=(const SliceParser&) = delete;

  // Calls sink->OnRecord for each record of the slice, in order; exceptions
  // of the sink pass through. Returns false if simdjson rejects the slice or
  // it holds something this front end does not mirror exactly (then
  // re-parse the table with the reference front end).
  bool Parse(const Slice& slice, RecordSink* sink);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The fast front end's slice size. 256 KiB rather than 1 MiB: each thread's
// slice and simdjson buffers are a quarter as big, and a first v1.0-mini-size
// load in a fresh process, two threads, faulted 2,000 fewer pages in (8,258 ->
// 6,215 for the whole process) at the same speed; the trainval-size load was
// no slower (docs/PERFORMANCE.md, "nuScenes reader").
constexpr size_t kDefaultSliceBytes = size_t{1} << 18;

// Testing hooks (process-wide): disable the fast front end (every table goes
// through the reference one), set the slice size (default kDefaultSliceBytes),
// and count the tables that fell back to the reference front end.
void SetFastFrontEndEnabled(bool enabled);
bool FastFrontEndEnabled();
void SetSliceBytes(size_t bytes);
size_t SliceBytes();
void CountFallback();
size_t FallbackCount();

}  // namespace nuscenes_json
}  // namespace geodrive

// JsonRecord (the flat record both JSON front ends of the nuScenes reader
// fill) and the front ends' testing hooks. See nuscenes_json.h.

#include "dataset/internal/nuscenes_json.h"

#include <atomic>
#include <cstring>

namespace geodrive {
namespace nuscenes_json {

void JsonField::ResetValue() {
  kind = kNull;
  boolean = false;
  number = 0;
  integer = 0;
  is_integer = false;
  str.clear();
  numbers.clear();
  strings.clear();
  row_sizes.clear();
  array_of_other = false;
}

void JsonRecord::Clear() {
  previous_size_ = size_;
  size_ = 0;
  layout_changed_ = false;
  finished_ = false;
}

JsonField* JsonRecord::Add(const char* key, size_t key_size) {
  finished_ = false;
  if (size_ == fields_.size()) {
    fields_.emplace_back();
    layout_changed_ = true;
  }
  JsonField& f = fields_[size_++];
  if (f.key.size() != key_size || std::memcmp(f.key.data(), key, key_size)) {
    f.key.assign(key, key_size);
    layout_changed_ = true;
  }
  f.ResetValue();
  return &f;
}

void JsonRecord::Finish() {
  if (layout_changed_ || size_ != previous_size_) ++layout_;
  layout_changed_ = false;
  previous_size_ = size_;
  finished_ = true;
  memo_next_ = 0;
}

const JsonField* JsonRecord::Find(const char* key) const {
  // The memo: the i-th Find of a finished record remembers its key (by
  // address: callers pass literals) and answer for the current key layout.
  Memo* memo = nullptr;
  if (finished_) {
    if (memo_next_ == memo_.size()) memo_.emplace_back();
    memo = &memo_[memo_next_++];
    if (memo->key == key && memo->layout == layout_) {
      return memo->index < 0 ? nullptr : &fields_[memo->index];
    }
  }
  int found = -1;
  for (size_t i = 0; i < size_; ++i) {
    if (fields_[i].key == key) {
      found = static_cast<int>(i);
      break;
    }
  }
  if (memo) {
    memo->key = key;
    memo->layout = layout_;
    memo->index = found;
  }
  return found < 0 ? nullptr : &fields_[found];
}

namespace {
std::atomic<bool> g_fast_enabled{true};
std::atomic<size_t> g_slice_bytes{size_t{1} << 20};
std::atomic<size_t> g_fallbacks{0};
}  // namespace

void SetFastFrontEndEnabled(bool enabled) { g_fast_enabled = enabled; }
bool FastFrontEndEnabled() { return g_fast_enabled; }
void SetSliceBytes(size_t bytes) { g_slice_bytes = bytes < 64 ? 64 : bytes; }
size_t SliceBytes() { return g_slice_bytes; }
void CountFallback() { ++g_fallbacks; }
size_t FallbackCount() { return g_fallbacks; }

}  // namespace nuscenes_json
}  // namespace geodrive

// JsonRecord (the flat record both JSON front ends of the nuScenes reader
// fill) and the front ends' testing hooks. See nuscenes_json.h.

#include "dataset/internal/nuscenes_json.h"

#include <atomic>
#include <cstring>

namespace geodrive {
namespace nuscenes_json {

void JsonRecord::Clear() {
  previous_size_ = size_;
  size_ = 0;
  layout_changed_ = false;
  finished_ = false;
}

JsonField* JsonRecord::AddNewKey(const char* key, size_t key_size) {
  if (size_ == fields_.size()) fields_.emplace_back();
  JsonField& f = fields_[size_++];
  f.key.assign(key, key_size);
  f.key_plain = key_size <= sizeof(f.key32) &&
                f.key.find_first_of("\\\"") == std::string::npos;
  std::memset(f.key32, 0, sizeof(f.key32));
  if (f.key_plain) std::memcpy(f.key32, key, key_size);
  layout_changed_ = true;
  f.ResetValue();
  return &f;
}

void JsonRecord::PointTextsAtStrings() {
  for (size_t i = 0; i < size_; ++i) {
    JsonField& f = fields_[i];
    if (f.text_in_str) f.text = f.str;  // after fields_ stopped moving
  }
}

void JsonRecord::Finish() {
  if (layout_changed_ || size_ != previous_size_) ++layout_;
  layout_changed_ = false;
  previous_size_ = size_;
  finished_ = true;
  memo_next_ = 0;
}

const JsonField* JsonRecord::FindAndRemember(const char* key) const {
  Memo* memo = nullptr;
  if (finished_) {
    if (memo_next_ == memo_.size()) memo_.emplace_back();
    memo = &memo_[memo_next_++];
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
std::atomic<size_t> g_slice_bytes{kDefaultSliceBytes};
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

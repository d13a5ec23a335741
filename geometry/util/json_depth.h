#pragma once
// The JSON depth limit: every JSON reader of the toolkit stops at the first
// array or object nested more than kMaxJsonDepth deep, with one InputError
// naming the file (docs/RELIABILITY.md, "Parsers with unbounded cost").
// Internal: includes nlohmann/json, so only .cc files include it.
//
// Why. A parser or a walk over the parsed value that recurses per level
// (simdjson On Demand walks, nlohmann's dump(), copies and comparisons) runs
// out of stack on input such as 110,000 "[": a crash, not an error. The
// deepest file we read legitimately is 4 levels deep (a nuScenes
// camera_intrinsic: table array, record, matrix, row; meta.json and the
// safetensors headers are 3), so 64 leaves room for any future field and
// bounds every recursion at a few kilobytes of stack.
//
// How. Readers that build a DOM parse with ParseJson (nlohmann's SAX
// parser, which does not recurse, feeding nlohmann's own DOM builder through
// a depth counter); the nuScenes table front ends count the depth themselves
// (dataset/internal/nuscenes_json*.cc) against the same constant.

#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>

#include "geometry/util/status.h"

namespace geodrive {

// The deepest nesting of arrays and objects any JSON reader accepts: the
// top-level value is depth 1.
constexpr int kMaxJsonDepth = 64;

namespace internal {

// The error every reader gives for nesting deeper than kMaxJsonDepth.
[[noreturn]] inline void ThrowJsonTooDeep(const std::string& path) {
  ThrowInputError(path, "JSON nested more than ", kMaxJsonDepth,
                  " arrays/objects deep (the limit of every JSON reader)");
}

// nlohmann's DOM builder behind a depth counter: the first array or object
// deeper than kMaxJsonDepth throws ThrowJsonTooDeep. Parse errors throw
// nlohmann's parse_error, as json::parse does. Derived SAX handlers may add
// checks (they are called statically: sax_parse is a template on the handler
// type).
class DepthLimitedJsonSax
    : public nlohmann::detail::json_sax_dom_parser<nlohmann::json> {
 public:
  using Base = nlohmann::detail::json_sax_dom_parser<nlohmann::json>;
  DepthLimitedJsonSax(nlohmann::json* root, std::string path)
      : Base(*root, /*allow_exceptions_=*/true), path_(std::move(path)) {}

  bool start_object(std::size_t n) {
    Enter();
    return Base::start_object(n);
  }
  bool start_array(std::size_t n) {
    Enter();
    return Base::start_array(n);
  }
  bool end_object() {
    --depth_;
    return Base::end_object();
  }
  bool end_array() {
    --depth_;
    return Base::end_array();
  }
  // Arrays and objects open at this point of the parse.
  int depth() const { return depth_; }
  const std::string& path() const { return path_; }

 private:
  void Enter() {
    if (++depth_ > kMaxJsonDepth) ThrowJsonTooDeep(path_);
  }

  std::string path_;
  int depth_ = 0;
};

// json::parse(input) with the depth limit; `input` is anything
// nlohmann::json::sax_parse reads (a stream, a string, a string_view).
// Malformed JSON throws nlohmann's parse_error as json::parse does; nesting
// deeper than kMaxJsonDepth throws InputError naming `path`.
template <typename Input>
nlohmann::json ParseJson(Input&& input, const std::string& path) {
  nlohmann::json root;
  DepthLimitedJsonSax sax(&root, path);
  nlohmann::json::sax_parse(std::forward<Input>(input), &sax);
  return root;
}

}  // namespace internal
}  // namespace geodrive

#pragma once
// Error types shared by every module.
//
// Convention (docs/reference/exit-codes.md): bad user input -- a missing or
// malformed file, an invalid option value, an inconsistent dataset -- throws
// InputError with a message that names the file (or table/record) and what is
// wrong. The CLI maps InputError to exit code 2 and anything else to exit code
// 1 (internal failure). Internal invariants use glog's CHECK.

#include <sstream>
#include <stdexcept>
#include <string>

namespace geodrive {

// Thrown for bad input (files, arguments, options). The message is one line,
// user facing.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

namespace internal {
template <typename... Args>
std::string StrCat(const Args&... args) {
  std::ostringstream os;
  (os << ... << args);
  return os.str();
}
}  // namespace internal

// Throws InputError("<what>: <message parts...>"), e.g. ThrowInputError(path,
// "truncated").
template <typename... Args>
[[noreturn]] void ThrowInputError(const std::string& what,
                                  const Args&... args) {
  throw InputError(what + ": " + internal::StrCat(args...));
}

}  // namespace geodrive

// Throws InputError(StrCat(args...)) when `cond` is false. For caller/user
// input only.
#define GEODRIVE_CHECK_INPUT(cond, ...)                                        \
  do {                                                                         \
    if (!(cond))                                                               \
      throw ::geodrive::InputError(::geodrive::internal::StrCat(__VA_ARGS__)); \
  } while (0)

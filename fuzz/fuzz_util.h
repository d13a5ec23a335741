#pragma once
// Shared by the libFuzzer targets in this folder (docs/RELIABILITY.md).
//
// Our readers take paths, as users call them, so each target writes the fuzz
// input to one file per process (under $TMPDIR, /tmp by default) and calls the
// reader on it. The contract under test: a reader either returns or throws
// geodrive::InputError. Anything else -- another exception type, a crash, a
// sanitizer report, a glog CHECK, a hang or an allocation beyond libFuzzer's
// -malloc_limit_mb -- is a finding.

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "geometry/util/status.h"

namespace geodrive {
namespace fuzz {

// A per-process path ending in `name` (the readers dispatch on extensions).
inline std::string InputPath(const std::string& name) {
  const char* tmp = std::getenv("TMPDIR");
  return std::string(tmp && *tmp ? tmp : "/tmp") + "/geodrive_fuzz_" +
         std::to_string(::getpid()) + "_" + name;
}

// Writes `size` bytes to `path` (aborts if it cannot: a broken fuzzing set-up,
// not a finding).
inline void WriteInput(const std::string& path,
                       const uint8_t* data,
                       size_t size) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) std::abort();
  if (size > 0 && std::fwrite(data, 1, size, f) != size) std::abort();
  std::fclose(f);
}

// Runs `read`, accepting InputError (the documented failure) only.
template <typename F>
void ExpectReturnOrInputError(F&& read) {
  try {
    read();
  } catch (const InputError&) {
  }
}

}  // namespace fuzz
}  // namespace geodrive

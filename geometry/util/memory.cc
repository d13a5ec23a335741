#include "geometry/util/memory.h"

#include <cstdlib>
#include <cstring>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace geodrive {

bool ConfigureAllocatorForThroughput() {
  const char* skip = std::getenv("GEODRIVE_MALLOC_DEFAULTS");
  if (skip != nullptr && std::strcmp(skip, "1") == 0) return false;
#if defined(__GLIBC__)
  // 32 MiB is glibc's largest mmap threshold on 64-bit (HEAP_MAX_SIZE / 2).
  const bool mmap_ok = mallopt(M_MMAP_THRESHOLD, 32 << 20) == 1;
  const bool trim_ok = mallopt(M_TRIM_THRESHOLD, 1 << 30) == 1;
  return mmap_ok && trim_ok;
#else
  return false;
#endif
}

}  // namespace geodrive

#include "geometry/util/memory.h"

#include <sys/resource.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

// Under AddressSanitizer malloc is the sanitizer's, not glibc's (mallopt is a
// no-op that fails): the policy does not apply.
#if defined(__SANITIZE_ADDRESS__)
#define GEODRIVE_GLIBC_MALLOC 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define GEODRIVE_GLIBC_MALLOC 0
#endif
#endif
#if !defined(GEODRIVE_GLIBC_MALLOC)
#if defined(__GLIBC__)
#define GEODRIVE_GLIBC_MALLOC 1
#else
#define GEODRIVE_GLIBC_MALLOC 0
#endif
#endif

namespace geodrive {

bool UsesGlibcMalloc() { return GEODRIVE_GLIBC_MALLOC != 0; }

bool ConfigureAllocatorForThroughput() {
  const char* skip = std::getenv("GEODRIVE_MALLOC_DEFAULTS");
  if (skip != nullptr && std::strcmp(skip, "1") == 0) return false;
#if GEODRIVE_GLIBC_MALLOC
  // 32 MiB is glibc's largest mmap threshold on 64-bit (HEAP_MAX_SIZE / 2).
  const bool mmap_ok = mallopt(M_MMAP_THRESHOLD, 32 << 20) == 1;
  const bool trim_ok = mallopt(M_TRIM_THRESHOLD, 1 << 30) == 1;
  return mmap_ok && trim_ok;
#else
  return false;
#endif
}

namespace {

// The value of `key` (in kB) in a /proc file of "Key:   123 kB" lines, in
// bytes; 0 when absent.
uint64_t ProcKilobytes(const char* file, const std::string& key) {
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    if (line.compare(0, key.size(), key) != 0) continue;
    std::istringstream ss(line.substr(key.size()));
    uint64_t kb = 0;
    if (ss >> kb) return kb * 1024;
  }
  return 0;
}

// A cgroup v2 file holding one number (or "max"); UINT64_MAX when absent or
// "max".
uint64_t CgroupValue(const char* file) {
  std::ifstream in(file);
  std::string text;
  if (!(in >> text) || text == "max") {
    return std::numeric_limits<uint64_t>::max();
  }
  return std::strtoull(text.c_str(), nullptr, 10);
}

}  // namespace

uint64_t AvailableMemoryBytes() {
  constexpr uint64_t kUnknown = std::numeric_limits<uint64_t>::max();
  uint64_t available = kUnknown;
  const uint64_t mem_available =
      ProcKilobytes("/proc/meminfo", "MemAvailable:");
  if (mem_available > 0) available = mem_available;
  rlimit limit{};
  if (getrlimit(RLIMIT_AS, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY) {
    const uint64_t used = ProcKilobytes("/proc/self/status", "VmSize:");
    const uint64_t cap = static_cast<uint64_t>(limit.rlim_cur);
    available = std::min(available, cap > used ? cap - used : 0);
  }
  if (getrlimit(RLIMIT_DATA, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY) {
    const uint64_t used = ProcKilobytes("/proc/self/status", "VmData:");
    const uint64_t cap = static_cast<uint64_t>(limit.rlim_cur);
    available = std::min(available, cap > used ? cap - used : 0);
  }
  const uint64_t cgroup_max = CgroupValue("/sys/fs/cgroup/memory.max");
  if (cgroup_max != kUnknown) {
    const uint64_t current = CgroupValue("/sys/fs/cgroup/memory.current");
    if (current != kUnknown) {
      available =
          std::min(available, cgroup_max > current ? cgroup_max - current : 0);
    }
  }
  return available;
}

}  // namespace geodrive

#pragma once
// Process-wide allocator policy for throughput.
//
// With glibc's defaults, large blocks (frames, packed clouds, scratch) are
// returned to the operating system when freed (mmap threshold 128 KiB, raised
// dynamically; heap tops trimmed past ~2x that), so a loop that renders clip
// after clip page-faults every output byte again: on a 2-vCPU development
// machine about half of a 25-frame render was kernel page-fault time, and two
// threads faulting at once contend in the kernel.
// `ConfigureAllocatorForThroughput` keeps freed memory in the process for reuse
// instead: blocks up to 32 MiB come from the heap and heap tops are trimmed
// only past 1 GiB of free space. Peak memory is unchanged; memory freed after a
// peak is held (up to the trim threshold) until the process exits. The
// `geodrive` and `geodrive-diffusion` binaries and the render benchmarks call
// it first thing; library code never does. Setting GEODRIVE_MALLOC_DEFAULTS=1
// in the environment skips it.

#include <cstdint>

namespace geodrive {

// Applies the policy above (glibc mallopt); returns false where it is not
// supported (not glibc's malloc, e.g. under AddressSanitizer) or was skipped
// by GEODRIVE_MALLOC_DEFAULTS=1. UsesGlibcMalloc() says which.
bool ConfigureAllocatorForThroughput();
// True when this build allocates through glibc's malloc (where the policy
// applies).
bool UsesGlibcMalloc();

// Bytes this process can still allocate, as far as the system says: the
// smallest of the memory the kernel reports available (/proc/meminfo
// MemAvailable), the address-space and data-segment limits (`ulimit -v`,
// `ulimit -d`) less what the process already uses, and the cgroup's
// memory.max less memory.current. UINT64_MAX when none of these is known.
// Commands that would hold large buffers check their estimate against it
// and refuse with a clear message instead of dying on std::bad_alloc.
uint64_t AvailableMemoryBytes();

}  // namespace geodrive

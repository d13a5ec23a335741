#include "geometry/util/memory.h"

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <cstdlib>
#include <memory>
#include <vector>

namespace geodrive {
namespace {

long MinorFaults() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_minflt;
}

// Allocates, touches and frees 40 blocks of 1 MiB (like the frames of a
// render); returns the minor page faults it took.
long FrameLikeRound() {
  constexpr size_t kBlock = 1 << 20;
  const long before = MinorFaults();
  {
    std::vector<std::unique_ptr<char[]>> blocks;
    for (int b = 0; b < 40; ++b) {
      blocks.emplace_back(new char[kBlock]);
      for (size_t i = 0; i < kBlock; i += 4096) blocks.back()[i] = 1;
    }
    volatile char sink = blocks[7][4096];
    (void)sink;
  }
  return MinorFaults() - before;
}

TEST(Memory, EnvironmentVariableKeepsTheDefaults) {
  setenv("GEODRIVE_MALLOC_DEFAULTS", "1", 1);
  EXPECT_FALSE(ConfigureAllocatorForThroughput());
  unsetenv("GEODRIVE_MALLOC_DEFAULTS");
}

TEST(Memory, FreedFrameBlocksAreReusedWithoutPageFaults) {
  if (!UsesGlibcMalloc()) {
    // The policy is glibc's mallopt: elsewhere (another libc, or under
    // AddressSanitizer's allocator) the call says it did nothing.
    EXPECT_FALSE(ConfigureAllocatorForThroughput());
    return;
  }
  ASSERT_TRUE(ConfigureAllocatorForThroughput());
  FrameLikeRound();  // the heap grows once
  FrameLikeRound();
  const long faults = FrameLikeRound();
  // 40 MiB touched = 10240 pages; with glibc's defaults every round faults
  // (nearly) all of them again, as the freed heap top is trimmed.
  std::printf("minor page faults in a third round of 40 x 1 MiB: %ld\n",
              faults);
  EXPECT_LT(faults, 10240 / 20);
}

}  // namespace
}  // namespace geodrive

#pragma once
// main() of the render benchmarks: Google Benchmark's, after applying the
// allocator policy of the geodrive binaries (geometry/memory.h), so freed
// frames are reused instead of page-faulted again on every iteration, as in
// `geodrive render`.

#include <benchmark/benchmark.h>

#include "geometry/util/memory.h"

#define GEODRIVE_BENCHMARK_MAIN()                                     \
  int main(int argc, char** argv) {                                   \
    geodrive::ConfigureAllocatorForThroughput();                      \
    benchmark::Initialize(&argc, argv);                               \
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1; \
    benchmark::RunSpecifiedBenchmarks();                              \
    benchmark::Shutdown();                                            \
    return 0;                                                         \
  }                                                                   \
  int main(int, char**)

#pragma once
// Function multiversioning for the hot loops (image resampling, the builder's
// PSNR, the metrics): GCC compiles a function once per listed target and the
// loader picks the clone the CPU supports (an ifunc), so one binary runs AVX2
// code where the CPU has it and the baseline elsewhere.

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && \
    defined(__linux__)
// An AVX2 clone and the baseline one.
#define GEODRIVE_AVX2_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define GEODRIVE_AVX2_CLONES
#endif

// For the helpers of a cloned function: force-inlined into each clone. A
// helper that is only `inline` is compiled once, for the baseline target, and
// every clone would call that one.
#if defined(__GNUC__)
#define GEODRIVE_FORCE_INLINE inline __attribute__((always_inline))
#else
#define GEODRIVE_FORCE_INLINE inline
#endif

#pragma once

// Which vector kernels a build can compile beside its baseline, for the run-time choice (no
// intrinsics here: algo/flow/lk_kernels_neon32.cpp reads these before its target pragma).

// EPITRACK_LK_NEON_ARMV7: 32-bit ARM with GCC, which compiles NEON functions (target pragma) into
// a baseline build (algo/flow/lk_kernels_neon32.cpp); they run only where the processor has NEON.
#if defined(__arm__) && !defined(__aarch64__) && defined(__GNUC__) && !defined(__clang__) && \
    defined(__linux__)
#define EPITRACK_LK_NEON_ARMV7 1
#else
#define EPITRACK_LK_NEON_ARMV7 0
#endif

// EPITRACK_LK_AVX2: x86-64 with GCC or Clang, which compile AVX2 functions (target attribute) into
// a baseline build; they run only where the processor has AVX2 (checked at run time).
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define EPITRACK_LK_AVX2 1
#else
#define EPITRACK_LK_AVX2 0
#endif

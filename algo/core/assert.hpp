#pragma once

// One project macro for programmer errors (a broken precondition, never bad user input).
// Bad input is reported through status values; EPITRACK_ASSERT aborts with the location, or
// compiles to nothing when EPITRACK_DISABLE_ASSERTS is defined.

#include <cstdio>
#include <cstdlib>

#if defined(EPITRACK_DISABLE_ASSERTS)
#define EPITRACK_ASSERT(cond) ((void)0)
#else
#define EPITRACK_ASSERT(cond)                                                                      \
  do {                                                                                             \
    if (!(cond)) {                                                                                 \
      std::fprintf(stderr, "epitrack: assertion failed: %s (%s:%d)\n", #cond, __FILE__, __LINE__); \
      std::abort();                                                                                \
    }                                                                                              \
  } while (0)
#endif

#pragma once

// Shared by the libFuzzer harnesses of tests/fuzz: an invariant check that aborts (libFuzzer
// reports an abort as a crash and keeps the input) and the size cap of decoded images.

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>

#include "algo/image/image_view.hpp"

/// Aborts with the failed condition when an invariant of the code under test does not hold.
#define FUZZ_CHECK(condition)                                                                 \
  do {                                                                                        \
    if (!(condition)) {                                                                       \
      std::fprintf(stderr, "%s:%d: FUZZ_CHECK failed: %s\n", __FILE__, __LINE__, #condition); \
      std::abort();                                                                           \
    }                                                                                         \
  } while (false)

namespace epitrack::fuzz {

/// Decoded images larger than this are not decoded by the harnesses (headers up to the readers'
/// own limit of 16384 x 16384 are still parsed): a 1-megapixel cap keeps each run fast and within
/// libFuzzer's memory limit, and no reader has a code path that only larger images reach.
inline constexpr std::int64_t kMaxFuzzPixels = std::int64_t{1} << 20;

[[nodiscard]] inline bool smallEnough(int width, int height) {
  return width > 0 && height > 0 &&
         static_cast<std::int64_t>(width) * static_cast<std::int64_t>(height) <= kMaxFuzzPixels;
}

[[nodiscard]] inline bool sameView(ImageView<const uint8_t> a, ImageView<const uint8_t> b) {
  if (a.width != b.width || a.height != b.height) return false;
  for (int y = 0; y < a.height; ++y) {
    for (int x = 0; x < a.width; ++x) {
      if (a(x, y) != b(x, y)) return false;
    }
  }
  return true;
}

}  // namespace epitrack::fuzz

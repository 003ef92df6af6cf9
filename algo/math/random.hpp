#pragma once

#include <cstdint>

namespace epitrack {

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny generator whose sequence for a seed is the same on
/// every platform and standard library (unlike std::uniform_int_distribution), which makes RANSAC
/// samples, and so every solve, reproducible across x86-64 and ARM.
class SplitMix64 {
 public:
  explicit SplitMix64(uint64_t seed = 0x9e3779b97f4a7c15ULL) : state_(seed) {}

  uint64_t next() {
    uint64_t z = (state_ += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30U)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27U)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31U);
  }

  /// Uniform integer in [0, n) by Lemire's multiply-shift (bias below 2^-32 for the n used here).
  uint32_t below(uint32_t n) {
    return static_cast<uint32_t>(((next() >> 32U) * static_cast<uint64_t>(n)) >> 32U);
  }

  /// Uniform double in [0, 1) from the top 53 bits.
  double uniform() { return static_cast<double>(next() >> 11U) * 0x1.0p-53; }

 private:
  uint64_t state_;
};

}  // namespace epitrack

#pragma once

#include <cstdint>

namespace epitrack::synth {

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny generator whose sequence is defined by integer
/// arithmetic alone, hence the same on every platform. Used for scene layout, textures and noise.
class SplitMix64 {
 public:
  explicit SplitMix64(uint64_t seed) : state_(seed) {}
  uint64_t next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  /// Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(next() >> 11) * (1.0 / 9007199254740992.0); }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  /// Integer in [lo, hi].
  int uniformInt(int lo, int hi) {
    return lo + static_cast<int>(next() % static_cast<uint64_t>(hi - lo + 1));
  }
  /// Approximately standard normal: the Irwin-Hall sum of 12 uniforms minus 6 (mean 0, variance 1,
  /// bounded at +-6). Integer sums keep it platform-exact without log/cos.
  double gaussian() {
    uint64_t sum = 0;
    for (int i = 0; i < 12; ++i) sum += next() >> 32;  // 12 * 2^32 fits easily
    return static_cast<double>(sum) * (1.0 / 4294967296.0) - 6.0;
  }

 private:
  uint64_t state_;
};

/// Mixes several integers into one seed (so frame i of seed s has its own noise stream).
inline uint64_t mixSeed(uint64_t a, uint64_t b) {
  SplitMix64 g(a * 0x9E3779B97F4A7C15ull ^ (b + 0x632BE59BD9B4E019ull));
  return g.next();
}

}  // namespace epitrack::synth

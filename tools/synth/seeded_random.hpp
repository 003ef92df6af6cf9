#pragma once

// Seeded random draws for synthetic scenes (tests, benchmarks) that are bit-identical on x86-64
// and aarch64.
//
// Two rules make a seeded scene portable:
//  1. Draw from SplitMix64 (algo/math/random.hpp) or synth::SplitMix64 (tools/synth/random.hpp),
//     never through std::*_distribution (their algorithms differ between standard libraries).
//  2. Never make two draws in one expression: the order in which function arguments are evaluated
//     is unspecified, and GCC evaluates them right to left on x86-64 but left to right on aarch64,
//     so `Eigen::Vector3d(rng.uniform(), rng.uniform(), rng.uniform())` gives different points on
//     the two machines. Draw into named variables, one statement each. (That, not the
//     distributions, is why the geometry tests used to fail under qemu-aarch64.)
//
// The scenes of the existing tests were tuned on x86-64, so where they were rewritten the draws
// keep the order x86-64 used: the last argument first.

#include <algorithm>
#include <cmath>

#include "algo/math/random.hpp"

namespace epitrack::scenes {

/// Standard normal draw by Box-Muller from two uniforms (u1 drawn first). sqrt is exact in IEEE
/// arithmetic; glibc's log and cos gave identical bits on x86-64 and aarch64 for 10^6 draws.
inline double standardNormal(epitrack::SplitMix64& rng) {
  const double u1 = std::max(rng.uniform(), 1e-300);
  const double u2 = rng.uniform();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

}  // namespace epitrack::scenes

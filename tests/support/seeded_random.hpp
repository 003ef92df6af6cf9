#pragma once

// The portable seeded draws live with the synthetic scenes (tools/synth/seeded_random.hpp: the
// rules that keep a scene bit-identical on x86-64 and aarch64); the tests use them by these names.

#include "tools/synth/seeded_random.hpp"

namespace epitrack::test {
using scenes::standardNormal;
}  // namespace epitrack::test

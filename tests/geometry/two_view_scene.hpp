#pragma once

// The seeded two-view scenes live in tools/synth/two_view_scene.hpp (the benchmarks use them
// too, and nothing outside tests/ includes from it); the tests use them by these names.

#include "tools/synth/two_view_scene.hpp"

namespace epitrack::test {
using namespace epitrack::scenes;  // NOLINT(google-build-using-namespace): the tests' names
}  // namespace epitrack::test

// Linked into every test binary (tests/CMakeLists.txt epitrack_test): before any test runs, the
// LK kernels are chosen for this processor, as every program that tracks does at start
// (hal::selectKernelsForThisCpu), so the tests exercise the kernels the programs run (NEON on an
// ARMv7 that has it).
#include "hal/cpu/cpu_features.hpp"

namespace {

// A static object: its initialiser runs before Catch2's main (the kernel choice in algo is a
// constant-initialised flag, so the order against other static initialisers does not matter).
[[maybe_unused]] const bool kKernelsSelected = [] {
  epitrack::hal::selectKernelsForThisCpu();
  return true;
}();

}  // namespace

#pragma once

// What the processor offers beyond the build's baseline, read from the platform (the kernel's
// auxiliary vector) and handed to algo, which reads no system state (ARCHITECTURE.md "Folders").

#include "algo/flow/lk_kernels.hpp"

namespace epitrack::hal {

/// The vector instruction set this processor adds to the build's baseline for the LK kernels:
/// kNeon on a 32-bit ARM build (GCC, Linux) whose kernel reports NEON (getauxval(AT_HWCAP)),
/// since Debian's armhf baseline does not include it; kBaseline everywhere else (every aarch64
/// has NEON in its baseline, and x86-64 builds ask cpuid for AVX2 themselves).
CpuVectorIsa cpuVectorIsa();

/// Chooses the LK kernels for this processor: lkSelectKernels(cpuVectorIsa()). Every program
/// that tracks calls it once at start, before any tracking; without it a 32-bit ARM build runs
/// the scalar kernels (the same sums, bit for bit, only slower).
void selectKernelsForThisCpu();

}  // namespace epitrack::hal

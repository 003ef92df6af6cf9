// The 128-bit LK kernels for 32-bit ARM with NEON, compiled into the baseline armhf build (Debian's
// armv7-a+fp, VFPv3-D16, no NEON) and run only where the kernel reports NEON (lkHaveNeon, set by
// lkSelectKernels from hal::cpuVectorIsa()), as the AVX2 kernels are on x86-64. The kernel bodies
// are lk_kernels_simd128.hpp's, over simd_int16.hpp's NEON operations in their ARMv7 spelling, so
// the sums are the scalar kernel's bit for bit.
//
// Everything this file includes from the standard library and the project comes before the target
// pragma and is compiled for the baseline: only the kernels and the vector operations, which have
// internal linkage or exist in this file alone, are compiled for NEON, so no inline function that
// other files share (whose one copy the linker keeps) can carry NEON instructions.
#include "algo/flow/lk_kernels.hpp"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>

#include "algo/flow/simd_isa.hpp"

#if EPITRACK_LK_NEON_ARMV7

#include "algo/flow/lk_kernels_arm.hpp"

#pragma GCC push_options
#pragma GCC target("fpu=neon")
// simd_int16.hpp's NEON operations, in their ARMv7 spelling (see EPITRACK_SIMD_ARMV7_NEON there).
#define EPITRACK_SIMD_ARMV7_NEON 1
#include "algo/flow/lk_kernels_simd128.hpp"
#include "algo/flow/simd_int16.hpp"

namespace epitrack::armv7 {

void translationSumsNeon(const uint8_t* image, std::ptrdiff_t stride, int side, const LkBilinear& w,
                         const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                         LkWindowSums& out) {
  translationSums128(image, stride, side, w, T, Sx, Sy, tstride, out);
}

void affineSumsNeon(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                    const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                    LkAffineSums& out) {
  affineSums128(image, warp, side, T, Sx, Sy, tstride, out);
}

}  // namespace epitrack::armv7
#pragma GCC pop_options

#endif

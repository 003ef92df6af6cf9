#pragma once

// The ARMv7 NEON LK kernels (lk_kernels_neon32.cpp): the 128-bit kernels of
// lk_kernels_simd128.hpp compiled for NEON in a baseline armhf build, called by
// lkTranslationSumsVector and lkAffineSums128 only where lkHaveNeon() holds.

#include "algo/flow/lk_kernels.hpp"

namespace epitrack::armv7 {

void translationSumsNeon(const uint8_t* image, std::ptrdiff_t stride, int side, const LkBilinear& w,
                         const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                         LkWindowSums& out);
void affineSumsNeon(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                    const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                    LkAffineSums& out);

}  // namespace epitrack::armv7

#pragma once

// What the x86 affine LK kernels (lk_kernels_avx2.cpp, lk_kernels_avx512.cpp) share: the plan of a
// window (compiled for the baseline ISA).

#include "algo/flow/lk_kernels.hpp"

namespace epitrack::x86 {

/// False when the window needs lkAffineSums128 (beyond 80 pixels, or a gather's 4-byte read could
/// pass the end of the image's last row); else `shuffle` tells whether every group of 8 pixels
/// spans at most 15 columns and 2 rows that may be read whole (row loads and byte shuffles),
/// else gathers.
bool affinePlan(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side, bool& shuffle);

}  // namespace epitrack::x86

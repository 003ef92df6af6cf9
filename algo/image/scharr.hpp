#pragma once

#include <cstdint>

#include "algo/image/image_view.hpp"

namespace epitrack {

/// Scharr derivatives (Scharr 2000; the kernel OpenCV's LK uses):
///   dx = [-3 0 3; -10 0 10; -3 0 3] * I,  dy = its transpose,
/// unnormalised (|d| <= 16 * 255 = 4080, so int16_t holds it; divide by 32 for intensity per
/// pixel). Border: reflect-101. `dx` and `dy` must have `src`'s size. Never allocates.
/// SSE2 / NEON where available (algo/flow/simd_int16.hpp), the same values as the scalar reference.
void scharrGradients(ImageView<const uint8_t> src, ImageView<int16_t> dx, ImageView<int16_t> dy);
/// The scalar reference of scharrGradients.
void scharrGradientsScalar(ImageView<const uint8_t> src, ImageView<int16_t> dx,
                           ImageView<int16_t> dy);

}  // namespace epitrack

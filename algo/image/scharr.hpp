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
/// scharrGradients on the pixels [x0, x1) x [y0, y1) only (clipped to the image), each the value
/// the whole-image call gives it (its neighbours read from `src`, reflected only at the image's
/// edges); the other pixels of dx, dy are left as they are. Without SIMD: the whole image.
void scharrGradientsRegion(ImageView<const uint8_t> src, ImageView<int16_t> dx,
                           ImageView<int16_t> dy, int x0, int y0, int x1, int y1);
/// The scalar reference of scharrGradients.
void scharrGradientsScalar(ImageView<const uint8_t> src, ImageView<int16_t> dx,
                           ImageView<int16_t> dy);

}  // namespace epitrack

#pragma once

// The inner loop of the translation Lucas-Kanade iteration (PyramidalLk::alignLevel): one
// bilinear pass over the window and the window sums of the Gauss-Newton right-hand side. A
// scalar reference and a vector variant (SSE2 / NEON through algo/flow/simd_int16.hpp) that
// computes the same integers in the same fixed-point formats, so their sums agree bit for bit
// (tests/tracker/lk_kernels_test.cpp).

#include <cstddef>
#include <cstdint>

namespace epitrack {

/// Fixed-point formats of the LK kernels (after OpenCV's lkpyramid W_BITS): bilinear weights in
/// kLkWeightBits = 14 fractional bits, the fourth weight the remainder so the four sum exactly to
/// 1 << 14; samples and template values in kLkValueBits = 5 fractional bits (gray * 32, at most
/// 8160, so an error e = sample - template fits int16); gradients are unnormalised Scharr (32 x
/// the intensity gradient, |g| <= 4080).
constexpr int kLkWeightBits = 14;
constexpr int kLkValueBits = 5;

/// Bilinear weights of one sub-pixel position, kLkWeightBits each, w00 + w01 + w10 + w11 =
/// 1 << kLkWeightBits (w01: the right neighbour, w10: the one below).
struct LkBilinear {
  int32_t w00 = 1 << kLkWeightBits;
  int32_t w01 = 0;
  int32_t w10 = 0;
  int32_t w11 = 0;
};
/// The weights for fractional offsets (ax, ay) in [0, 1 << kLkWeightBits].
inline LkBilinear lkBilinear(int32_t ax, int32_t ay) {
  constexpr int32_t kOne = 1 << kLkWeightBits;
  LkBilinear w;
  w.w00 = ((kOne - ax) * (kOne - ay) + (kOne >> 1)) >> kLkWeightBits;
  w.w01 = (ax * (kOne - ay) + (kOne >> 1)) >> kLkWeightBits;
  w.w10 = ((kOne - ax) * ay + (kOne >> 1)) >> kLkWeightBits;
  w.w11 = kOne - w.w00 - w.w01 - w.w10;  // the four sum exactly to 1 << kLkWeightBits
  return w;
}

/// Window sums of one translation iteration, e = sample - template (1/32 gray levels).
struct LkWindowSums {
  int64_t gx_e = 0;    ///< sum Sx * e
  int64_t gy_e = 0;    ///< sum Sy * e
  int64_t sum_e = 0;   ///< sum e
  int64_t sum_sq = 0;  ///< sum e^2
};

/// One pass over a side x side window. `image`: the window's top-left pixel (side + 1 columns
/// and rows are read, for the bilinear neighbours); `T`, `Sx`, `Sy`: template values and
/// gradients, rows of `tstride` int16 (tstride a multiple of 8 and >= side, the columns beyond
/// `side` zero). The sums are exact: every product fits int32 (|Sx e| <= 4080 x 8160,
/// e^2 <= 8160^2); the scalar kernel adds them in int64, the vector kernel in int32 lanes per
/// row (exact up to side 120, beyond which it calls the scalar kernel), then in int64.
void lkTranslationSumsScalar(const uint8_t* image, std::ptrdiff_t stride, int side,
                             const LkBilinear& w, const int16_t* T, const int16_t* Sx,
                             const int16_t* Sy, int tstride, LkWindowSums& out);
/// The same with 128-bit integer vectors; the scalar kernel where there are none.
void lkTranslationSumsVector(const uint8_t* image, std::ptrdiff_t stride, int side,
                             const LkBilinear& w, const int16_t* T, const int16_t* Sx,
                             const int16_t* Sy, int tstride, LkWindowSums& out);
/// "sse2", "neon" or "scalar": what lkTranslationSumsVector uses on this build.
const char* lkVectorIsa();

}  // namespace epitrack

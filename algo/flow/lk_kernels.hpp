#pragma once

// The inner loop of the translation Lucas-Kanade iteration (PyramidalLk::alignLevel): one
// bilinear pass over the window and the window sums of the Gauss-Newton right-hand side. A
// scalar reference and a vector variant (SSE2 / NEON through algo/flow/simd_int16.hpp) that
// computes the same integers in the same fixed-point formats, so their sums agree bit for bit
// (tests/tracker/lk_kernels_test.cpp).

#include <cstddef>
#include <cstdint>

#include "algo/image/image_view.hpp"

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
/// The same with 128-bit integer vectors (SSE2, NEON); the scalar kernel where there are none.
void lkTranslationSumsVector(const uint8_t* image, std::ptrdiff_t stride, int side,
                             const LkBilinear& w, const int16_t* T, const int16_t* Sx,
                             const int16_t* Sy, int tstride, LkWindowSums& out);
/// "sse2", "neon" or "scalar": what lkTranslationSumsVector and lkAffineSums128 use on this
/// machine.
const char* lkVectorIsa();
/// True when this machine runs the NEON kernels: every aarch64; a 32-bit ARM build (GCC for
/// Linux) once lkSelectKernels was told the processor has NEON, since Debian's armhf baseline
/// does not include it; false elsewhere.
bool lkHaveNeon();

/// A vector instruction set the processor adds to the build's baseline, as the platform reports
/// it (hal::cpuVectorIsa() reads the kernel's AT_HWCAP: algo reads no system state).
enum class CpuVectorIsa {
  kBaseline,  ///< nothing beyond the build's baseline
  kNeon,      ///< NEON on a 32-bit ARM build whose baseline lacks it
};
/// Chooses the kernels for a processor with `isa`: a 32-bit ARM build runs the NEON kernels after
/// lkSelectKernels(CpuVectorIsa::kNeon) and the scalar ones before it or after kBaseline; other
/// builds choose at compile time (SSE2, aarch64 NEON) or by cpuid (AVX2) and ignore the call.
/// Call once at start (hal::selectKernelsForThisCpu), not while another thread tracks: the sums
/// are the same bit for bit either way, only the speed changes.
void lkSelectKernels(CpuVectorIsa isa);

// ---- The affine iteration (PyramidalLk::alignAffine, Baker & Matthews 2004 §3.2) ---------------

/// Warped positions of the affine iteration: 16.16 fixed point (kLkPosBits fractional bits).
constexpr int kLkPosBits = 16;

/// Where the template pixel (u, v) lies in the image: (row_x[v] + u xu, row_y[v] + u yu), 16.16
/// fixed point: each row's start rounded from the affine warp once, then whole steps per column.
struct LkAffineWarp {
  const int32_t* row_x = nullptr;  ///< per template row: position of its first pixel
  const int32_t* row_y = nullptr;
  int32_t xu = 1 << kLkPosBits;  ///< step per template column
  int32_t yu = 0;
};

/// The affine sample at the 16.16 position (X, Y), in 1/2^kLkValueBits gray levels: the fraction
/// cut to kLkWeightBits, the four bilinear weights rounded and the last one the remainder, so they
/// sum to 1 << kLkWeightBits exactly (as lkBilinear). Reads the pixel at (X >> 16, Y >> 16) and its
/// right, lower and lower-right neighbours.
inline int32_t lkAffineSample(const uint8_t* image, std::ptrdiff_t stride, int32_t X, int32_t Y) {
  constexpr int kShift = kLkWeightBits - kLkValueBits;
  constexpr int kCut = kLkPosBits - kLkWeightBits;
  constexpr int32_t kFraction = (1 << kLkWeightBits) - 1;
  const LkBilinear w = lkBilinear((X >> kCut) & kFraction, (Y >> kCut) & kFraction);
  const uint8_t* r0 =
      image + static_cast<std::ptrdiff_t>(Y >> kLkPosBits) * stride + (X >> kLkPosBits);
  const uint8_t* r1 = r0 + stride;
  return (w.w00 * r0[0] + w.w01 * r0[1] + w.w10 * r1[0] + w.w11 * r1[1] + (1 << (kShift - 1))) >>
         kShift;
}

/// Window sums of one affine iteration, e = sample - template (1/32 gray levels), u and v the
/// template column and row relative to the centre (u - side / 2, v - side / 2).
struct LkAffineSums {
  int64_t gx_e = 0;    ///< sum Sx e
  int64_t gy_e = 0;    ///< sum Sy e
  int64_t ugx_e = 0;   ///< sum u Sx e
  int64_t vgx_e = 0;   ///< sum v Sx e
  int64_t ugy_e = 0;   ///< sum u Sy e
  int64_t vgy_e = 0;   ///< sum v Sy e
  int64_t sum_e = 0;   ///< sum e
  int64_t sum_sq = 0;  ///< sum e^2
};

/// One pass of the affine iteration over a side x side template warped by `warp` into `image`.
/// Valid domain: every position of the window has 0 <= X >> 16 <= width - 2 and
/// 0 <= Y >> 16 <= height - 2 (it suffices that each row's first and last pixel do: positions
/// are linear along a row); `T`, `Sx`, `Sy` as for lkTranslationSumsScalar. The sums are exact
/// integers (every product fits int32, the sums are int64), so every variant gives the same sums
/// bit for bit.
void lkAffineSumsScalar(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                        const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                        LkAffineSums& out);
/// The same with 128-bit vectors (SSE2 / NEON; the scalar kernel where there are none, see
/// lkHaveNeon, or for windows beyond 56): a software gather of the four neighbours per pixel (one
/// contiguous load per row where the warped row of 8 pixels steps by exactly one pixel).
void lkAffineSums128(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                     const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                     LkAffineSums& out);
/// True when this machine runs lkAffineSumsAvx2 (x86-64 with AVX2, checked once at run time).
bool lkHaveAvx2();
/// The same with AVX2, 8 pixels per step (byte shuffles of the window's rows, or gathers);
/// lkAffineSums128 where AVX2 is missing (see lkHaveAvx2), for windows beyond 80, or when a
/// gather's 4-byte read could pass the end of the image's last row.
void lkAffineSumsAvx2(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                      const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                      LkAffineSums& out);
/// True when this machine also has AVX-512 F, BW, VL and DQ (lkAffineSumsAvx512).
bool lkHaveAvx512();
/// The AVX2 kernel's method on two template rows per 512-bit step; lkAffineSumsAvx2 where
/// AVX-512 is missing, lkAffineSums128 where the AVX2 kernel would use it.
void lkAffineSumsAvx512(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                        const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                        LkAffineSums& out);
/// The fastest of the above on this machine (chosen once).
void lkAffineSumsVector(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                        const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                        LkAffineSums& out);
/// "avx512", "avx2", "sse2", "neon" or "scalar": what lkAffineSumsVector uses on this machine.
const char* lkAffineVectorIsa();

}  // namespace epitrack

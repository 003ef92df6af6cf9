#include "algo/flow/lk_kernels.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstring>
#include <string_view>

#include "algo/flow/simd_int16.hpp"
#if EPITRACK_LK_SIMD
#include "algo/flow/lk_kernels_simd128.hpp"
#endif
#if EPITRACK_LK_NEON_ARMV7
#include "algo/flow/lk_kernels_arm.hpp"
#endif

namespace epitrack {
namespace {

constexpr int kShift = kLkWeightBits - kLkValueBits;  // sample = weighted sum >> 9
constexpr int kRound = 1 << (kShift - 1);

}  // namespace

void lkTranslationSumsScalar(const uint8_t* image, std::ptrdiff_t stride, int side,
                             const LkBilinear& w, const int16_t* T, const int16_t* Sx,
                             const int16_t* Sy, int tstride, LkWindowSums& out) {
  int64_t gx_e = 0, gy_e = 0, sum_e = 0, sum_sq = 0;
  for (int v = 0; v < side; ++v) {
    const uint8_t* r0 = image + v * stride;
    const uint8_t* r1 = r0 + stride;
    const int16_t* t = T + v * tstride;
    const int16_t* sx = Sx + v * tstride;
    const int16_t* sy = Sy + v * tstride;
    int64_t row_gx = 0, row_gy = 0, row_e = 0, row_sq = 0;
    for (int u = 0; u < side; ++u) {
      const int32_t sample =
          (w.w00 * r0[u] + w.w01 * r0[u + 1] + w.w10 * r1[u] + w.w11 * r1[u + 1] + kRound) >>
          kShift;
      const int32_t e = sample - t[u];
      row_gx += sx[u] * e;  // each product < 2^25: exact in int32
      row_gy += sy[u] * e;
      row_e += e;
      row_sq += e * e;
    }
    gx_e += row_gx;
    gy_e += row_gy;
    sum_e += row_e;
    sum_sq += row_sq;
  }
  out = LkWindowSums{gx_e, gy_e, sum_e, sum_sq};
}

#if EPITRACK_LK_SIMD

void lkTranslationSumsVector(const uint8_t* image, std::ptrdiff_t stride, int side,
                             const LkBilinear& w, const int16_t* T, const int16_t* Sx,
                             const int16_t* Sy, int tstride, LkWindowSums& out) {
  translationSums128(image, stride, side, w, T, Sx, Sy, tstride, out);
}

const char* lkVectorIsa() { return EPITRACK_LK_SIMD_NAME; }

bool lkHaveNeon() { return std::string_view(EPITRACK_LK_SIMD_NAME) == "neon"; }

void lkSelectKernels(CpuVectorIsa /*isa*/) {}

#elif EPITRACK_LK_NEON_ARMV7

namespace {
// What lkSelectKernels was told; scalar until then. Relaxed: the flag guards no other data, and
// both kernels give the same sums.
std::atomic<bool> g_neon{false};
}  // namespace

bool lkHaveNeon() { return g_neon.load(std::memory_order_relaxed); }

void lkSelectKernels(CpuVectorIsa isa) {
  g_neon.store(isa == CpuVectorIsa::kNeon, std::memory_order_relaxed);
}

void lkTranslationSumsVector(const uint8_t* image, std::ptrdiff_t stride, int side,
                             const LkBilinear& w, const int16_t* T, const int16_t* Sx,
                             const int16_t* Sy, int tstride, LkWindowSums& out) {
  const auto kernel = lkHaveNeon() ? armv7::translationSumsNeon : lkTranslationSumsScalar;
  kernel(image, stride, side, w, T, Sx, Sy, tstride, out);
}

const char* lkVectorIsa() { return lkHaveNeon() ? "neon" : "scalar"; }

#else

void lkTranslationSumsVector(const uint8_t* image, std::ptrdiff_t stride, int side,
                             const LkBilinear& w, const int16_t* T, const int16_t* Sx,
                             const int16_t* Sy, int tstride, LkWindowSums& out) {
  lkTranslationSumsScalar(image, stride, side, w, T, Sx, Sy, tstride, out);
}

const char* lkVectorIsa() { return "scalar"; }

bool lkHaveNeon() { return false; }

void lkSelectKernels(CpuVectorIsa /*isa*/) {}

#endif

// ---- Affine iteration -------------------------------------------------------------------------

void lkAffineSumsScalar(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                        const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                        LkAffineSums& out) {
  const int half = side / 2;
  int64_t gx = 0, gy = 0, ugx = 0, vgx = 0, ugy = 0, vgy = 0, sum_e = 0, sum_sq = 0;
  for (int v = 0; v < side; ++v) {
    int32_t X = warp.row_x[v];
    int32_t Y = warp.row_y[v];
    const int16_t* t = T + v * tstride;
    const int16_t* sx = Sx + v * tstride;
    const int16_t* sy = Sy + v * tstride;
    int64_t row_gx = 0, row_gy = 0, row_ugx = 0, row_ugy = 0, row_e = 0, row_sq = 0;
    for (int u = 0; u < side; ++u, X += warp.xu, Y += warp.yu) {
      const int32_t e = lkAffineSample(image.data, image.stride, X, Y) - t[u];
      const int32_t ge_x = sx[u] * e;  // < 2^25: exact in int32
      const int32_t ge_y = sy[u] * e;
      row_gx += ge_x;
      row_gy += ge_y;
      row_ugx += static_cast<int64_t>(u - half) * ge_x;
      row_ugy += static_cast<int64_t>(u - half) * ge_y;
      row_e += e;
      row_sq += e * e;
    }
    gx += row_gx;
    gy += row_gy;
    ugx += row_ugx;
    ugy += row_ugy;
    vgx += (v - half) * row_gx;
    vgy += (v - half) * row_gy;
    sum_e += row_e;
    sum_sq += row_sq;
  }
  out = LkAffineSums{gx, gy, ugx, vgx, ugy, vgy, sum_e, sum_sq};
}

#if EPITRACK_LK_SIMD

void lkAffineSums128(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                     const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                     LkAffineSums& out) {
  affineSums128(image, warp, side, T, Sx, Sy, tstride, out);
}

#elif EPITRACK_LK_NEON_ARMV7

void lkAffineSums128(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                     const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                     LkAffineSums& out) {
  const auto kernel = lkHaveNeon() ? armv7::affineSumsNeon : lkAffineSumsScalar;
  kernel(image, warp, side, T, Sx, Sy, tstride, out);
}

#else

void lkAffineSums128(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                     const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                     LkAffineSums& out) {
  lkAffineSumsScalar(image, warp, side, T, Sx, Sy, tstride, out);
}

#endif

#if !EPITRACK_LK_AVX2
bool lkHaveAvx2() { return false; }
bool lkHaveAvx512() { return false; }
void lkAffineSumsAvx2(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                      const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                      LkAffineSums& out) {
  lkAffineSums128(image, warp, side, T, Sx, Sy, tstride, out);
}
void lkAffineSumsAvx512(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                        const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                        LkAffineSums& out) {
  lkAffineSums128(image, warp, side, T, Sx, Sy, tstride, out);
}
#endif

void lkAffineSumsVector(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                        const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                        LkAffineSums& out) {
  // Chosen once; every variant gives the same sums.
  static const auto kernel = lkHaveAvx512() ? lkAffineSumsAvx512
                             : lkHaveAvx2() ? lkAffineSumsAvx2
                                            : lkAffineSums128;
  kernel(image, warp, side, T, Sx, Sy, tstride, out);
}

const char* lkAffineVectorIsa() {
  return lkHaveAvx512() ? "avx512" : lkHaveAvx2() ? "avx2" : lkVectorIsa();
}

}  // namespace epitrack

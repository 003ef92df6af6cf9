#include "algo/flow/lk_kernels.hpp"

#include "algo/flow/simd_int16.hpp"

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
  // Each int32 lane sums 2 products per 8 columns of a row: 2 * ceil(side / 8) * 8160^2 < 2^31
  // for side <= kMaxVectorSide; beyond, the scalar kernel.
  constexpr int kMaxVectorSide = 120;
  if (side > kMaxVectorSide) {
    lkTranslationSumsScalar(image, stride, side, w, T, Sx, Sy, tstride, out);
    return;
  }
  using namespace simd;
  const I16x8 w_top = pair16(static_cast<int16_t>(w.w00), static_cast<int16_t>(w.w01));
  const I16x8 w_bottom = pair16(static_cast<int16_t>(w.w10), static_cast<int16_t>(w.w11));
  const I32x4 round = set32(kRound);
  const I16x8 ones = set16(1);
  int64_t gx_e = 0, gy_e = 0, sum_e = 0, sum_sq = 0;
  for (int v = 0; v < side; ++v) {
    const uint8_t* r0 = image + v * stride;
    const uint8_t* r1 = r0 + stride;
    const int16_t* t = T + v * tstride;
    const int16_t* sx = Sx + v * tstride;
    const int16_t* sy = Sy + v * tstride;
    I32x4 acc_gx = zero32(), acc_gy = zero32(), acc_e = zero32(), acc_sq = zero32();
    for (int u = 0; u < side; u += 8) {
      // Pixels u.. and their right neighbours u+1.. of both rows, widened to int16. The last
      // group reads only what the window holds; its lanes beyond the window are 0, so are
      // their samples ((0 + kRound) >> kShift), the template's padding and the products.
      const int n = side - u;
      I16x8 p0, p1, q0, q1;
      if (n >= 8) {
        p0 = loadWidenU8(r0 + u);
        p1 = loadWidenU8(r0 + u + 1);
        q0 = loadWidenU8(r1 + u);
        q1 = loadWidenU8(r1 + u + 1);
      } else {
        p0 = loadWidenU8Partial(r0 + u, n);
        p1 = loadWidenU8Partial(r0 + u + 1, n);
        q0 = loadWidenU8Partial(r1 + u, n);
        q1 = loadWidenU8Partial(r1 + u + 1, n);
      }
      // w00 * p0 + w01 * p1 + w10 * q0 + w11 * q1 per pixel: pairs (p0, p1) x (w00, w01).
      const I32x4 s_lo = sra32<kShift>(
          add32(add32(madd(zipLo16(p0, p1), w_top), madd(zipLo16(q0, q1), w_bottom)), round));
      const I32x4 s_hi = sra32<kShift>(
          add32(add32(madd(zipHi16(p0, p1), w_top), madd(zipHi16(q0, q1), w_bottom)), round));
      const I16x8 e = sub16(pack32(s_lo, s_hi), loadI16(t + u));
      acc_gx = add32(acc_gx, madd(e, loadI16(sx + u)));
      acc_gy = add32(acc_gy, madd(e, loadI16(sy + u)));
      acc_e = add32(acc_e, madd(e, ones));
      acc_sq = add32(acc_sq, madd(e, e));
    }
    gx_e += sum32(acc_gx);
    gy_e += sum32(acc_gy);
    sum_e += sum32(acc_e);
    sum_sq += sum32(acc_sq);
  }
  out = LkWindowSums{gx_e, gy_e, sum_e, sum_sq};
}

const char* lkVectorIsa() { return EPITRACK_LK_SIMD_NAME; }

#else

void lkTranslationSumsVector(const uint8_t* image, std::ptrdiff_t stride, int side,
                             const LkBilinear& w, const int16_t* T, const int16_t* Sx,
                             const int16_t* Sy, int tstride, LkWindowSums& out) {
  lkTranslationSumsScalar(image, stride, side, w, T, Sx, Sy, tstride, out);
}

const char* lkVectorIsa() { return "scalar"; }

#endif

}  // namespace epitrack

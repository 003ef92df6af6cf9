#pragma once

// The 128-bit LK kernels, written once over the operations of algo/flow/simd_int16.hpp and
// compiled once per instruction set (OpenCV's dispatched .simd.hpp): by lk_kernels.cpp where the
// baseline has 128-bit vectors (SSE2, aarch64 NEON) and by lk_kernels_neon32.cpp for ARMv7 NEON,
// chosen at run time. Include after simd_int16.hpp with EPITRACK_LK_SIMD 1. The functions have
// internal linkage: each translation unit keeps its own copy, compiled for its instruction set.

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>

#include "algo/flow/lk_kernels.hpp"
#include "algo/flow/simd_int16.hpp"

#if !EPITRACK_LK_SIMD
#error "lk_kernels_simd128.hpp needs the 128-bit operations of simd_int16.hpp"
#endif

namespace epitrack {
namespace {

constexpr int kSimdShift = kLkWeightBits - kLkValueBits;  // sample = weighted sum >> 9
constexpr int kSimdRound = 1 << (kSimdShift - 1);

/// lkTranslationSumsVector's kernel (see lk_kernels.hpp), the same sums as the scalar kernel.
void translationSums128(const uint8_t* image, std::ptrdiff_t stride, int side, const LkBilinear& w,
                        const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                        LkWindowSums& out) {
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
  const I32x4 round = set32(kSimdRound);
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
      // their samples ((0 + kSimdRound) >> kSimdShift), the template's padding and the products.
      const int n = side - u;
      I16x8 p0, p1, q0, q1;
      if (n >= 8) {
        p0 = loadWidenU8(r0 + u);
        p1 = loadWidenU8(r0 + u + 1);
        q0 = loadWidenU8(r1 + u);
        q1 = loadWidenU8(r1 + u + 1);
      } else if (side >= 8) {  // the 8 bytes ending at the window's last column are inside it
        p0 = loadWidenU8Tail(r0 + u, n);
        p1 = loadWidenU8Tail(r0 + u + 1, n);
        q0 = loadWidenU8Tail(r1 + u, n);
        q1 = loadWidenU8Tail(r1 + u + 1, n);
      } else {
        p0 = loadWidenU8Partial(r0 + u, n);
        p1 = loadWidenU8Partial(r0 + u + 1, n);
        q0 = loadWidenU8Partial(r1 + u, n);
        q1 = loadWidenU8Partial(r1 + u + 1, n);
      }
      // w00 * p0 + w01 * p1 + w10 * q0 + w11 * q1 per pixel: pairs (p0, p1) x (w00, w01).
      const I32x4 s_lo = sra32<kSimdShift>(
          add32(add32(madd(zipLo16(p0, p1), w_top), madd(zipLo16(q0, q1), w_bottom)), round));
      const I32x4 s_hi = sra32<kSimdShift>(
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

/// lkAffineSums128's kernel (see lk_kernels.hpp), the same sums as the scalar kernel.
void affineSums128(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                   const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                   LkAffineSums& out) {
  static_assert(std::endian::native == std::endian::little, "the pixel pairs are little-endian");
  // Pixel pairs: int32 lane i of a group of 8 holds the products of pixels 2i and 2i + 1 (pmaddwd),
  // at most 2 * 4080 * 8160 < 2^26. Per row, with n = ceil(side / 8) groups, a lane sums n of
  // them (a), and the running sums of a after each group (q, for the column weights: see below),
  // at most n (n + 1) / 2 * 2^26 < 2^31 for n <= 7; beyond, the scalar kernel.
  constexpr int kMaxSide = 56;
  if (side > kMaxSide) {
    lkAffineSumsScalar(image, warp, side, T, Sx, Sy, tstride, out);
    return;
  }
  using namespace simd;
  constexpr int32_t kOne = 1 << kLkWeightBits;
  constexpr int kCut = kLkPosBits - kLkWeightBits;
  const int groups = (side + 7) / 8;
  const int half = side / 2;
  const std::ptrdiff_t stride = image.stride;
  const uint8_t* base = image.data;
  const int32_t xu = warp.xu;
  const int32_t yu = warp.yu;
  const I32x4 lane_x_lo = set32x4(0, xu, 2 * xu, 3 * xu);
  const I32x4 lane_x_hi = set32x4(4 * xu, 5 * xu, 6 * xu, 7 * xu);
  const I32x4 lane_y_lo = set32x4(0, yu, 2 * yu, 3 * yu);
  const I32x4 lane_y_hi = set32x4(4 * yu, 5 * yu, 6 * yu, 7 * yu);
  const I32x4 one = set32(kOne);
  const I32x4 fraction = set32(kOne - 1);
  const I32x4 round_w = set32(kOne >> 1);
  const I32x4 round_s = set32(1 << (kLkWeightBits - kLkValueBits - 1));
  const I16x8 one16 = set16(static_cast<int16_t>(kOne));
  const I16x8 odd = pair16(0, -1);  // the second pixel of each pair
  const I16x8 ones = set16(1);
  // lkBilinear's weights of 8 pixels from their positions (16.16), as (w00, w01) and (w10, w11)
  // int16 pairs per int32 lane, pixels 0-3 (lo) and 4-7 (hi): exact 32-bit products of the
  // 14-bit fractions, rounded, the fourth weight the remainder.
  struct Weights {
    I16x8 w0_lo, w1_lo, w0_hi, w1_hi;
  };
  const auto weights = [&](I32x4 X_lo, I32x4 X_hi, I32x4 Y_lo, I32x4 Y_hi) {
    const I16x8 fx =
        pack32(bitAnd(srl32<kCut>(X_lo), fraction), bitAnd(srl32<kCut>(X_hi), fraction));
    const I16x8 fy =
        pack32(bitAnd(srl32<kCut>(Y_lo), fraction), bitAnd(srl32<kCut>(Y_hi), fraction));
    const I16x8 gx = sub16(one16, fx);
    const I16x8 gy = sub16(one16, fy);
    I32x4 p00_lo, p00_hi, p01_lo, p01_hi, p10_lo, p10_hi;
    mulWidenU16(gx, gy, p00_lo, p00_hi);
    mulWidenU16(fx, gy, p01_lo, p01_hi);
    mulWidenU16(gx, fy, p10_lo, p10_hi);
    const auto pairs = [&](I32x4 p00, I32x4 p01, I32x4 p10, I16x8& w0, I16x8& w1) {
      const I32x4 w00 = sra32<kLkWeightBits>(add32(p00, round_w));
      const I32x4 w01 = sra32<kLkWeightBits>(add32(p01, round_w));
      const I32x4 w10 = sra32<kLkWeightBits>(add32(p10, round_w));
      const I32x4 w11 = sub32(sub32(sub32(one, w00), w01), w10);
      w0 = as16(bitOr(w00, sll32<16>(w01)));
      w1 = as16(bitOr(w10, sll32<16>(w11)));
    };
    Weights w{};  // every lane is written below
    pairs(p00_lo, p01_lo, p10_lo, w.w0_lo, w.w1_lo);
    pairs(p00_hi, p01_hi, p10_hi, w.w0_hi, w.w1_hi);
    return w;
  };
  // (p0, p1) pairs of the top and bottom rows (int16 each) to samples (lkAffineSample).
  const auto sample = [&](I16x8 top, I16x8 bottom, I16x8 w0, I16x8 w1) {
    return sra32<kLkWeightBits - kLkValueBits>(
        add32(add32(madd(top, w0), madd(bottom, w1)), round_s));
  };
  I32x4 acc_e = zero32();
  int64_t gx = 0, gy = 0, ugx = 0, vgx = 0, ugy = 0, vgy = 0, sum_sq = 0;
  for (int v = 0; v < side; ++v) {
    int32_t Xg = warp.row_x[v];
    int32_t Yg = warp.row_y[v];
    const int16_t* t = T + v * tstride;
    const int16_t* sx = Sx + v * tstride;
    const int16_t* sy = Sy + v * tstride;
    I32x4 a_gx = zero32(), q_gx = zero32(), o_gx = zero32();
    I32x4 a_gy = zero32(), q_gy = zero32(), o_gy = zero32();
    I32x4 a_sq = zero32();
    for (int u = 0; u < side; u += 8, Xg += 8 * xu, Yg += 8 * yu) {
      const int n = std::min(8, side - u);
      // The four neighbours of each pixel as (left, right) pairs of the top and bottom rows,
      // pixels 0-3 (lo) and 4-7 (hi); lanes beyond the window 0.
      I16x8 top_lo, top_hi, bottom_lo, bottom_hi;
      const int ix = Xg >> kLkPosBits;
      const int iy = Yg >> kLkPosBits;
      const int32_t X_last = Xg + (n - 1) * xu;
      const int32_t Y_last = Yg + (n - 1) * yu;
      if ((X_last >> kLkPosBits) - ix == n - 1 && (Y_last >> kLkPosBits) == iy) {
        // The warped row steps by exactly one pixel here (positions are monotonic in u): two
        // contiguous loads per row, as in the translation kernel.
        const uint8_t* r0 = base + static_cast<std::ptrdiff_t>(iy) * stride + ix;
        const uint8_t* r1 = r0 + stride;
        I16x8 p0, p1, q0, q1;
        if (n == 8) {
          p0 = loadWidenU8(r0);
          p1 = loadWidenU8(r0 + 1);
          q0 = loadWidenU8(r1);
          q1 = loadWidenU8(r1 + 1);
        } else if (ix + n >= 8) {  // the 8 bytes ending at the last column are in the row
          p0 = loadWidenU8Tail(r0, n);
          p1 = loadWidenU8Tail(r0 + 1, n);
          q0 = loadWidenU8Tail(r1, n);
          q1 = loadWidenU8Tail(r1 + 1, n);
        } else {
          p0 = loadWidenU8Partial(r0, n);
          p1 = loadWidenU8Partial(r0 + 1, n);
          q0 = loadWidenU8Partial(r1, n);
          q1 = loadWidenU8Partial(r1 + 1, n);
        }
        top_lo = zipLo16(p0, p1);
        top_hi = zipHi16(p0, p1);
        bottom_lo = zipLo16(q0, q1);
        bottom_hi = zipHi16(q0, q1);
      } else {
        uint16_t tp[8] = {0, 0, 0, 0, 0, 0, 0, 0};
        uint16_t bt[8] = {0, 0, 0, 0, 0, 0, 0, 0};
        int32_t X = Xg;
        int32_t Y = Yg;
        for (int k = 0; k < n; ++k, X += xu, Y += yu) {
          const uint8_t* r0 =
              base + static_cast<std::ptrdiff_t>(Y >> kLkPosBits) * stride + (X >> kLkPosBits);
          std::memcpy(&tp[k], r0, 2);
          std::memcpy(&bt[k], r0 + stride, 2);
        }
        const I16x8 top = set16x8(tp[0], tp[1], tp[2], tp[3], tp[4], tp[5], tp[6], tp[7]);
        const I16x8 bottom = set16x8(bt[0], bt[1], bt[2], bt[3], bt[4], bt[5], bt[6], bt[7]);
        top_lo = widenLoU8(top);
        top_hi = widenHiU8(top);
        bottom_lo = widenLoU8(bottom);
        bottom_hi = widenHiU8(bottom);
      }
      const I32x4 X0 = set32(Xg);
      const I32x4 Y0 = set32(Yg);
      const Weights w = weights(add32(X0, lane_x_lo), add32(X0, lane_x_hi), add32(Y0, lane_y_lo),
                                add32(Y0, lane_y_hi));
      const I32x4 s_lo = sample(top_lo, bottom_lo, w.w0_lo, w.w1_lo);
      const I32x4 s_hi = sample(top_hi, bottom_hi, w.w0_hi, w.w1_hi);
      // Beyond the window the pixels are 0, so are the samples and (padding) the template.
      const I16x8 e = sub16(pack32(s_lo, s_hi), loadI16(t + u));
      const I16x8 e_odd = as16(bitAnd(as32(e), as32(odd)));
      const I16x8 gxv = loadI16(sx + u);
      const I16x8 gyv = loadI16(sy + u);
      a_gx = add32(a_gx, madd(e, gxv));
      q_gx = add32(q_gx, a_gx);
      o_gx = add32(o_gx, madd(e_odd, gxv));
      a_gy = add32(a_gy, madd(e, gyv));
      q_gy = add32(q_gy, a_gy);
      o_gy = add32(o_gy, madd(e_odd, gyv));
      acc_e = add32(acc_e, madd(e, ones));
      a_sq = add32(a_sq, madd(e, e));
    }
    // Column weights: pixel 8 j + 2 i + b (group j, lane i, b = 1 for the odd one) has weight
    // 8 j + 2 i + b; sum_j j a_j = n a - q over a row of n groups (q: the running sums).
    const auto row = [&](I32x4 a, I32x4 q, I32x4 o, int64_t& plain, int64_t& u_weighted,
                         int64_t& v_weighted) {
      int32_t al[4], ql[4], ol[4];
      store32(al, a);
      store32(ql, q);
      store32(ol, o);
      int64_t p = 0, w = 0;
      for (int i = 0; i < 4; ++i) {
        p += al[i];
        w += static_cast<int64_t>(2 * i + 8 * groups) * al[i] - 8 * static_cast<int64_t>(ql[i]) +
             ol[i];
      }
      plain += p;
      u_weighted += w - half * p;
      v_weighted += (v - half) * p;
    };
    row(a_gx, q_gx, o_gx, gx, ugx, vgx);
    row(a_gy, q_gy, o_gy, gy, ugy, vgy);
    sum_sq += sum32(a_sq);
  }
  out = LkAffineSums{gx, gy, ugx, vgx, ugy, vgy, sum32(acc_e), sum_sq};
}

}  // namespace
}  // namespace epitrack

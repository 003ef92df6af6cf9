// The affine LK kernel with AVX-512 (F, BW, VL, DQ; x86-64 only): compiled through the target
// attribute in a baseline build and run only where the processor has it (lkHaveAvx512, checked
// once). The AVX2 kernel's method (lk_kernels_avx2.cpp) on two template rows at once: int32 lanes
// 0-7 hold 8 pixels of row v, lanes 8-15 the same columns of row v + 1. Same integers as
// lkAffineSumsScalar (algo/flow/lk_kernels.hpp), bit for bit.
#include "algo/flow/lk_kernels.hpp"
#include "algo/flow/lk_kernels_x86.hpp"
#include "algo/flow/simd_int16.hpp"

#if EPITRACK_LK_AVX2

// GCC 12's AVX-512 headers start some intrinsics from _mm512_undefined_epi32(), which it then
// reports as maybe uninitialized (GCC bug 105593, fixed in GCC 13).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <immintrin.h>

#include <algorithm>
#include <cstring>

namespace epitrack {
namespace {

#define EPITRACK_AVX512 __attribute__((target("avx2,avx512f,avx512bw,avx512vl,avx512dq")))
#define EPITRACK_AVX512_INLINE \
  __attribute__((target("avx2,avx512f,avx512bw,avx512vl,avx512dq"), always_inline)) inline

/// What every group of a window shares.
struct Setup {
  __m512i one, fraction, round_w, round_s, pair, pair_base, stride, step_x, step_y;
  const uint8_t* data;
  std::ptrdiff_t row_stride;
  const int* top_row;  // the gathers take an int pointer; they read 4 bytes at byte offsets
  const int* bottom_row;
  int32_t xu, yu;
};

/// One pair of rows: positions and int32 running sums per lane (see lk_kernels_avx2.cpp).
struct PairSums {
  __m512i X, Y;      // positions of the group's 16 pixels (16.16)
  int32_t xg, yg;    // the group's first pixel in the first row
  int32_t xg1, yg1;  // ... in the second
  __m512i a_gx, q_gx, a_gy, q_gy, a_sq, acc_e;
};

/// 16 bytes at p into the low 256 bits (both 128-bit lanes) and q into the high 256 bits.
EPITRACK_AVX512_INLINE __m512i rows2(const uint8_t* p, const uint8_t* q) {
  __m128i a, b;
  std::memcpy(&a, p, sizeof(a));
  std::memcpy(&b, q, sizeof(b));
  return _mm512_mask_broadcast_i32x4(_mm512_broadcast_i32x4(a), 0xFF00, b);
}

/// 8 int16 at p (lanes 0-7) and at q (lanes 8-15), sign-extended.
EPITRACK_AVX512_INLINE __m512i load16x2(const int16_t* p, const int16_t* q) {
  __m128i a, b;
  std::memcpy(&a, p, sizeof(a));
  std::memcpy(&b, q, sizeof(b));
  return _mm512_cvtepi16_epi32(_mm256_inserti128_si256(_mm256_castsi128_si256(a), b, 1));
}

/// The left column and top row of one row's group of n pixels starting at (xg, yg).
EPITRACK_AVX512_INLINE void groupCorner(const Setup& c, int32_t xg, int32_t yg, int n, int& ix0,
                                        int& iy0) {
  ix0 = std::min(xg >> kLkPosBits, (xg + (n - 1) * c.xu) >> kLkPosBits);
  iy0 = std::min(yg >> kLkPosBits, (yg + (n - 1) * c.yu) >> kLkPosBits);
}

/// One group: 8 columns of two rows (lanes `mask`: the window's pixels; the second row absent
/// when kSingle). kShuffle as in lk_kernels_avx2.cpp.
template <bool kShuffle, bool kSingle>
EPITRACK_AVX512_INLINE void group(const Setup& c, PairSums& r, const int16_t* t0, const int16_t* t1,
                                  const int16_t* sx0, const int16_t* sx1, const int16_t* sy0,
                                  const int16_t* sy1, int n, __mmask16 mask) {
  constexpr int kCut = kLkPosBits - kLkWeightBits;
  __m512i top, bottom;
  if constexpr (kShuffle) {
    int ix0, iy0;
    groupCorner(c, r.xg, r.yg, n, ix0, iy0);
    int ix1 = ix0, iy1 = iy0;  // the second row (the first again when absent: readable)
    if constexpr (!kSingle) groupCorner(c, r.xg1, r.yg1, n, ix1, iy1);
    const uint8_t* p0 = c.data + static_cast<std::ptrdiff_t>(iy0) * c.row_stride + ix0;
    const uint8_t* p1 = c.data + static_cast<std::ptrdiff_t>(iy1) * c.row_stride + ix1;
    const __m512i l0 = rows2(p0, p1);
    const __m512i l1 = rows2(p0 + c.row_stride, p1 + c.row_stride);
    const __m512i l2 = rows2(p0 + 2 * c.row_stride, p1 + 2 * c.row_stride);
    const __m512i left = _mm512_mask_set1_epi32(_mm512_set1_epi32(ix0), 0xFF00, ix1);
    const __m512i upper = _mm512_mask_set1_epi32(_mm512_set1_epi32(iy0), 0xFF00, iy1);
    const __m512i dx = _mm512_sub_epi32(_mm512_srai_epi32(r.X, kLkPosBits), left);
    const __m512i control =
        _mm512_add_epi32(_mm512_add_epi32(dx, _mm512_slli_epi32(dx, 16)), c.pair_base);
    const __mmask16 lower = _mm512_cmpgt_epi32_mask(_mm512_srai_epi32(r.Y, kLkPosBits), upper);
    const __m512i s0 = _mm512_shuffle_epi8(l0, control);
    const __m512i s1 = _mm512_shuffle_epi8(l1, control);
    const __m512i s2 = _mm512_shuffle_epi8(l2, control);
    top = _mm512_maskz_mov_epi32(mask, _mm512_mask_blend_epi32(lower, s0, s1));
    bottom = _mm512_maskz_mov_epi32(mask, _mm512_mask_blend_epi32(lower, s1, s2));
  } else {
    const __m512i offset =
        _mm512_add_epi32(_mm512_mullo_epi32(_mm512_srai_epi32(r.Y, kLkPosBits), c.stride),
                         _mm512_srai_epi32(r.X, kLkPosBits));
    const __m512i zero = _mm512_setzero_si512();
    top =
        _mm512_shuffle_epi8(_mm512_mask_i32gather_epi32(zero, mask, offset, c.top_row, 1), c.pair);
    bottom = _mm512_shuffle_epi8(_mm512_mask_i32gather_epi32(zero, mask, offset, c.bottom_row, 1),
                                 c.pair);
  }
  // lkBilinear's weights from the 14-bit fractions (exact int32 products), the fourth the
  // remainder, as (w00, w01) and (w10, w11) int16 pairs; then lkAffineSample's sum.
  const __m512i fx = _mm512_and_si512(_mm512_srli_epi32(r.X, kCut), c.fraction);
  const __m512i fy = _mm512_and_si512(_mm512_srli_epi32(r.Y, kCut), c.fraction);
  const __m512i gx = _mm512_sub_epi32(c.one, fx);
  const __m512i gy = _mm512_sub_epi32(c.one, fy);
  const __m512i w00 =
      _mm512_srai_epi32(_mm512_add_epi32(_mm512_mullo_epi32(gx, gy), c.round_w), kLkWeightBits);
  const __m512i w01 =
      _mm512_srai_epi32(_mm512_add_epi32(_mm512_mullo_epi32(fx, gy), c.round_w), kLkWeightBits);
  const __m512i w10 =
      _mm512_srai_epi32(_mm512_add_epi32(_mm512_mullo_epi32(gx, fy), c.round_w), kLkWeightBits);
  const __m512i w11 = _mm512_sub_epi32(_mm512_sub_epi32(_mm512_sub_epi32(c.one, w00), w01), w10);
  const __m512i w0 = _mm512_or_si512(w00, _mm512_slli_epi32(w01, 16));
  const __m512i w1 = _mm512_or_si512(w10, _mm512_slli_epi32(w11, 16));
  const __m512i s = _mm512_srai_epi32(
      _mm512_add_epi32(_mm512_add_epi32(_mm512_madd_epi16(top, w0), _mm512_madd_epi16(bottom, w1)),
                       c.round_s),
      kLkWeightBits - kLkValueBits);
  // Lanes outside the window (the padding, an absent row) give e = 0.
  const __m512i e = _mm512_maskz_sub_epi32(mask, s, load16x2(t0, t1));
  r.a_gx = _mm512_add_epi32(r.a_gx, _mm512_mullo_epi32(e, load16x2(sx0, sx1)));
  r.q_gx = _mm512_add_epi32(r.q_gx, r.a_gx);
  r.a_gy = _mm512_add_epi32(r.a_gy, _mm512_mullo_epi32(e, load16x2(sy0, sy1)));
  r.q_gy = _mm512_add_epi32(r.q_gy, r.a_gy);
  r.acc_e = _mm512_add_epi32(r.acc_e, e);
  r.a_sq = _mm512_add_epi32(r.a_sq, _mm512_mullo_epi32(e, e));
  r.X = _mm512_add_epi32(r.X, c.step_x);
  r.Y = _mm512_add_epi32(r.Y, c.step_y);
  r.xg += 8 * c.xu;
  r.yg += 8 * c.yu;
  r.xg1 += 8 * c.xu;
  r.yg1 += 8 * c.yu;
}

/// int64 accumulators per column lane k (0-7) over the window.
struct Acc64 {
  __m512i P, Q, R, H;  // products, column running sums, row-pair running sums of P, second rows
};

/// The row pair's int32 sums into int64: both halves into P (and Q), the second half into H.
EPITRACK_AVX512_INLINE void flush(__m512i a, __m512i q, Acc64& acc) {
  const __m512i a_lo = _mm512_cvtepi32_epi64(_mm512_castsi512_si256(a));
  const __m512i a_hi = _mm512_cvtepi32_epi64(_mm512_extracti64x4_epi64(a, 1));
  acc.P = _mm512_add_epi64(acc.P, _mm512_add_epi64(a_lo, a_hi));
  acc.H = _mm512_add_epi64(acc.H, a_hi);
  acc.Q = _mm512_add_epi64(
      acc.Q, _mm512_add_epi64(_mm512_cvtepi32_epi64(_mm512_castsi512_si256(q)),
                              _mm512_cvtepi32_epi64(_mm512_extracti64x4_epi64(q, 1))));
  acc.R = _mm512_add_epi64(acc.R, acc.P);
}

EPITRACK_AVX512_INLINE int64_t lane(__m512i v, int k) {
  int64_t l[8];
  std::memcpy(l, &v, sizeof(l));
  return l[k];
}

template <bool kShuffle>
EPITRACK_AVX512_INLINE void affineBody(ImageView<const uint8_t> image, const LkAffineWarp& warp,
                                       int side, const int16_t* T, const int16_t* Sx,
                                       const int16_t* Sy, int tstride, LkAffineSums& out) {
  constexpr int32_t kOne = 1 << kLkWeightBits;
  const int groups = (side + 7) / 8;
  const int half = side / 2;
  const int tail = side - 8 * (groups - 1);  // pixels in the last group of a row
  const int pairs = (side + 1) / 2;
  // Lane k < 8: column k of the first row; k >= 8: column k - 8 of the second.
  const __m512i column = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 0, 1, 2, 3, 4, 5, 6, 7);
  const __mmask16 second = 0xFF00;
  const __m512i lane_x = _mm512_mullo_epi32(column, _mm512_set1_epi32(warp.xu));
  const __m512i lane_y = _mm512_mullo_epi32(column, _mm512_set1_epi32(warp.yu));
  const __mmask16 tail_mask =
      static_cast<__mmask16>(_mm512_cmpgt_epi32_mask(_mm512_set1_epi32(tail), column));
  Setup c{};
  c.one = _mm512_set1_epi32(kOne);
  c.fraction = _mm512_set1_epi32(kOne - 1);
  c.round_w = _mm512_set1_epi32(kOne >> 1);
  c.round_s = _mm512_set1_epi32(1 << (kLkWeightBits - kLkValueBits - 1));
  // Bytes 0 and 1 of each gathered int32 as two int16 (per 128-bit lane).
  c.pair = _mm512_set4_epi32(static_cast<int32_t>(0x800D800Cu), static_cast<int32_t>(0x80098008u),
                             static_cast<int32_t>(0x80058004u), static_cast<int32_t>(0x80018000u));
  c.pair_base = _mm512_set1_epi32(static_cast<int32_t>(0x80018000u));
  c.stride = _mm512_set1_epi32(static_cast<int32_t>(image.stride));
  c.step_x = _mm512_set1_epi32(8 * warp.xu);
  c.step_y = _mm512_set1_epi32(8 * warp.yu);
  c.data = image.data;
  c.row_stride = image.stride;
  c.top_row = static_cast<const int*>(static_cast<const void*>(image.data));
  c.bottom_row = static_cast<const int*>(static_cast<const void*>(image.data + image.stride));
  c.xu = warp.xu;
  c.yu = warp.yu;
  const __m512i zero = _mm512_setzero_si512();
  Acc64 gx{zero, zero, zero, zero}, gy{zero, zero, zero, zero};
  __m512i sq = zero;
  __m512i acc_e = zero;
  for (int p = 0; p < pairs; ++p) {
    const int v = 2 * p;
    const bool single = v + 1 == side;  // the last row of an odd window
    PairSums r{};
    r.xg = warp.row_x[v];
    r.yg = warp.row_y[v];
    r.xg1 = single ? r.xg : warp.row_x[v + 1];  // (an absent row: masked off)
    r.yg1 = single ? r.yg : warp.row_y[v + 1];
    r.X = _mm512_add_epi32(_mm512_mask_set1_epi32(_mm512_set1_epi32(r.xg), second, r.xg1), lane_x);
    r.Y = _mm512_add_epi32(_mm512_mask_set1_epi32(_mm512_set1_epi32(r.yg), second, r.yg1), lane_y);
    r.a_gx = r.q_gx = r.a_gy = r.q_gy = r.a_sq = zero;
    r.acc_e = acc_e;
    const std::ptrdiff_t row0 = static_cast<std::ptrdiff_t>(v) * tstride;
    const std::ptrdiff_t row1 = single ? row0 : row0 + tstride;
    const __mmask16 rows = single ? static_cast<__mmask16>(0x00FF) : static_cast<__mmask16>(0xFFFF);
    for (int j = 0; j < groups; ++j) {
      const std::ptrdiff_t o = 8 * j;
      const __mmask16 mask = j + 1 < groups ? rows : static_cast<__mmask16>(rows & tail_mask);
      const int n = j + 1 < groups ? 8 : tail;
      if (single) {
        group<kShuffle, true>(c, r, T + row0 + o, T + row1 + o, Sx + row0 + o, Sx + row1 + o,
                              Sy + row0 + o, Sy + row1 + o, n, mask);
      } else {
        group<kShuffle, false>(c, r, T + row0 + o, T + row1 + o, Sx + row0 + o, Sx + row1 + o,
                               Sy + row0 + o, Sy + row1 + o, n, mask);
      }
    }
    acc_e = r.acc_e;
    flush(r.a_gx, r.q_gx, gx);
    flush(r.a_gy, r.q_gy, gy);
    sq = _mm512_add_epi64(
        sq, _mm512_add_epi64(_mm512_cvtepi32_epi64(_mm512_castsi512_si256(r.a_sq)),
                             _mm512_cvtepi32_epi64(_mm512_extracti64x4_epi64(r.a_sq, 1))));
  }
  // Column u = 8 j + k: sum_j j a_j = n a - q (as lk_kernels_avx2.cpp). Row v = 2 p (+ 1 for the
  // second half): sum_v v row_v = 2 sum_p p (both rows) + (second rows), sum_p p S_p = pairs P - R.
  const auto reduce = [&](const Acc64& a, int64_t& plain, int64_t& u_weighted,
                          int64_t& v_weighted) {
    int64_t P[8], Q[8], R[8], H[8];
    std::memcpy(P, &a.P, sizeof(P));
    std::memcpy(Q, &a.Q, sizeof(Q));
    std::memcpy(R, &a.R, sizeof(R));
    std::memcpy(H, &a.H, sizeof(H));
    int64_t total = 0, u_sum = 0, r_sum = 0, h_sum = 0;
    for (int k = 0; k < 8; ++k) {
      total += P[k];
      u_sum += (k + 8 * groups) * P[k] - 8 * Q[k];
      r_sum += R[k];
      h_sum += H[k];
    }
    plain = total;
    u_weighted = u_sum - half * total;
    v_weighted = 2 * (pairs * total - r_sum) + h_sum - half * total;
  };
  LkAffineSums sums;
  reduce(gx, sums.gx_e, sums.ugx_e, sums.vgx_e);
  reduce(gy, sums.gy_e, sums.ugy_e, sums.vgy_e);
  sums.sum_sq = 0;
  for (int k = 0; k < 8; ++k) sums.sum_sq += lane(sq, k);
  int32_t e_lanes[16];
  std::memcpy(e_lanes, &acc_e, sizeof(acc_e));
  sums.sum_e = 0;
  for (const int32_t x : e_lanes) sums.sum_e += x;
  out = sums;
}

EPITRACK_AVX512 void affineSumsAvx512(ImageView<const uint8_t> image, const LkAffineWarp& warp,
                                      int side, const int16_t* T, const int16_t* Sx,
                                      const int16_t* Sy, int tstride, LkAffineSums& out,
                                      bool shuffle) {
  if (shuffle) {
    affineBody<true>(image, warp, side, T, Sx, Sy, tstride, out);
  } else {
    affineBody<false>(image, warp, side, T, Sx, Sy, tstride, out);
  }
}

}  // namespace

bool lkHaveAvx512() {
  static const bool have = [] {
    __builtin_cpu_init();
    return lkHaveAvx2() && __builtin_cpu_supports("avx512f") != 0 &&
           __builtin_cpu_supports("avx512bw") != 0 && __builtin_cpu_supports("avx512vl") != 0 &&
           __builtin_cpu_supports("avx512dq") != 0;
  }();
  return have;
}

void lkAffineSumsAvx512(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                        const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                        LkAffineSums& out) {
  bool shuffle = false;
  if (!lkHaveAvx512() || !x86::affinePlan(image, warp, side, shuffle)) {
    lkAffineSumsAvx2(image, warp, side, T, Sx, Sy, tstride, out);
    return;
  }
  affineSumsAvx512(image, warp, side, T, Sx, Sy, tstride, out, shuffle);
}

}  // namespace epitrack

#endif  // EPITRACK_LK_AVX2

// The affine LK kernel with AVX2 (x86-64 only): compiled for AVX2 through the target attribute in
// a baseline build and run only where the processor has it (lkHaveAvx2, checked once). Same
// integers as lkAffineSumsScalar (algo/flow/lk_kernels.hpp), bit for bit. 8 pixels per step, one
// per int32 lane: the neighbours by byte shuffles of three row loads where a group of 8 warped
// pixels spans at most 15 columns and 2 rows (shapes near the identity: almost always), else by
// gathers; bilinear weights and products in int32 lanes.
#include "algo/flow/lk_kernels.hpp"
#include "algo/flow/simd_int16.hpp"

#if EPITRACK_LK_AVX2

#include <immintrin.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>

namespace epitrack {
namespace {

#define EPITRACK_AVX2 __attribute__((target("avx2")))

/// Sign-extends the 8 int32 lanes of `a` and adds them to the int64 lanes of lo (0-3), hi (4-7).
EPITRACK_AVX2 inline void addWiden(__m256i a, __m256i& lo, __m256i& hi) {
  lo = _mm256_add_epi64(lo, _mm256_cvtepi32_epi64(_mm256_castsi256_si128(a)));
  hi = _mm256_add_epi64(hi, _mm256_cvtepi32_epi64(_mm256_extracti128_si256(a, 1)));
}

/// Lane k of (lo, hi) as int64.
struct Lanes64 {
  int64_t v[8];
};
EPITRACK_AVX2 inline Lanes64 lanes(__m256i lo, __m256i hi) {
  Lanes64 l;
  std::memcpy(l.v, &lo, sizeof(lo));
  std::memcpy(l.v + 4, &hi, sizeof(hi));
  return l;
}

EPITRACK_AVX2 void affineSumsAvx2(ImageView<const uint8_t> image, const LkAffineWarp& warp,
                                  int side, const int16_t* T, const int16_t* Sx, const int16_t* Sy,
                                  int tstride, LkAffineSums& out) {
  constexpr int32_t kOne = 1 << kLkWeightBits;
  constexpr int kCut = kLkPosBits - kLkWeightBits;
  const int groups = (side + 7) / 8;
  const int half = side / 2;
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256i lane_x = _mm256_mullo_epi32(lane, _mm256_set1_epi32(warp.xu));
  const __m256i lane_y = _mm256_mullo_epi32(lane, _mm256_set1_epi32(warp.yu));
  const __m256i step_x = _mm256_set1_epi32(8 * warp.xu);
  const __m256i step_y = _mm256_set1_epi32(8 * warp.yu);
  const __m256i stride = _mm256_set1_epi32(static_cast<int32_t>(image.stride));
  const __m256i one = _mm256_set1_epi32(kOne);
  const __m256i fraction = _mm256_set1_epi32(kOne - 1);
  const __m256i round7 = _mm256_set1_epi32(1 << 6);
  const __m256i round16 = _mm256_set1_epi32(1 << 15);
  // Bytes 0 and 1 of each gathered int32 (the pixel and its right neighbour) as two int16.
  const __m256i pair = _mm256_setr_epi8(0, -1, 1, -1, 4, -1, 5, -1, 8, -1, 9, -1, 12, -1, 13, -1, 0,
                                        -1, 1, -1, 4, -1, 5, -1, 8, -1, 9, -1, 12, -1, 13, -1);
  // Shuffle control base: bytes 1 and 3 of each int32 zero (high bit), byte 2 one further.
  const __m256i pair_base = _mm256_set1_epi32(static_cast<int32_t>(0x80018000u));
  const int tail = side - 8 * (groups - 1);  // pixels in the last group of a row
  const __m256i tail_mask = _mm256_cmpgt_epi32(_mm256_set1_epi32(tail), lane);
  const __m256i all = _mm256_set1_epi32(-1);
  // The gathers take an int pointer; they read 4 bytes at byte offsets (scale 1), no alignment.
  const auto* top_row = static_cast<const int*>(static_cast<const void*>(image.data));
  const auto* bottom_row =
      static_cast<const int*>(static_cast<const void*>(image.data + image.stride));
  const __m256i zero = _mm256_setzero_si256();
  // Per lane k (column 8 j + k of group j), int64 over the window: P the products, Q the running
  // sums within each row (column weights), R the running sums of P over rows (row weights).
  __m256i P_gx_lo = zero, P_gx_hi = zero, Q_gx_lo = zero, Q_gx_hi = zero, R_gx_lo = zero,
          R_gx_hi = zero;
  __m256i P_gy_lo = zero, P_gy_hi = zero, Q_gy_lo = zero, Q_gy_hi = zero, R_gy_lo = zero,
          R_gy_hi = zero;
  __m256i sq_lo = zero, sq_hi = zero;
  __m256i acc_e = zero;
  for (int v = 0; v < side; ++v) {
    int32_t xg = warp.x + v * warp.xv;  // the group's first pixel
    int32_t yg = warp.y + v * warp.yv;
    __m256i X = _mm256_add_epi32(_mm256_set1_epi32(xg), lane_x);
    __m256i Y = _mm256_add_epi32(_mm256_set1_epi32(yg), lane_y);
    const int16_t* t = T + v * tstride;
    const int16_t* sx = Sx + v * tstride;
    const int16_t* sy = Sy + v * tstride;
    // int32 per lane and row: products (a) and their running sums after each group (q); at most
    // n (n + 1) / 2 * 2^25 < 2^31 for n <= 10 groups. Squares: n * 2^26.
    __m256i a_gx = zero, q_gx = zero, a_gy = zero, q_gy = zero, a_sq = zero;
    for (int j = 0; j < groups; ++j) {
      const __m256i mask = j + 1 < groups ? all : tail_mask;
      // The four neighbours of each pixel as (left, right) int16 pairs of the top and bottom
      // rows. Where the group's 8 pixels span at most 15 columns and 2 rows (near-identity
      // shapes), from three 16-byte row loads and byte shuffles; else with gathers.
      const int n = j + 1 < groups ? 8 : tail;
      const int ix_a = xg >> kLkPosBits, ix_b = (xg + (n - 1) * warp.xu) >> kLkPosBits;
      const int iy_a = yg >> kLkPosBits, iy_b = (yg + (n - 1) * warp.yu) >> kLkPosBits;
      const int ix0 = std::min(ix_a, ix_b);
      const int iy0 = std::min(iy_a, iy_b);
      __m256i top, bottom;
      if (std::abs(ix_b - ix_a) <= 14 && std::abs(iy_b - iy_a) <= 1 && ix0 + 16 <= image.width) {
        const uint8_t* r0 = image.data + static_cast<std::ptrdiff_t>(iy0) * image.stride + ix0;
        // The third row only matters when the group spans two rows (it then exists).
        const int iy2 = std::min(iy0 + 2, image.height - 1);
        const uint8_t* r2 = image.data + static_cast<std::ptrdiff_t>(iy2) * image.stride + ix0;
        __m128i l0, l1, l2;
        std::memcpy(&l0, r0, sizeof(l0));
        std::memcpy(&l1, r0 + image.stride, sizeof(l1));
        std::memcpy(&l2, r2, sizeof(l2));
        // Control bytes (dx, -, dx + 1, -) per pixel: its two columns as int16 (dx <= 14).
        const __m256i dx =
            _mm256_sub_epi32(_mm256_srai_epi32(X, kLkPosBits), _mm256_set1_epi32(ix0));
        const __m256i control =
            _mm256_add_epi32(_mm256_add_epi32(dx, _mm256_slli_epi32(dx, 16)), pair_base);
        // Pixels whose row is iy0 + 1 take rows iy0 + 1 and iy0 + 2.
        const __m256i lower =
            _mm256_cmpgt_epi32(_mm256_srai_epi32(Y, kLkPosBits), _mm256_set1_epi32(iy0));
        const __m256i s0 = _mm256_shuffle_epi8(_mm256_broadcastsi128_si256(l0), control);
        const __m256i s1 = _mm256_shuffle_epi8(_mm256_broadcastsi128_si256(l1), control);
        const __m256i s2 = _mm256_shuffle_epi8(_mm256_broadcastsi128_si256(l2), control);
        top = _mm256_and_si256(_mm256_blendv_epi8(s0, s1, lower), mask);
        bottom = _mm256_and_si256(_mm256_blendv_epi8(s1, s2, lower), mask);
      } else {
        const __m256i offset =
            _mm256_add_epi32(_mm256_mullo_epi32(_mm256_srai_epi32(Y, kLkPosBits), stride),
                             _mm256_srai_epi32(X, kLkPosBits));
        top =
            _mm256_shuffle_epi8(_mm256_mask_i32gather_epi32(zero, top_row, offset, mask, 1), pair);
        bottom = _mm256_shuffle_epi8(_mm256_mask_i32gather_epi32(zero, bottom_row, offset, mask, 1),
                                     pair);
      }
      const __m256i fx = _mm256_and_si256(_mm256_srli_epi32(X, kCut), fraction);
      const __m256i fy = _mm256_and_si256(_mm256_srli_epi32(Y, kCut), fraction);
      const __m256i wx = _mm256_or_si256(_mm256_slli_epi32(fx, 16), _mm256_sub_epi32(one, fx));
      const __m256i wy = _mm256_or_si256(_mm256_slli_epi32(fy, 16), _mm256_sub_epi32(one, fy));
      const __m256i h0 = _mm256_srai_epi32(_mm256_add_epi32(_mm256_madd_epi16(top, wx), round7), 7);
      const __m256i h1 =
          _mm256_srai_epi32(_mm256_add_epi32(_mm256_madd_epi16(bottom, wx), round7), 7);
      const __m256i s = _mm256_srai_epi32(
          _mm256_add_epi32(_mm256_madd_epi16(_mm256_or_si256(h0, _mm256_slli_epi32(h1, 16)), wy),
                           round16),
          16);
      __m128i t16, sx16, sy16;
      std::memcpy(&t16, t + 8 * j, sizeof(t16));
      std::memcpy(&sx16, sx + 8 * j, sizeof(sx16));
      std::memcpy(&sy16, sy + 8 * j, sizeof(sy16));
      // Beyond the window the gathers give 0, so do the samples, and the template is 0 (padding).
      const __m256i e = _mm256_sub_epi32(s, _mm256_cvtepi16_epi32(t16));
      a_gx = _mm256_add_epi32(a_gx, _mm256_mullo_epi32(e, _mm256_cvtepi16_epi32(sx16)));
      q_gx = _mm256_add_epi32(q_gx, a_gx);
      a_gy = _mm256_add_epi32(a_gy, _mm256_mullo_epi32(e, _mm256_cvtepi16_epi32(sy16)));
      q_gy = _mm256_add_epi32(q_gy, a_gy);
      acc_e = _mm256_add_epi32(acc_e, e);
      a_sq = _mm256_add_epi32(a_sq, _mm256_mullo_epi32(e, e));
      X = _mm256_add_epi32(X, step_x);
      Y = _mm256_add_epi32(Y, step_y);
      xg += 8 * warp.xu;
      yg += 8 * warp.yu;
    }
    addWiden(a_gx, P_gx_lo, P_gx_hi);
    addWiden(q_gx, Q_gx_lo, Q_gx_hi);
    R_gx_lo = _mm256_add_epi64(R_gx_lo, P_gx_lo);
    R_gx_hi = _mm256_add_epi64(R_gx_hi, P_gx_hi);
    addWiden(a_gy, P_gy_lo, P_gy_hi);
    addWiden(q_gy, Q_gy_lo, Q_gy_hi);
    R_gy_lo = _mm256_add_epi64(R_gy_lo, P_gy_lo);
    R_gy_hi = _mm256_add_epi64(R_gy_hi, P_gy_hi);
    addWiden(a_sq, sq_lo, sq_hi);
  }
  // Column u = 8 j + k: sum_j j a_j = n a - q per row (q includes the last group); row v:
  // sum_v v row_v = side P - R (R includes the last row). Then relative to the centre.
  const auto reduce = [&](const Lanes64& p, const Lanes64& q, const Lanes64& r, int64_t& plain,
                          int64_t& u_weighted, int64_t& v_weighted) {
    int64_t total = 0, u_sum = 0, r_sum = 0;
    for (int k = 0; k < 8; ++k) {
      total += p.v[k];
      u_sum += (k + 8 * groups) * p.v[k] - 8 * q.v[k];
      r_sum += r.v[k];
    }
    plain = total;
    u_weighted = u_sum - half * total;
    v_weighted = side * total - r_sum - half * total;
  };
  LkAffineSums sums;
  reduce(lanes(P_gx_lo, P_gx_hi), lanes(Q_gx_lo, Q_gx_hi), lanes(R_gx_lo, R_gx_hi), sums.gx_e,
         sums.ugx_e, sums.vgx_e);
  reduce(lanes(P_gy_lo, P_gy_hi), lanes(Q_gy_lo, Q_gy_hi), lanes(R_gy_lo, R_gy_hi), sums.gy_e,
         sums.ugy_e, sums.vgy_e);
  const Lanes64 sq = lanes(sq_lo, sq_hi);
  sums.sum_sq = 0;
  for (const int64_t x : sq.v) sums.sum_sq += x;
  int32_t e_lanes[8];
  std::memcpy(e_lanes, &acc_e, sizeof(acc_e));
  sums.sum_e = 0;
  for (const int32_t x : e_lanes) sums.sum_e += x;
  out = sums;
}

}  // namespace

bool lkHaveAvx2() {
  static const bool have = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return have;
}

void lkAffineSumsAvx2(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                      const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                      LkAffineSums& out) {
  // n <= 10 groups per row (the int32 row sums above); the gathers read 4 bytes at each pixel,
  // 2 beyond its right neighbour: not past the end of the image's last row.
  constexpr int kMaxSide = 80;
  int32_t x_max = warp.x, y_max = warp.y;
  const int32_t du = (side - 1) * warp.xu, dv = (side - 1) * warp.xv;
  const int32_t eu = (side - 1) * warp.yu, ev = (side - 1) * warp.yv;
  x_max = std::max({warp.x, warp.x + du, warp.x + dv, warp.x + du + dv});
  y_max = std::max({warp.y, warp.y + eu, warp.y + ev, warp.y + eu + ev});
  const bool last_row = (y_max >> kLkPosBits) + 2 >= image.height;
  if (!lkHaveAvx2() || side > kMaxSide || (last_row && (x_max >> kLkPosBits) + 3 >= image.width)) {
    lkAffineSums128(image, warp, side, T, Sx, Sy, tstride, out);
    return;
  }
  affineSumsAvx2(image, warp, side, T, Sx, Sy, tstride, out);
}

}  // namespace epitrack

#endif  // EPITRACK_LK_AVX2

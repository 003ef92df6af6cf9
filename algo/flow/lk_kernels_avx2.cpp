// The affine LK kernel with AVX2 (x86-64 only): compiled for AVX2 through the target attribute in
// a baseline build and run only where the processor has it (lkHaveAvx2, checked once). Same
// integers as lkAffineSumsScalar (algo/flow/lk_kernels.hpp), bit for bit. 8 pixels per step, one
// per int32 lane: the neighbours by byte shuffles of three row loads where every group of 8 warped
// pixels spans at most 15 columns and 2 rows (shapes near the identity, away from the right and
// bottom edges: almost always), else by gathers; bilinear weights and products in int32 lanes.
#include "algo/flow/lk_kernels.hpp"
#include "algo/flow/lk_kernels_x86.hpp"
#include "algo/flow/simd_int16.hpp"

#if EPITRACK_LK_AVX2

#include <immintrin.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>

namespace epitrack {
namespace {

#define EPITRACK_AVX2 __attribute__((target("avx2")))
#define EPITRACK_AVX2_INLINE __attribute__((target("avx2"), always_inline)) inline

/// Sign-extends the 8 int32 lanes of `a` and adds them to the int64 lanes of acc[0] (0-3) and
/// acc[1] (4-7).
EPITRACK_AVX2_INLINE void addWiden(__m256i a, __m256i (&acc)[2]) {
  acc[0] = _mm256_add_epi64(acc[0], _mm256_cvtepi32_epi64(_mm256_castsi256_si128(a)));
  acc[1] = _mm256_add_epi64(acc[1], _mm256_cvtepi32_epi64(_mm256_extracti128_si256(a, 1)));
}

/// The lanes of acc as int64.
struct Lanes64 {
  int64_t v[8];
};
EPITRACK_AVX2_INLINE Lanes64 lanes(const __m256i (&acc)[2]) {
  Lanes64 l;
  std::memcpy(l.v, &acc[0], sizeof(acc[0]));
  std::memcpy(l.v + 4, &acc[1], sizeof(acc[1]));
  return l;
}

/// What every group of a window shares.
struct Setup {
  __m256i one, fraction, round_w, round_s, pair, pair_base, stride, step_x, step_y;
  const uint8_t* data;
  std::ptrdiff_t row_stride;
  const int* top_row;  // the gathers take an int pointer; they read 4 bytes at byte offsets
  const int* bottom_row;
  int32_t xu, yu;
};

/// One row's running sums: int32 per lane (products a, their running sums after each group q).
struct RowSums {
  __m256i X, Y;    // positions of the group's 8 pixels (16.16)
  int32_t xg, yg;  // the group's first pixel
  __m256i a_gx, q_gx, a_gy, q_gy, a_sq, acc_e;
};

/// One group of 8 pixels (n valid, the others masked off by `mask` when kTail). kShuffle: the
/// group spans at most 15 columns and 2 rows that may be read whole (see affineBody).
template <bool kShuffle, bool kTail>
EPITRACK_AVX2_INLINE void group(const Setup& c, RowSums& r, const int16_t* t, const int16_t* sx,
                                const int16_t* sy, int n, __m256i mask) {
  constexpr int kCut = kLkPosBits - kLkWeightBits;
  // The four neighbours of each pixel as (left, right) int16 pairs of the top and bottom rows.
  __m256i top, bottom;
  if constexpr (kShuffle) {
    // Three 16-byte row loads from the group's leftmost column and top row, and byte shuffles.
    const int ix_a = r.xg >> kLkPosBits, ix_b = (r.xg + (n - 1) * c.xu) >> kLkPosBits;
    const int iy_a = r.yg >> kLkPosBits, iy_b = (r.yg + (n - 1) * c.yu) >> kLkPosBits;
    const int ix0 = std::min(ix_a, ix_b);
    const int iy0 = std::min(iy_a, iy_b);
    const uint8_t* r0 = c.data + static_cast<std::ptrdiff_t>(iy0) * c.row_stride + ix0;
    __m128i l0, l1, l2;
    std::memcpy(&l0, r0, sizeof(l0));
    std::memcpy(&l1, r0 + c.row_stride, sizeof(l1));
    std::memcpy(&l2, r0 + 2 * c.row_stride, sizeof(l2));
    // Control bytes (dx, -, dx + 1, -) per pixel: its two columns as int16 (dx <= 14).
    const __m256i dx = _mm256_sub_epi32(_mm256_srai_epi32(r.X, kLkPosBits), _mm256_set1_epi32(ix0));
    const __m256i control =
        _mm256_add_epi32(_mm256_add_epi32(dx, _mm256_slli_epi32(dx, 16)), c.pair_base);
    // Pixels whose row is iy0 + 1 take rows iy0 + 1 and iy0 + 2.
    const __m256i lower =
        _mm256_cmpgt_epi32(_mm256_srai_epi32(r.Y, kLkPosBits), _mm256_set1_epi32(iy0));
    const __m256i s0 = _mm256_shuffle_epi8(_mm256_broadcastsi128_si256(l0), control);
    const __m256i s1 = _mm256_shuffle_epi8(_mm256_broadcastsi128_si256(l1), control);
    const __m256i s2 = _mm256_shuffle_epi8(_mm256_broadcastsi128_si256(l2), control);
    top = _mm256_blendv_epi8(s0, s1, lower);
    bottom = _mm256_blendv_epi8(s1, s2, lower);
    if constexpr (kTail) {
      top = _mm256_and_si256(top, mask);
      bottom = _mm256_and_si256(bottom, mask);
    }
  } else {
    const __m256i offset =
        _mm256_add_epi32(_mm256_mullo_epi32(_mm256_srai_epi32(r.Y, kLkPosBits), c.stride),
                         _mm256_srai_epi32(r.X, kLkPosBits));
    if constexpr (kTail) {
      const __m256i zero = _mm256_setzero_si256();
      top = _mm256_mask_i32gather_epi32(zero, c.top_row, offset, mask, 1);
      bottom = _mm256_mask_i32gather_epi32(zero, c.bottom_row, offset, mask, 1);
    } else {
      top = _mm256_i32gather_epi32(c.top_row, offset, 1);
      bottom = _mm256_i32gather_epi32(c.bottom_row, offset, 1);
    }
    // Bytes 0 and 1 of each int32 (the pixel and its right neighbour) as two int16.
    top = _mm256_shuffle_epi8(top, c.pair);
    bottom = _mm256_shuffle_epi8(bottom, c.pair);
  }
  // lkBilinear's weights from the 14-bit fractions (exact int32 products), the fourth the
  // remainder, as (w00, w01) and (w10, w11) int16 pairs; then lkAffineSample's sum.
  const __m256i fx = _mm256_and_si256(_mm256_srli_epi32(r.X, kCut), c.fraction);
  const __m256i fy = _mm256_and_si256(_mm256_srli_epi32(r.Y, kCut), c.fraction);
  const __m256i gx = _mm256_sub_epi32(c.one, fx);
  const __m256i gy = _mm256_sub_epi32(c.one, fy);
  const __m256i w00 =
      _mm256_srai_epi32(_mm256_add_epi32(_mm256_mullo_epi32(gx, gy), c.round_w), kLkWeightBits);
  const __m256i w01 =
      _mm256_srai_epi32(_mm256_add_epi32(_mm256_mullo_epi32(fx, gy), c.round_w), kLkWeightBits);
  const __m256i w10 =
      _mm256_srai_epi32(_mm256_add_epi32(_mm256_mullo_epi32(gx, fy), c.round_w), kLkWeightBits);
  const __m256i w11 = _mm256_sub_epi32(_mm256_sub_epi32(_mm256_sub_epi32(c.one, w00), w01), w10);
  const __m256i w0 = _mm256_or_si256(w00, _mm256_slli_epi32(w01, 16));
  const __m256i w1 = _mm256_or_si256(w10, _mm256_slli_epi32(w11, 16));
  const __m256i s = _mm256_srai_epi32(
      _mm256_add_epi32(_mm256_add_epi32(_mm256_madd_epi16(top, w0), _mm256_madd_epi16(bottom, w1)),
                       c.round_s),
      kLkWeightBits - kLkValueBits);
  __m128i t16, sx16, sy16;
  std::memcpy(&t16, t, sizeof(t16));
  std::memcpy(&sx16, sx, sizeof(sx16));
  std::memcpy(&sy16, sy, sizeof(sy16));
  // Beyond the window the neighbours are 0, so are the samples, and the template is 0 (padding).
  const __m256i e = _mm256_sub_epi32(s, _mm256_cvtepi16_epi32(t16));
  r.a_gx = _mm256_add_epi32(r.a_gx, _mm256_mullo_epi32(e, _mm256_cvtepi16_epi32(sx16)));
  r.q_gx = _mm256_add_epi32(r.q_gx, r.a_gx);
  r.a_gy = _mm256_add_epi32(r.a_gy, _mm256_mullo_epi32(e, _mm256_cvtepi16_epi32(sy16)));
  r.q_gy = _mm256_add_epi32(r.q_gy, r.a_gy);
  r.acc_e = _mm256_add_epi32(r.acc_e, e);
  r.a_sq = _mm256_add_epi32(r.a_sq, _mm256_mullo_epi32(e, e));
  r.X = _mm256_add_epi32(r.X, c.step_x);
  r.Y = _mm256_add_epi32(r.Y, c.step_y);
  r.xg += 8 * c.xu;
  r.yg += 8 * c.yu;
}

/// The window (see lkAffineSumsAvx2 for the valid domain).
template <bool kShuffle>
EPITRACK_AVX2_INLINE void affineBody(ImageView<const uint8_t> image, const LkAffineWarp& warp,
                                     int side, const int16_t* T, const int16_t* Sx,
                                     const int16_t* Sy, int tstride, LkAffineSums& out) {
  constexpr int32_t kOne = 1 << kLkWeightBits;
  const int groups = (side + 7) / 8;
  const int half = side / 2;
  const int tail = side - 8 * (groups - 1);  // pixels in the last group of a row
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256i lane_x = _mm256_mullo_epi32(lane, _mm256_set1_epi32(warp.xu));
  const __m256i lane_y = _mm256_mullo_epi32(lane, _mm256_set1_epi32(warp.yu));
  const __m256i tail_mask = _mm256_cmpgt_epi32(_mm256_set1_epi32(tail), lane);
  Setup c;
  c.one = _mm256_set1_epi32(kOne);
  c.fraction = _mm256_set1_epi32(kOne - 1);
  c.round_w = _mm256_set1_epi32(kOne >> 1);
  c.round_s = _mm256_set1_epi32(1 << (kLkWeightBits - kLkValueBits - 1));
  c.pair = _mm256_setr_epi8(0, -1, 1, -1, 4, -1, 5, -1, 8, -1, 9, -1, 12, -1, 13, -1, 0, -1, 1, -1,
                            4, -1, 5, -1, 8, -1, 9, -1, 12, -1, 13, -1);
  // Shuffle control base: bytes 1 and 3 of each int32 zero (high bit), byte 2 one further.
  c.pair_base = _mm256_set1_epi32(static_cast<int32_t>(0x80018000u));
  c.stride = _mm256_set1_epi32(static_cast<int32_t>(image.stride));
  c.step_x = _mm256_set1_epi32(8 * warp.xu);
  c.step_y = _mm256_set1_epi32(8 * warp.yu);
  c.data = image.data;
  c.row_stride = image.stride;
  c.top_row = static_cast<const int*>(static_cast<const void*>(image.data));
  c.bottom_row = static_cast<const int*>(static_cast<const void*>(image.data + image.stride));
  c.xu = warp.xu;
  c.yu = warp.yu;
  const __m256i zero = _mm256_setzero_si256();
  // Per lane k (column 8 j + k of group j), int64 over the window: P the products, Q the running
  // sums within each row (column weights), R the running sums of P over rows (row weights).
  __m256i P_gx[2] = {zero, zero}, Q_gx[2] = {zero, zero}, R_gx[2] = {zero, zero};
  __m256i P_gy[2] = {zero, zero}, Q_gy[2] = {zero, zero}, R_gy[2] = {zero, zero};
  __m256i sq[2] = {zero, zero};
  __m256i acc_e = zero;
  for (int v = 0; v < side; ++v) {
    // int32 per lane and row: products and their running sums after each group, at most
    // n (n + 1) / 2 * 2^25 < 2^31 for n <= 10 groups; squares n * 2^26.
    RowSums r;
    r.xg = warp.row_x[v];
    r.yg = warp.row_y[v];
    r.X = _mm256_add_epi32(_mm256_set1_epi32(r.xg), lane_x);
    r.Y = _mm256_add_epi32(_mm256_set1_epi32(r.yg), lane_y);
    r.a_gx = r.q_gx = r.a_gy = r.q_gy = r.a_sq = zero;
    r.acc_e = acc_e;
    const int16_t* t = T + v * tstride;
    const int16_t* sx = Sx + v * tstride;
    const int16_t* sy = Sy + v * tstride;
    for (int j = 0; j + 1 < groups; ++j, t += 8, sx += 8, sy += 8) {
      group<kShuffle, false>(c, r, t, sx, sy, 8, tail_mask);
    }
    group<kShuffle, true>(c, r, t, sx, sy, tail, tail_mask);
    acc_e = r.acc_e;
    addWiden(r.a_gx, P_gx);
    addWiden(r.q_gx, Q_gx);
    R_gx[0] = _mm256_add_epi64(R_gx[0], P_gx[0]);
    R_gx[1] = _mm256_add_epi64(R_gx[1], P_gx[1]);
    addWiden(r.a_gy, P_gy);
    addWiden(r.q_gy, Q_gy);
    R_gy[0] = _mm256_add_epi64(R_gy[0], P_gy[0]);
    R_gy[1] = _mm256_add_epi64(R_gy[1], P_gy[1]);
    addWiden(r.a_sq, sq);
  }
  // Column u = 8 j + k: sum_j j a_j = n a - q per row (q includes the last group); row v:
  // sum_v v row_v = side P - R (R includes the last row). Then relative to the centre.
  const auto reduce = [&](const Lanes64& p, const Lanes64& q, const Lanes64& rr, int64_t& plain,
                          int64_t& u_weighted, int64_t& v_weighted) {
    int64_t total = 0, u_sum = 0, r_sum = 0;
    for (int k = 0; k < 8; ++k) {
      total += p.v[k];
      u_sum += (k + 8 * groups) * p.v[k] - 8 * q.v[k];
      r_sum += rr.v[k];
    }
    plain = total;
    u_weighted = u_sum - half * total;
    v_weighted = side * total - r_sum - half * total;
  };
  LkAffineSums sums;
  reduce(lanes(P_gx), lanes(Q_gx), lanes(R_gx), sums.gx_e, sums.ugx_e, sums.vgx_e);
  reduce(lanes(P_gy), lanes(Q_gy), lanes(R_gy), sums.gy_e, sums.ugy_e, sums.vgy_e);
  const Lanes64 sq_lanes = lanes(sq);
  sums.sum_sq = 0;
  for (const int64_t x : sq_lanes.v) sums.sum_sq += x;
  int32_t e_lanes[8];
  std::memcpy(e_lanes, &acc_e, sizeof(acc_e));
  sums.sum_e = 0;
  for (const int32_t x : e_lanes) sums.sum_e += x;
  out = sums;
}

EPITRACK_AVX2 void affineSumsAvx2(ImageView<const uint8_t> image, const LkAffineWarp& warp,
                                  int side, const int16_t* T, const int16_t* Sx, const int16_t* Sy,
                                  int tstride, LkAffineSums& out, bool shuffle) {
  // Two instantiations: the row loads and shuffles for the whole window, or the gathers.
  if (shuffle) {
    affineBody<true>(image, warp, side, T, Sx, Sy, tstride, out);
  } else {
    affineBody<false>(image, warp, side, T, Sx, Sy, tstride, out);
  }
}

}  // namespace

bool lkHaveAvx2() {
  static const bool have = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return have;
}

namespace x86 {

/// True when every group of 8 pixels spans at most 15 columns and 2 rows whose 16 bytes from the
/// group's leftmost column lie inside the image (the shuffle path of `group`): a step of
/// 7 |xu| < 14 pixels and 7 |yu| < 1 pixel over a group, the window 16 columns and 3 rows from
/// the right and bottom edges (the third row is read even when unused).
static bool shuffleFits(ImageView<const uint8_t> image, const LkAffineWarp& warp, int32_t x_max,
                        int32_t y_max) {
  const int64_t group_x = 7 * static_cast<int64_t>(warp.xu < 0 ? -warp.xu : warp.xu);
  const int64_t group_y = 7 * static_cast<int64_t>(warp.yu < 0 ? -warp.yu : warp.yu);
  return group_x < (14 << kLkPosBits) && group_y < (1 << kLkPosBits) &&
         (x_max >> kLkPosBits) + 16 <= image.width && (y_max >> kLkPosBits) + 3 <= image.height;
}

bool affinePlan(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side, bool& shuffle) {
  // n <= 10 groups per row (the int32 row sums); the gathers read 4 bytes at each pixel, 2 beyond
  // its right neighbour: not past the end of the image's last row.
  constexpr int kMaxSide = 80;
  if (side > kMaxSide) return false;
  // The largest positions: each row's first or last pixel (positions are linear along a row).
  const int32_t du = (side - 1) * warp.xu, eu = (side - 1) * warp.yu;
  int32_t x_max = warp.row_x[0], y_max = warp.row_y[0];
  for (int v = 0; v < side; ++v) {
    x_max = std::max({x_max, warp.row_x[v], warp.row_x[v] + du});
    y_max = std::max({y_max, warp.row_y[v], warp.row_y[v] + eu});
  }
  shuffle = shuffleFits(image, warp, x_max, y_max);
  const bool last_row = (y_max >> kLkPosBits) + 2 >= image.height;
  return shuffle || !last_row || (x_max >> kLkPosBits) + 3 < image.width;
}

}  // namespace x86

void lkAffineSumsAvx2(ImageView<const uint8_t> image, const LkAffineWarp& warp, int side,
                      const int16_t* T, const int16_t* Sx, const int16_t* Sy, int tstride,
                      LkAffineSums& out) {
  bool shuffle = false;
  if (!lkHaveAvx2() || !x86::affinePlan(image, warp, side, shuffle)) {
    lkAffineSums128(image, warp, side, T, Sx, Sy, tstride, out);
    return;
  }
  affineSumsAvx2(image, warp, side, T, Sx, Sy, tstride, out, shuffle);
}

}  // namespace epitrack

#endif  // EPITRACK_LK_AVX2

#pragma once

// The few 128-bit integer operations the Lucas-Kanade kernels (algo/flow/lk_kernels.cpp) and the
// image core (pyramid, Scharr gradients) and the Shi-Tomasi detector need, on SSE2 (every x86-64)
// and NEON (every aarch64; ARMv7 at run time, see below), so that a kernel is written once. Every
// operation is exact integer arithmetic with a defined result per lane, so a vector kernel gives
// the same sums as the scalar reference, bit for bit, on every instruction set.
// EPITRACK_LK_SIMD is 1 when one of them is available, else 0 (the scalar kernels only).
//
// ARMv7 (armhf): Debian's baseline (armv7-a+fp, VFPv3-D16) does not include NEON, so the baseline
// build has no vector operations (EPITRACK_LK_SIMD 0). algo/flow/lk_kernels_neon32.cpp defines
// EPITRACK_SIMD_ARMV7_NEON and includes this header under `#pragma GCC target("fpu=neon")` (and
// nowhere else: the one file of an armhf build with these operations, all NEON): it
// gets the integer operations, written with ARMv7 intrinsics only, and its kernels run where the
// kernel reports NEON (lkHaveNeon). The float operations are aarch64 only: ARMv7 NEON flushes
// denormals to zero and has no vector square root, so it would not match scalar float code.

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>

#include "algo/flow/simd_isa.hpp"

#if defined(__SSE2__) || defined(_M_X64)
#include <emmintrin.h>
#define EPITRACK_LK_SIMD 1
#define EPITRACK_LK_SIMD_NAME "sse2"
#elif (defined(__ARM_NEON) && defined(__aarch64__)) || defined(EPITRACK_SIMD_ARMV7_NEON)
#include <arm_neon.h>
#define EPITRACK_LK_SIMD 1
#define EPITRACK_LK_SIMD_NAME "neon"
#else
#define EPITRACK_LK_SIMD 0
#define EPITRACK_LK_SIMD_NAME "scalar"
#endif

#if EPITRACK_LK_SIMD
namespace epitrack::simd {

#if defined(__SSE2__) || defined(_M_X64)
using I16x8 = __m128i;  ///< 8 x int16
using I32x4 = __m128i;  ///< 4 x int32

/// 8 bytes widened to 8 x int16 (unaligned; memcpy, no pointer cast).
inline I16x8 loadWidenU8(const uint8_t* p) {
  int64_t bits = 0;
  std::memcpy(&bits, p, 8);
  return _mm_unpacklo_epi8(_mm_cvtsi64_si128(bits), _mm_setzero_si128());
}
/// `n` (< 8) bytes widened to int16, the other lanes 0.
inline I16x8 loadWidenU8Partial(const uint8_t* p, int n) {
  int64_t bits = 0;
  std::memcpy(&bits, p, static_cast<std::size_t>(n));
  return _mm_unpacklo_epi8(_mm_cvtsi64_si128(bits), _mm_setzero_si128());
}
/// The same as loadWidenU8Partial, reading the 8 bytes that end at p[n - 1] instead (they must
/// be readable): one load and a shift instead of a copy of n bytes.
inline I16x8 loadWidenU8Tail(const uint8_t* p, int n) {
  static_assert(std::endian::native == std::endian::little);
  uint64_t bits = 0;
  std::memcpy(&bits, p + n - 8, 8);
  bits >>= 8 * (8 - n);
  return _mm_unpacklo_epi8(_mm_cvtsi64_si128(static_cast<int64_t>(bits)), _mm_setzero_si128());
}
inline I16x8 loadI16(const int16_t* p) {
  I16x8 v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
/// (a0, b0, a1, b1, a2, b2, a3, b3) and (a4, b4, ..., a7, b7).
inline I16x8 zipLo16(I16x8 a, I16x8 b) { return _mm_unpacklo_epi16(a, b); }
inline I16x8 zipHi16(I16x8 a, I16x8 b) { return _mm_unpackhi_epi16(a, b); }
/// (a, b) repeated.
inline I16x8 pair16(int16_t a, int16_t b) {
  return _mm_set1_epi32(static_cast<int32_t>(
      (static_cast<uint32_t>(static_cast<uint16_t>(b)) << 16) | static_cast<uint16_t>(a)));
}
inline I16x8 set16(int16_t a) { return _mm_set1_epi16(a); }
inline I16x8 sub16(I16x8 a, I16x8 b) { return _mm_sub_epi16(a, b); }
/// Lane i of the result: a[2i] * b[2i] + a[2i+1] * b[2i+1] in int32 (pmaddwd).
inline I32x4 madd(I16x8 a, I16x8 b) { return _mm_madd_epi16(a, b); }
inline I32x4 zero32() { return _mm_setzero_si128(); }
inline I32x4 set32(int32_t a) { return _mm_set1_epi32(a); }
inline I32x4 add32(I32x4 a, I32x4 b) { return _mm_add_epi32(a, b); }
template <int kShift>
inline I32x4 sra32(I32x4 a) {
  return _mm_srai_epi32(a, kShift);
}
/// Saturating narrowing of 8 x int32 to 8 x int16 (exact when they fit).
inline I16x8 pack32(I32x4 lo, I32x4 hi) { return _mm_packs_epi32(lo, hi); }
/// Reinterpretations between the lane widths (SSE2 has one register type for both).
inline I16x8 as16(I32x4 a) { return a; }
inline I32x4 as32(I16x8 a) { return a; }
/// 16 bytes (unaligned), as the raw register (see widenLoU8 / widenHiU8).
inline I16x8 loadU8x16(const uint8_t* p) {
  I16x8 v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
inline void storeI16(int16_t* p, I16x8 a) { std::memcpy(p, &a, sizeof(a)); }
inline I16x8 add16(I16x8 a, I16x8 b) { return _mm_add_epi16(a, b); }
template <int kShift>
inline I16x8 sll16(I16x8 a) {
  return _mm_slli_epi16(a, kShift);
}
/// The 8 int16 lanes narrowed to bytes with unsigned saturation, into 8 bytes of memory.
inline void storeU8x8(uint8_t* p, I16x8 a) {
  const int64_t bits = _mm_cvtsi128_si64(_mm_packus_epi16(a, a));
  std::memcpy(p, &bits, 8);
}
/// The low 16 bits of each product (exact when it fits int16).
inline I16x8 mul16(I16x8 a, I16x8 b) { return _mm_mullo_epi16(a, b); }
/// The exact int32 products of lanes 0-3 (lo) and 4-7 (hi).
inline void mulWiden16(I16x8 a, I16x8 b, I32x4& lo, I32x4& hi) {
  const __m128i l = _mm_mullo_epi16(a, b);
  const __m128i h = _mm_mulhi_epi16(a, b);
  lo = _mm_unpacklo_epi16(l, h);
  hi = _mm_unpackhi_epi16(l, h);
}
inline I32x4 loadI32(const int32_t* p) {
  I32x4 v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
/// The exact int32 products of lanes 0-3 (lo) and 4-7 (hi) taken as uint16 (each product below
/// 2^31 when both factors are at most 2^15).
inline void mulWidenU16(I16x8 a, I16x8 b, I32x4& lo, I32x4& hi) {
  const __m128i l = _mm_mullo_epi16(a, b);
  const __m128i h = _mm_mulhi_epu16(a, b);
  lo = _mm_unpacklo_epi16(l, h);
  hi = _mm_unpackhi_epi16(l, h);
}

// 4 x float, IEEE single precision with round-to-nearest (the same results as scalar float
// arithmetic without contraction, -ffp-contract=off).
using F32x4 = __m128;
inline F32x4 toF32(I32x4 a) { return _mm_cvtepi32_ps(a); }  // rounded to nearest, as a cast
inline F32x4 setF32(float a) { return _mm_set1_ps(a); }
inline F32x4 loadF32(const float* p) { return _mm_loadu_ps(p); }
inline void storeF32(float* p, F32x4 a) { _mm_storeu_ps(p, a); }
inline F32x4 addF32(F32x4 a, F32x4 b) { return _mm_add_ps(a, b); }
inline F32x4 subF32(F32x4 a, F32x4 b) { return _mm_sub_ps(a, b); }
inline F32x4 mulF32(F32x4 a, F32x4 b) { return _mm_mul_ps(a, b); }
inline F32x4 sqrtF32(F32x4 a) { return _mm_sqrt_ps(a); }  // correctly rounded
inline F32x4 maxF32(F32x4 a, F32x4 b) { return _mm_max_ps(a, b); }
/// Bit i set when lane i of a >= b (a > b); the comparisons of non-NaN values.
inline int maskGeF32(F32x4 a, F32x4 b) { return _mm_movemask_ps(_mm_cmpge_ps(a, b)); }
inline int maskGtF32(F32x4 a, F32x4 b) { return _mm_movemask_ps(_mm_cmpgt_ps(a, b)); }
/// The largest lane.
inline float maxLaneF32(F32x4 a) {
  float l[4];
  _mm_storeu_ps(l, a);
  return std::max(std::max(l[0], l[1]), std::max(l[2], l[3]));
}
/// The sum of the 4 lanes, exact in int64.
inline int64_t sum32(I32x4 a) {
  int32_t lanes[4];
  std::memcpy(lanes, &a, sizeof(lanes));
  return static_cast<int64_t>(lanes[0]) + lanes[1] + lanes[2] + lanes[3];
}
/// The 4 lanes into memory.
inline void store32(int32_t* p, I32x4 a) { std::memcpy(p, &a, sizeof(a)); }
/// (a0, a1, a2, a3).
inline I32x4 set32x4(int32_t a0, int32_t a1, int32_t a2, int32_t a3) {
  return _mm_setr_epi32(a0, a1, a2, a3);
}
/// (a0, ..., a7).
inline I16x8 set16x8(uint16_t a0, uint16_t a1, uint16_t a2, uint16_t a3, uint16_t a4, uint16_t a5,
                     uint16_t a6, uint16_t a7) {
  return _mm_setr_epi16(static_cast<int16_t>(a0), static_cast<int16_t>(a1),
                        static_cast<int16_t>(a2), static_cast<int16_t>(a3),
                        static_cast<int16_t>(a4), static_cast<int16_t>(a5),
                        static_cast<int16_t>(a6), static_cast<int16_t>(a7));
}
/// Bytes 0..7 (lo) or 8..15 (hi) of the register, widened to 8 x int16.
inline I16x8 widenLoU8(I16x8 a) { return _mm_unpacklo_epi8(a, _mm_setzero_si128()); }
inline I16x8 widenHiU8(I16x8 a) { return _mm_unpackhi_epi8(a, _mm_setzero_si128()); }
inline I32x4 sub32(I32x4 a, I32x4 b) { return _mm_sub_epi32(a, b); }
inline I32x4 bitAnd(I32x4 a, I32x4 b) { return _mm_and_si128(a, b); }
inline I32x4 bitOr(I32x4 a, I32x4 b) { return _mm_or_si128(a, b); }
/// Logical shifts of the 32-bit lanes.
template <int kShift>
inline I32x4 srl32(I32x4 a) {
  return _mm_srli_epi32(a, kShift);
}
template <int kShift>
inline I32x4 sll32(I32x4 a) {
  return _mm_slli_epi32(a, kShift);
}

#else  // NEON: aarch64, or ARMv7 with ARMv7 intrinsics only (where the two differ, both spelled)
using I16x8 = int16x8_t;
using I32x4 = int32x4_t;

#if defined(__aarch64__)
/// The int32 products of lanes 4-7.
inline int32x4_t mulHighS16(int16x8_t a, int16x8_t b) { return vmull_high_s16(a, b); }
inline uint32x4_t mulHighU16(uint16x8_t a, uint16x8_t b) { return vmull_high_u16(a, b); }
#else
inline int32x4_t mulHighS16(int16x8_t a, int16x8_t b) {
  return vmull_s16(vget_high_s16(a), vget_high_s16(b));
}
inline uint32x4_t mulHighU16(uint16x8_t a, uint16x8_t b) {
  return vmull_u16(vget_high_u16(a), vget_high_u16(b));
}
#endif

inline I16x8 loadWidenU8(const uint8_t* p) {
  uint8_t bytes[8];
  std::memcpy(bytes, p, 8);
  return vreinterpretq_s16_u16(vmovl_u8(vld1_u8(bytes)));
}
inline I16x8 loadWidenU8Partial(const uint8_t* p, int n) {
  uint8_t bytes[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  std::memcpy(bytes, p, static_cast<std::size_t>(n));
  return vreinterpretq_s16_u16(vmovl_u8(vld1_u8(bytes)));
}
inline I16x8 loadWidenU8Tail(const uint8_t* p, int n) {
  static_assert(std::endian::native == std::endian::little);
  uint64_t bits = 0;
  std::memcpy(&bits, p + n - 8, 8);
  bits >>= 8 * (8 - n);
  return vreinterpretq_s16_u16(vmovl_u8(vcreate_u8(bits)));
}
inline I16x8 loadI16(const int16_t* p) { return vld1q_s16(p); }
#if defined(__aarch64__)
inline I16x8 zipLo16(I16x8 a, I16x8 b) { return vzip1q_s16(a, b); }
inline I16x8 zipHi16(I16x8 a, I16x8 b) { return vzip2q_s16(a, b); }
#else
inline I16x8 zipLo16(I16x8 a, I16x8 b) { return vzipq_s16(a, b).val[0]; }
inline I16x8 zipHi16(I16x8 a, I16x8 b) { return vzipq_s16(a, b).val[1]; }
#endif
inline I16x8 pair16(int16_t a, int16_t b) {
  const int16_t v[8] = {a, b, a, b, a, b, a, b};
  return vld1q_s16(v);
}
inline I16x8 set16(int16_t a) { return vdupq_n_s16(a); }
inline I16x8 sub16(I16x8 a, I16x8 b) { return vsubq_s16(a, b); }
/// As SSE2's pmaddwd: widening products, then adjacent pairs added (wrapping as pmaddwd does).
inline I32x4 madd(I16x8 a, I16x8 b) {
  const int32x4_t lo = vmull_s16(vget_low_s16(a), vget_low_s16(b));
  const int32x4_t hi = mulHighS16(a, b);
#if defined(__aarch64__)
  return vpaddq_s32(lo, hi);
#else
  return vcombine_s32(vpadd_s32(vget_low_s32(lo), vget_high_s32(lo)),
                      vpadd_s32(vget_low_s32(hi), vget_high_s32(hi)));
#endif
}
inline I32x4 zero32() { return vdupq_n_s32(0); }
inline I32x4 set32(int32_t a) { return vdupq_n_s32(a); }
inline I32x4 add32(I32x4 a, I32x4 b) { return vaddq_s32(a, b); }
template <int kShift>
inline I32x4 sra32(I32x4 a) {
  return vshrq_n_s32(a, kShift);
}
inline I16x8 pack32(I32x4 lo, I32x4 hi) { return vcombine_s16(vqmovn_s32(lo), vqmovn_s32(hi)); }
inline int64_t sum32(I32x4 a) {
#if defined(__aarch64__)
  return vaddlvq_s32(a);
#else
  const int64x2_t pairs = vpaddlq_s32(a);
  return vgetq_lane_s64(pairs, 0) + vgetq_lane_s64(pairs, 1);
#endif
}
inline void store32(int32_t* p, I32x4 a) { vst1q_s32(p, a); }
inline I32x4 set32x4(int32_t a0, int32_t a1, int32_t a2, int32_t a3) {
  const int32_t v[4] = {a0, a1, a2, a3};
  return vld1q_s32(v);
}
inline I16x8 set16x8(uint16_t a0, uint16_t a1, uint16_t a2, uint16_t a3, uint16_t a4, uint16_t a5,
                     uint16_t a6, uint16_t a7) {
  uint16x8_t v = vdupq_n_u16(a0);
  v = vsetq_lane_u16(a1, v, 1);
  v = vsetq_lane_u16(a2, v, 2);
  v = vsetq_lane_u16(a3, v, 3);
  v = vsetq_lane_u16(a4, v, 4);
  v = vsetq_lane_u16(a5, v, 5);
  v = vsetq_lane_u16(a6, v, 6);
  v = vsetq_lane_u16(a7, v, 7);
  return vreinterpretq_s16_u16(v);
}
inline I16x8 widenLoU8(I16x8 a) {
  return vreinterpretq_s16_u16(vmovl_u8(vget_low_u8(vreinterpretq_u8_s16(a))));
}
inline I16x8 widenHiU8(I16x8 a) {
  return vreinterpretq_s16_u16(vmovl_u8(vget_high_u8(vreinterpretq_u8_s16(a))));
}
inline I32x4 sub32(I32x4 a, I32x4 b) { return vsubq_s32(a, b); }
inline I32x4 bitAnd(I32x4 a, I32x4 b) { return vandq_s32(a, b); }
inline I32x4 bitOr(I32x4 a, I32x4 b) { return vorrq_s32(a, b); }
template <int kShift>
inline I32x4 srl32(I32x4 a) {
  return vreinterpretq_s32_u32(vshrq_n_u32(vreinterpretq_u32_s32(a), kShift));
}
template <int kShift>
inline I32x4 sll32(I32x4 a) {
  return vshlq_n_s32(a, kShift);
}
/// Reinterpretations between the lane widths (SSE2 has one register type for both).
inline I16x8 as16(I32x4 a) { return vreinterpretq_s16_s32(a); }
inline I32x4 as32(I16x8 a) { return vreinterpretq_s32_s16(a); }
inline I16x8 loadU8x16(const uint8_t* p) { return vreinterpretq_s16_u8(vld1q_u8(p)); }
inline void storeI16(int16_t* p, I16x8 a) { vst1q_s16(p, a); }
inline I16x8 add16(I16x8 a, I16x8 b) { return vaddq_s16(a, b); }
template <int kShift>
inline I16x8 sll16(I16x8 a) {
  return vshlq_n_s16(a, kShift);
}
inline void storeU8x8(uint8_t* p, I16x8 a) { vst1_u8(p, vqmovun_s16(a)); }
inline I16x8 mul16(I16x8 a, I16x8 b) { return vmulq_s16(a, b); }
inline void mulWiden16(I16x8 a, I16x8 b, I32x4& lo, I32x4& hi) {
  lo = vmull_s16(vget_low_s16(a), vget_low_s16(b));
  hi = mulHighS16(a, b);
}
inline I32x4 loadI32(const int32_t* p) { return vld1q_s32(p); }
inline void mulWidenU16(I16x8 a, I16x8 b, I32x4& lo, I32x4& hi) {
  const uint16x8_t ua = vreinterpretq_u16_s16(a);
  const uint16x8_t ub = vreinterpretq_u16_s16(b);
  lo = vreinterpretq_s32_u32(vmull_u16(vget_low_u16(ua), vget_low_u16(ub)));
  hi = vreinterpretq_s32_u32(mulHighU16(ua, ub));
}

#if defined(__aarch64__)
using F32x4 = float32x4_t;
inline F32x4 toF32(I32x4 a) { return vcvtq_f32_s32(a); }
inline F32x4 setF32(float a) { return vdupq_n_f32(a); }
inline F32x4 loadF32(const float* p) { return vld1q_f32(p); }
inline void storeF32(float* p, F32x4 a) { vst1q_f32(p, a); }
inline F32x4 addF32(F32x4 a, F32x4 b) { return vaddq_f32(a, b); }
inline F32x4 subF32(F32x4 a, F32x4 b) { return vsubq_f32(a, b); }
inline F32x4 mulF32(F32x4 a, F32x4 b) { return vmulq_f32(a, b); }
inline F32x4 sqrtF32(F32x4 a) { return vsqrtq_f32(a); }
inline F32x4 maxF32(F32x4 a, F32x4 b) { return vmaxq_f32(a, b); }
inline int laneBits(uint32x4_t m) {
  const uint32_t bits[4] = {1, 2, 4, 8};
  return static_cast<int>(vaddvq_u32(vandq_u32(m, vld1q_u32(bits))));
}
inline int maskGeF32(F32x4 a, F32x4 b) { return laneBits(vcgeq_f32(a, b)); }
inline int maskGtF32(F32x4 a, F32x4 b) { return laneBits(vcgtq_f32(a, b)); }
inline float maxLaneF32(F32x4 a) { return vmaxvq_f32(a); }
#endif
#endif

}  // namespace epitrack::simd
#endif

#pragma once

#include <array>
#include <bit>
#include <cstdint>
#include <vector>

#include "algo/image/image_view.hpp"

namespace epitrack {

/// A 256-bit binary descriptor.
struct BinaryDescriptor {
  std::array<uint64_t, 4> bits{};
};

/// Set bits of a 64-bit word. x86-64 without -mpopcnt (the portable default build) would call
/// libgcc's table-driven __popcountdi2 for std::popcount: the SWAR sum (Hacker's Delight 5-1)
/// inline is faster; elsewhere (aarch64: CNT) the builtin is one instruction.
[[nodiscard]] inline int popcount64(uint64_t x) {
#if defined(__x86_64__) && !defined(__POPCNT__)
  x = x - ((x >> 1U) & 0x5555555555555555ULL);
  x = (x & 0x3333333333333333ULL) + ((x >> 2U) & 0x3333333333333333ULL);
  x = (x + (x >> 4U)) & 0x0f0f0f0f0f0f0f0fULL;
  return static_cast<int>((x * 0x0101010101010101ULL) >> 56U);
#else
  return std::popcount(x);
#endif
}

/// Number of differing bits (0..256).
[[nodiscard]] inline int hammingDistance(const BinaryDescriptor& a, const BinaryDescriptor& b) {
  return popcount64(a.bits[0] ^ b.bits[0]) + popcount64(a.bits[1] ^ b.bits[1]) +
         popcount64(a.bits[2] ^ b.bits[2]) + popcount64(a.bits[3] ^ b.bits[3]);
}

/// Summed-area table of an 8-bit image: `out` is (width + 1) x (height + 1), out(x, y) the sum of
/// the pixels above and left of (x, y). uint32 holds any image up to 16 Mpixel.
void integralImage(ImageView<const uint8_t> image, ImageView<uint32_t> out);

/// Oriented BRIEF in the manner of ORB (Rublee, Rabaud, Konolige & Bradski, ICCV 2011; BRIEF:
/// Calonder et al., ECCV 2010): 256 intensity comparisons between 5x5 box means at point pairs of
/// a fixed pattern, the pattern rotated to the patch orientation given by the intensity centroid
/// (Rosin 1999; ORB §3.2). The pattern is drawn once from a seeded generator (BRIEF's G II:
/// isotropic, near-Gaussian with sigma = patch size / 5, here the sum of four uniforms) inside a
/// disc of radius kPatchRadius, and pre-rotated into kAngleBins orientations with integer
/// (Q14) cosines, so every descriptor is integer arithmetic and identical on every platform.
/// Unlike ORB the pairs are not learnt (no training set): they are random and de-duplicated.
class OrientedBrief {
 public:
  static constexpr int kPatchRadius = 15;  ///< pattern disc and centroid disc radius, px
  static constexpr int kBoxRadius = 2;     ///< 5x5 box means
  static constexpr int kAngleBins = 30;    ///< 12 degrees each
  /// A keypoint needs this many pixels to every image edge (the rotated pattern and its boxes).
  static constexpr int kBorder = kPatchRadius + kBoxRadius + 1;

  explicit OrientedBrief(uint64_t seed = 0x6272696566ULL);

  /// Orientation bin (0..kAngleBins-1, counter-clockwise in image coordinates x right, y down)
  /// of the intensity centroid of the disc of radius kPatchRadius around pixel (x, y);
  /// (x, y) must be at least kBorder from every edge.
  [[nodiscard]] int orientationBin(ImageView<const uint8_t> image, int x, int y) const;

  /// The descriptor of pixel (x, y) for orientation `bin` from the image's integral image
  /// (`integralImage`); (x, y) at least kBorder from every edge of the image.
  void describe(ImageView<const uint32_t> integral, int x, int y, int bin,
                BinaryDescriptor& out) const;

  /// Angle of a bin centre, radians.
  [[nodiscard]] static double binAngle(int bin);

 private:
  struct Pair {
    int8_t x1, y1, x2, y2;
  };
  std::vector<Pair> pattern_;  // kAngleBins x 256, rotated
  std::array<int, kPatchRadius + 1> disc_half_width_{};
  std::array<int32_t, kAngleBins> cos_q14_{}, sin_q14_{};
};

}  // namespace epitrack

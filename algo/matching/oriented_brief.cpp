#include "algo/matching/oriented_brief.hpp"

#include <cmath>

#include "algo/math/random.hpp"

namespace epitrack {

void integralImage(ImageView<const uint8_t> image, ImageView<uint32_t> out) {
  EPITRACK_ASSERT(out.width == image.width + 1 && out.height == image.height + 1);
  uint32_t* first = out.row(0);
  for (int x = 0; x <= image.width; ++x) first[x] = 0;
  for (int y = 0; y < image.height; ++y) {
    const uint8_t* in = image.row(y);
    const uint32_t* above = out.row(y);
    uint32_t* row = out.row(y + 1);
    uint32_t run = 0;
    row[0] = 0;
    for (int x = 0; x < image.width; ++x) {
      run += in[x];
      row[x + 1] = above[x + 1] + run;
    }
  }
}

namespace {

constexpr int kBits = 256;
constexpr int kQ = 14;

// BRIEF's G II, sigma^2 = S^2 / 25 for the patch side S = 2 * kPatchRadius + 1: the sum of four
// uniforms on [-1/2, 1/2) has variance 1/3, scaled by sigma * sqrt(3).
int drawCoordinate(SplitMix64& rng) {
  constexpr double kSigma = (2.0 * OrientedBrief::kPatchRadius + 1.0) / 5.0;
  const double u1 = rng.uniform();
  const double u2 = rng.uniform();
  const double u3 = rng.uniform();
  const double u4 = rng.uniform();
  const double s = (u1 + u2 + u3 + u4) - 2.0;
  return static_cast<int>(std::lround(s * kSigma * 1.7320508075688772));
}

}  // namespace

double OrientedBrief::binAngle(int bin) { return 2.0 * M_PI * bin / kAngleBins; }

OrientedBrief::OrientedBrief(uint64_t seed) {
  for (int b = 0; b < kAngleBins; ++b) {
    cos_q14_[static_cast<std::size_t>(b)] =
        static_cast<int32_t>(std::lround(std::cos(binAngle(b)) * (1 << kQ)));
    sin_q14_[static_cast<std::size_t>(b)] =
        static_cast<int32_t>(std::lround(std::sin(binAngle(b)) * (1 << kQ)));
  }
  for (int dy = 0; dy <= kPatchRadius; ++dy) {
    int hw = 0;
    while ((hw + 1) * (hw + 1) + dy * dy <= kPatchRadius * kPatchRadius) ++hw;
    disc_half_width_[static_cast<std::size_t>(dy)] = hw;
  }
  // Points inside radius kPatchRadius - 1 stay inside kPatchRadius after a rotation and rounding.
  constexpr int kMaxR2 = (kPatchRadius - 1) * (kPatchRadius - 1);
  SplitMix64 rng(seed);
  std::vector<Pair> base;
  base.reserve(kBits);
  while (static_cast<int>(base.size()) < kBits) {
    const int x1 = drawCoordinate(rng);
    const int y1 = drawCoordinate(rng);
    const int x2 = drawCoordinate(rng);
    const int y2 = drawCoordinate(rng);
    if (x1 * x1 + y1 * y1 > kMaxR2 || x2 * x2 + y2 * y2 > kMaxR2) continue;
    if (x1 == x2 && y1 == y2) continue;
    bool duplicate = false;
    for (const Pair& p : base) {
      duplicate = duplicate || (p.x1 == x1 && p.y1 == y1 && p.x2 == x2 && p.y2 == y2) ||
                  (p.x1 == x2 && p.y1 == y2 && p.x2 == x1 && p.y2 == y1);
    }
    if (duplicate) continue;
    base.push_back(Pair{static_cast<int8_t>(x1), static_cast<int8_t>(y1), static_cast<int8_t>(x2),
                        static_cast<int8_t>(y2)});
  }
  pattern_.resize(static_cast<std::size_t>(kAngleBins) * kBits);
  const auto rotate = [](int x, int y, int32_t c, int32_t s, int8_t& rx, int8_t& ry) {
    rx = static_cast<int8_t>((x * c - y * s + (1 << (kQ - 1))) >> kQ);
    ry = static_cast<int8_t>((x * s + y * c + (1 << (kQ - 1))) >> kQ);
  };
  for (int b = 0; b < kAngleBins; ++b) {
    const int32_t c = cos_q14_[static_cast<std::size_t>(b)];
    const int32_t s = sin_q14_[static_cast<std::size_t>(b)];
    for (int i = 0; i < kBits; ++i) {
      const Pair& p = base[static_cast<std::size_t>(i)];
      Pair& r = pattern_[static_cast<std::size_t>(b * kBits + i)];
      rotate(p.x1, p.y1, c, s, r.x1, r.y1);
      rotate(p.x2, p.y2, c, s, r.x2, r.y2);
    }
  }
}

int OrientedBrief::orientationBin(ImageView<const uint8_t> image, int x, int y) const {
  EPITRACK_ASSERT(x >= kBorder && y >= kBorder && x < image.width - kBorder &&
                  y < image.height - kBorder);
  int64_t m10 = 0, m01 = 0;
  for (int dy = -kPatchRadius; dy <= kPatchRadius; ++dy) {
    const int hw = disc_half_width_[static_cast<std::size_t>(dy < 0 ? -dy : dy)];
    const uint8_t* row = image.row(y + dy) + x;
    int32_t row_sum = 0, row_moment = 0;
    for (int dx = -hw; dx <= hw; ++dx) {
      row_sum += row[dx];
      row_moment += dx * row[dx];
    }
    m10 += row_moment;
    m01 += static_cast<int64_t>(dy) * row_sum;
  }
  // The bin whose direction has the largest projection of the centroid offset (integer only).
  int best = 0;
  int64_t best_dot = INT64_MIN;
  for (int b = 0; b < kAngleBins; ++b) {
    const int64_t dot =
        m10 * cos_q14_[static_cast<std::size_t>(b)] + m01 * sin_q14_[static_cast<std::size_t>(b)];
    if (dot > best_dot) {
      best_dot = dot;
      best = b;
    }
  }
  return best;
}

void OrientedBrief::describe(ImageView<const uint32_t> integral, int x, int y, int bin,
                             BinaryDescriptor& out) const {
  EPITRACK_ASSERT(bin >= 0 && bin < kAngleBins);
  EPITRACK_ASSERT(x >= kBorder && y >= kBorder && x < integral.width - 1 - kBorder &&
                  y < integral.height - 1 - kBorder);
  const Pair* p = pattern_.data() + static_cast<std::ptrdiff_t>(bin) * kBits;
  const std::ptrdiff_t stride = integral.stride;
  // Box [cx - r, cx + r] x [cy - r, cy + r]: four corners of the summed-area table.
  const uint32_t* base = integral.data + static_cast<std::ptrdiff_t>(y) * stride + x;
  const std::ptrdiff_t lo = -kBoxRadius, hi = kBoxRadius + 1;
  const auto box = [&](int dx, int dy) -> uint32_t {
    const uint32_t* c = base + static_cast<std::ptrdiff_t>(dy) * stride + dx;
    return c[hi * stride + hi] - c[hi * stride + lo] - c[lo * stride + hi] + c[lo * stride + lo];
  };
  for (int w = 0; w < 4; ++w) {
    uint64_t word = 0;
    for (int i = 0; i < 64; ++i) {
      const Pair& q = p[w * 64 + i];
      word |= static_cast<uint64_t>(box(q.x1, q.y1) < box(q.x2, q.y2)) << i;
    }
    out.bits[static_cast<std::size_t>(w)] = word;
  }
}

}  // namespace epitrack

#include "algo/image/pyramid.hpp"

#include <algorithm>

#include "algo/flow/simd_int16.hpp"
#include "algo/image/border.hpp"
#include "algo/image/image.hpp"

namespace epitrack {

namespace {

/// The vertical pass over columns [x0, w): scratch = r0 + 4 r1 + 6 r2 + 4 r3 + r4 (<= 16 * 255).
void verticalScalar(const uint8_t* const (&r)[5], int x0, int w, uint16_t* scratch) {
  for (int x = x0; x < w; ++x) {
    scratch[x] = static_cast<uint16_t>(r[0][x] + 4 * r[1][x] + 6 * r[2][x] + 4 * r[3][x] + r[4][x]);
  }
}

/// The horizontal pass and decimation for outputs [xo0, xo1), reflect-101 at both ends:
/// out = (s[2x-2] + 4 s[2x-1] + 6 s[2x] + 4 s[2x+1] + s[2x+2] + 128) >> 8.
void horizontalScalar(const uint16_t* s, int w, int xo0, int xo1, uint8_t* out) {
  for (int xo = xo0; xo < xo1; ++xo) {
    const int xc = 2 * xo;
    uint32_t sum = 0;
    if (xc - 2 >= 0 && xc + 2 < w) {
      sum = static_cast<uint32_t>(s[xc - 2]) + 4u * s[xc - 1] + 6u * s[xc] + 4u * s[xc + 1] +
            s[xc + 2];
    } else {
      sum = static_cast<uint32_t>(s[reflect101(xc - 2, w)]) + 4u * s[reflect101(xc - 1, w)] +
            6u * s[xc] + 4u * s[reflect101(xc + 1, w)] + s[reflect101(xc + 2, w)];
    }
    out[xo] = static_cast<uint8_t>((sum + 128u) >> 8);
  }
}

/// Source rows 2y-2 .. 2y+2 of output row y, reflected at the borders.
void sourceRows(ImageView<const uint8_t> src, int yo, const uint8_t* (&r)[5]) {
  const int yc = 2 * yo;
  for (int k = 0; k < 5; ++k) r[k] = src.row(reflect101(yc - 2 + k, src.height));
}

}  // namespace

void pyrDownScalar(ImageView<const uint8_t> src, ImageView<uint8_t> dst, uint16_t* row_scratch) {
  EPITRACK_ASSERT(dst.width == (src.width + 1) / 2 && dst.height == (src.height + 1) / 2);
  for (int yo = 0; yo < dst.height; ++yo) {
    const uint8_t* r[5];
    sourceRows(src, yo, r);
    verticalScalar(r, 0, src.width, row_scratch);
    horizontalScalar(row_scratch, src.width, 0, dst.width, dst.row(yo));
  }
}

void pyrDown(ImageView<const uint8_t> src, ImageView<uint8_t> dst, uint16_t* row_scratch) {
#if EPITRACK_LK_SIMD
  EPITRACK_ASSERT(dst.width == (src.width + 1) / 2 && dst.height == (src.height + 1) / 2);
  using namespace simd;
  const int w = src.width;
  auto* scratch = reinterpret_cast<int16_t*>(row_scratch);  // values <= 4080: as int16
  const I16x8 w14 = pair16(1, 4);
  const I16x8 w64 = pair16(6, 4);
  const I16x8 w10 = pair16(1, 0);
  const I32x4 round = set32(128);
  for (int yo = 0; yo < dst.height; ++yo) {
    const uint8_t* r[5];
    sourceRows(src, yo, r);
    // Vertical pass, 16 columns per step: (r0 + r4) + 4 (r1 + r3) + 4 r2 + 2 r2, in int16.
    int x = 0;
    for (; x + 16 <= w; x += 16) {
      const I16x8 b0 = loadU8x16(r[0] + x), b1 = loadU8x16(r[1] + x), b2 = loadU8x16(r[2] + x);
      const I16x8 b3 = loadU8x16(r[3] + x), b4 = loadU8x16(r[4] + x);
      const auto column = [](I16x8 p0, I16x8 p1, I16x8 p2, I16x8 p3, I16x8 p4) {
        return add16(add16(add16(p0, p4), sll16<2>(add16(p1, p3))),
                     add16(sll16<2>(p2), sll16<1>(p2)));
      };
      storeI16(scratch + x,
               column(widenLoU8(b0), widenLoU8(b1), widenLoU8(b2), widenLoU8(b3), widenLoU8(b4)));
      storeI16(scratch + x + 8,
               column(widenHiU8(b0), widenHiU8(b1), widenHiU8(b2), widenHiU8(b3), widenHiU8(b4)));
    }
    verticalScalar(r, x, w, row_scratch);
    // Horizontal pass, 8 outputs per step from pairs (pmaddwd): (s[2x-2], s[2x-1]) . (1, 4) +
    // (s[2x], s[2x+1]) . (6, 4) + (s[2x+2], s[2x+3]) . (1, 0); the loads of outputs xo .. xo+7
    // read s[2 xo - 2] .. s[2 xo + 17], inside the row from xo = 1 while 2 xo + 17 < w.
    uint8_t* out = dst.row(yo);
    horizontalScalar(row_scratch, w, 0, std::min(1, dst.width), out);
    int xo = 1;
    for (; 2 * xo + 17 < w; xo += 8) {
      const int16_t* p = scratch + 2 * xo - 2;
      const auto four = [&](const int16_t* q) {
        return sra32<8>(add32(add32(add32(madd(loadI16(q), w14), madd(loadI16(q + 2), w64)),
                                    madd(loadI16(q + 4), w10)),
                              round));
      };
      storeU8x8(out + xo, pack32(four(p), four(p + 8)));
    }
    horizontalScalar(row_scratch, w, xo, dst.width, out);
  }
#else
  pyrDownScalar(src, dst, row_scratch);
#endif
}

bool Pyramid::configure(int width, int height, int level_count) {
  if (width <= 0 || height <= 0 || level_count < 1 || level_count > kMaxLevels) return false;
  std::array<std::size_t, kMaxLevels> offsets{};
  std::array<std::ptrdiff_t, kMaxLevels> strides{};
  std::size_t total = 0;
  for (int l = 0; l < level_count; ++l) {
    const auto w = static_cast<std::size_t>(pyramidLevelExtent(width, l));
    const auto h = static_cast<std::size_t>(pyramidLevelExtent(height, l));
    const std::size_t stride = roundUpBytes(w, 64);
    offsets[static_cast<std::size_t>(l)] = total;
    strides[static_cast<std::size_t>(l)] = static_cast<std::ptrdiff_t>(stride);
    total += stride * h;
  }
  storage_.reserve(total);
  scratch_.reserve(static_cast<std::size_t>(width));
  for (int l = 0; l < level_count; ++l) {
    const auto i = static_cast<std::size_t>(l);
    levels_[i] = ImageView<uint8_t>(storage_.data() + offsets[i], pyramidLevelExtent(width, l),
                                    pyramidLevelExtent(height, l), strides[i]);
  }
  for (int l = level_count; l < kMaxLevels; ++l) levels_[static_cast<std::size_t>(l)] = {};
  level_count_ = level_count;
  return true;
}

Pyramid::Status Pyramid::build(ImageView<const uint8_t> image) {
  if (level_count_ == 0) return Status::kNotConfigured;
  if (!sameSize(image, levels_[0])) return Status::kSizeMismatch;
  copyPixels(image, levels_[0]);
  return rebuildFromBase();
}

Pyramid::Status Pyramid::rebuildFromBase() {
  if (level_count_ == 0) return Status::kNotConfigured;
  for (int l = 1; l < level_count_; ++l) {
    const auto i = static_cast<std::size_t>(l);
    pyrDown(levels_[i - 1], levels_[i], scratch_.data());
  }
  return Status::kOk;
}

}  // namespace epitrack

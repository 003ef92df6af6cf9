#include "algo/image/pyramid.hpp"

#include "algo/image/border.hpp"
#include "algo/image/image.hpp"

namespace epitrack {

void pyrDown(ImageView<const uint8_t> src, ImageView<uint8_t> dst, uint16_t* row_scratch) {
  EPITRACK_ASSERT(dst.width == (src.width + 1) / 2 && dst.height == (src.height + 1) / 2);
  const int w = src.width;
  const int h = src.height;
  for (int yo = 0; yo < dst.height; ++yo) {
    // Vertical pass over source rows 2y-2 .. 2y+2 (reflected at the borders).
    const int yc = 2 * yo;
    const uint8_t* r0 = src.row(reflect101(yc - 2, h));
    const uint8_t* r1 = src.row(reflect101(yc - 1, h));
    const uint8_t* r2 = src.row(yc);
    const uint8_t* r3 = src.row(reflect101(yc + 1, h));
    const uint8_t* r4 = src.row(reflect101(yc + 2, h));
    for (int x = 0; x < w; ++x) {
      row_scratch[x] = static_cast<uint16_t>(r0[x] + 4 * r1[x] + 6 * r2[x] + 4 * r3[x] + r4[x]);
    }
    // Horizontal pass and decimation; interior without the border test.
    uint8_t* out = dst.row(yo);
    const auto tap = [&](int xc) -> uint32_t {
      return static_cast<uint32_t>(row_scratch[reflect101(xc - 2, w)]) +
             4u * row_scratch[reflect101(xc - 1, w)] + 6u * row_scratch[xc] +
             4u * row_scratch[reflect101(xc + 1, w)] + row_scratch[reflect101(xc + 2, w)];
    };
    int xo = 0;
    for (; xo < dst.width && 2 * xo - 2 < 0; ++xo)
      out[xo] = static_cast<uint8_t>((tap(2 * xo) + 128u) >> 8);
    for (; xo < dst.width && 2 * xo + 2 < w; ++xo) {
      const uint16_t* s = row_scratch + 2 * xo;
      const uint32_t sum = static_cast<uint32_t>(s[-2]) + 4u * s[-1] + 6u * s[0] + 4u * s[1] + s[2];
      out[xo] = static_cast<uint8_t>((sum + 128u) >> 8);
    }
    for (; xo < dst.width; ++xo) out[xo] = static_cast<uint8_t>((tap(2 * xo) + 128u) >> 8);
  }
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

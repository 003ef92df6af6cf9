#include "algo/matching/scale_pyramid.hpp"

#include <algorithm>
#include <cmath>

#include "algo/image/border.hpp"
#include "algo/image/pyramid.hpp"

namespace epitrack {

namespace {

constexpr int kPositionBits = 16;

// The 16.16 step of a downscale by `scale`, and the level extent it samples: the last sample
// (n - 1) * step must stay on the source.
int64_t resizeStep(double scale) { return std::llround(scale * (1 << kPositionBits)); }
int resizedExtent(int src, int64_t step) {
  return static_cast<int>((static_cast<int64_t>(src - 1) << kPositionBits) / step) + 1;
}

}  // namespace

void resizeDown(ImageView<const uint8_t> src, double scale, ImageView<uint8_t> blurred,
                ImageView<uint8_t> dst) {
  EPITRACK_ASSERT(sameSize(src, blurred) && scale >= 1.0);
  const int w = src.width;
  const int h = src.height;
  // [1 2 1] x [1 2 1] / 16, reflect-101 borders: a little low-pass before the decimation.
  for (int y = 0; y < h; ++y) {
    const uint8_t* r0 = src.row(reflect101(y - 1, h));
    const uint8_t* r1 = src.row(y);
    const uint8_t* r2 = src.row(reflect101(y + 1, h));
    uint8_t* out = blurred.row(y);
    const auto column = [&](int x) {
      return static_cast<int>(r0[x]) + 2 * static_cast<int>(r1[x]) + static_cast<int>(r2[x]);
    };
    for (int x = 0; x < w; ++x) {
      const int s = column(reflect101(x - 1, w)) + 2 * column(x) + column(reflect101(x + 1, w));
      out[x] = static_cast<uint8_t>((s + 8) >> 4);
    }
  }
  const int64_t step = resizeStep(scale);
  constexpr int kShift = kPositionBits - kResizeWeightBits;
  constexpr int kOne = 1 << kResizeWeightBits;
  for (int yo = 0; yo < dst.height; ++yo) {
    const int64_t sy = yo * step;
    const int y0 = static_cast<int>(sy >> kPositionBits);
    const int wy = static_cast<int>((sy & ((1 << kPositionBits) - 1)) >> kShift);
    const uint8_t* ra = blurred.row(std::min(y0, h - 1));
    const uint8_t* rb = blurred.row(std::min(y0 + 1, h - 1));
    uint8_t* out = dst.row(yo);
    for (int xo = 0; xo < dst.width; ++xo) {
      const int64_t sx = xo * step;
      const int x0 = static_cast<int>(sx >> kPositionBits);
      const int x1 = std::min(x0 + 1, w - 1);
      const int wx = static_cast<int>((sx & ((1 << kPositionBits) - 1)) >> kShift);
      const int top = ra[x0] * (kOne - wx) + ra[x1] * wx;
      const int bottom = rb[x0] * (kOne - wx) + rb[x1] * wx;
      // <= 255 * 2^22: fits int32.
      const int v = (top * (kOne - wy) + bottom * wy + (1 << (2 * kResizeWeightBits - 1))) >>
                    (2 * kResizeWeightBits);
      out[xo] = static_cast<uint8_t>(v);
    }
  }
}

ScalePyramid::ScalePyramid(int width, int height, int levels) : width_(width), height_(height) {
  levels = std::clamp(levels, 1, kMaxLevels);
  const int64_t step = resizeStep(std::sqrt(2.0));
  const double odd_scale = static_cast<double>(step) / (1 << kPositionBits);
  int count = 0;
  for (int l = 0; l < levels; ++l) {
    int w = width, h = height;
    double s = 1.0;
    if (l % 2 == 1) {
      w = resizedExtent(width, step);
      h = resizedExtent(height, step);
      s = odd_scale;
    }
    for (int k = 0; k < l / 2; ++k) {
      w = (w + 1) / 2;
      h = (h + 1) / 2;
      s *= 2.0;
    }
    if (w < 8 || h < 8) break;
    levels_[static_cast<std::size_t>(l)].allocate(w, h);
    scales_[static_cast<std::size_t>(l)] = s;
    ++count;
  }
  level_count_ = count;
  blurred_.allocate(width, height);
  row_scratch_.reserve(static_cast<std::size_t>(std::max(width, 1)));
}

ScalePyramid::Status ScalePyramid::build(ImageView<const uint8_t> image) {
  if (level_count_ == 0) return Status::kNotConfigured;
  if (image.width != width_ || image.height != height_) return Status::kSizeMismatch;
  copyPixels<uint8_t>(image, levels_[0].view());
  if (level_count_ > 1) resizeDown(image, scales_[1], blurred_.view(), levels_[1].view());
  for (int l = 2; l < level_count_; ++l) {
    pyrDown(levels_[static_cast<std::size_t>(l - 2)].constView(),
            levels_[static_cast<std::size_t>(l)].view(), row_scratch_.data());
  }
  return Status::kOk;
}

}  // namespace epitrack

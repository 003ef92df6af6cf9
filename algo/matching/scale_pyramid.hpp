#pragma once

#include <array>
#include <cstdint>

#include "algo/core/aligned_buffer.hpp"
#include "algo/image/image.hpp"
#include "algo/image/image_view.hpp"

namespace epitrack {

/// Downscales `src` by `scale` (> 1) into `dst` (sized by the caller): a [1 2 1]/4 separable
/// pre-filter, then bilinear sampling at src = scale * dst (pixel centres: dst pixel 0 sits on
/// src pixel 0, as in `pyrDown`). Fixed point: positions in 16.16, bilinear weights of
/// kResizeWeightBits that sum exactly to 1 << kResizeWeightBits per axis, one rounding at the end;
/// samples beyond the last source pixel clamp to it. `blurred` is scratch of src's size.
/// Never allocates.
inline constexpr int kResizeWeightBits = 11;
void resizeDown(ImageView<const uint8_t> src, double scale, ImageView<uint8_t> blurred,
                ImageView<uint8_t> dst);

/// A pyramid of scale factor sqrt(2) for scale-invariant features: even levels are 2:1 reductions
/// of level 0 (`pyrDown`), odd levels of a sqrt(2) downscale of level 0 (`resizeDown`), so level
/// l has scale 2^(l/2) with respect to level 0 and a level-l pixel (x, y) is at
/// (scale(l) x, scale(l) y) in level 0 (pixel centres, see `resizeDown`). Buffers are sized at
/// construction; `build` never allocates.
class ScalePyramid {
 public:
  static constexpr int kMaxLevels = 8;
  enum class Status { kOk, kSizeMismatch, kNotConfigured };

  ScalePyramid() = default;
  /// `levels`: 1..kMaxLevels (clamped), level 0 included. Levels smaller than 8x8 are dropped.
  ScalePyramid(int width, int height, int levels);

  Status build(ImageView<const uint8_t> image);

  [[nodiscard]] int levelCount() const { return level_count_; }
  [[nodiscard]] ImageView<const uint8_t> level(int l) const {
    EPITRACK_ASSERT(l >= 0 && l < level_count_);
    return levels_[static_cast<std::size_t>(l)].constView();
  }
  /// Level-l pixel to level-0 pixel factor, exactly as the levels were sampled.
  [[nodiscard]] double scale(int l) const { return scales_[static_cast<std::size_t>(l)]; }
  [[nodiscard]] int width() const { return width_; }
  [[nodiscard]] int height() const { return height_; }

 private:
  int width_ = 0;
  int height_ = 0;
  int level_count_ = 0;
  std::array<Image<uint8_t>, kMaxLevels> levels_;
  std::array<double, kMaxLevels> scales_{};
  Image<uint8_t> blurred_;  // resize scratch (level 0 size)
  AlignedBuffer<uint16_t> row_scratch_;
};

}  // namespace epitrack

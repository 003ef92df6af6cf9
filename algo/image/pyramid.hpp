#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "algo/core/aligned_buffer.hpp"
#include "algo/image/image_view.hpp"

namespace epitrack {

/// One 2:1 reduction: the separable 5-tap binomial low-pass [1 4 6 4 1]/16 in x and y, then every
/// second pixel (Burt & Adelson's Gaussian pyramid; Bouguet 2000 §2.1 uses the 3-tap [1/4 1/2 1/4],
/// the 5-tap kernel aliases less). Integer only: the vertical pass sums into uint16 (<= 16*255),
/// the horizontal pass rounds once, out = (sum of the 25 weights * pixels + 128) >> 8.
/// Border: reflect-101 (see border.hpp). `dst` must be ((src.width+1)/2, (src.height+1)/2);
/// `row_scratch` holds at least src.width values. Never allocates.
/// SSE2 / NEON where available (algo/flow/simd_int16.hpp), the same bytes as pyrDownScalar.
void pyrDown(ImageView<const uint8_t> src, ImageView<uint8_t> dst, uint16_t* row_scratch);
/// The scalar reference of pyrDown.
void pyrDownScalar(ImageView<const uint8_t> src, ImageView<uint8_t> dst, uint16_t* row_scratch);

/// Size of level `level` for a base of `base` pixels: each level is ceil(previous / 2).
[[nodiscard]] constexpr int pyramidLevelExtent(int base, int level) {
  for (int i = 0; i < level; ++i) base = (base + 1) / 2;
  return base;
}

/// An image pyramid held in one buffer; levels are views into it. Storage and the filter's scratch
/// row are sized in `configure`; `build` for a frame of the configured size never allocates.
class Pyramid {
 public:
  static constexpr int kMaxLevels = 8;  ///< level 0 (the base) plus up to 7 reductions

  enum class Status { kOk, kNotConfigured, kSizeMismatch };

  Pyramid() = default;
  /// See `configure`.
  Pyramid(int width, int height, int level_count) { configure(width, height, level_count); }

  /// Sizes the pyramid for `level_count` levels (base included, 1..kMaxLevels) of a
  /// width x height base. Returns false for an invalid size or level count.
  bool configure(int width, int height, int level_count);

  /// Copies `image` into level 0 and rebuilds every coarser level.
  Status build(ImageView<const uint8_t> image);

  /// Rebuilds levels 1.. from a base already written through `mutableBase()` (saves the copy
  /// when the caller decodes straight into the pyramid).
  Status rebuildFromBase();

  [[nodiscard]] ImageView<uint8_t> mutableBase() { return levels_[0]; }
  [[nodiscard]] int levelCount() const { return level_count_; }
  [[nodiscard]] ImageView<const uint8_t> level(int i) const {
    EPITRACK_ASSERT(i >= 0 && i < level_count_);
    return levels_[static_cast<std::size_t>(i)];
  }
  [[nodiscard]] int width() const { return levels_[0].width; }
  [[nodiscard]] int height() const { return levels_[0].height; }
  [[nodiscard]] std::size_t bytesReserved() const {
    return storage_.capacity() + scratch_.capacity() * sizeof(uint16_t);
  }

 private:
  AlignedBuffer<uint8_t> storage_;
  AlignedBuffer<uint16_t> scratch_;
  std::array<ImageView<uint8_t>, kMaxLevels> levels_{};
  int level_count_ = 0;
};

}  // namespace epitrack

#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "algo/core/assert.hpp"

namespace epitrack {

/// A non-owning view of a 2-D image: pointer, width, height and row stride in elements.
/// Read-only inputs are `ImageView<const T>`. Views never allocate and are cheap to copy.
template <typename T>
struct ImageView {
  T* data = nullptr;
  int width = 0;
  int height = 0;
  std::ptrdiff_t stride = 0;  ///< elements between the starts of two rows (>= width)

  constexpr ImageView() = default;
  constexpr ImageView(T* pixels, int w, int h, std::ptrdiff_t row_stride)
      : data(pixels), width(w), height(h), stride(row_stride) {}
  /// A view of a densely packed buffer (stride == width).
  constexpr ImageView(T* pixels, int w, int h) : data(pixels), width(w), height(h), stride(w) {}

  /// Implicit conversion to a read-only view.
  template <typename U = T, typename = std::enable_if_t<!std::is_const_v<U>>>
  constexpr operator ImageView<const U>() const {  // NOLINT(google-explicit-constructor)
    return ImageView<const U>(data, width, height, stride);
  }

  [[nodiscard]] constexpr bool empty() const {
    return data == nullptr || width <= 0 || height <= 0;
  }
  [[nodiscard]] constexpr T* row(int y) const {
    return data + static_cast<std::ptrdiff_t>(y) * stride;
  }
  [[nodiscard]] constexpr T& operator()(int x, int y) const { return row(y)[x]; }
  [[nodiscard]] constexpr bool contains(int x, int y) const {
    return x >= 0 && y >= 0 && x < width && y < height;
  }

  /// The rectangle [x, x+w) x [y, y+h) of this view, sharing its memory and stride.
  [[nodiscard]] ImageView subView(int x, int y, int w, int h) const {
    EPITRACK_ASSERT(x >= 0 && y >= 0 && w >= 0 && h >= 0 && x + w <= width && y + h <= height);
    return ImageView(data + static_cast<std::ptrdiff_t>(y) * stride + x, w, h, stride);
  }
};

/// True when both views have the same width and height.
template <typename A, typename B>
[[nodiscard]] constexpr bool sameSize(const ImageView<A>& a, const ImageView<B>& b) {
  return a.width == b.width && a.height == b.height;
}

}  // namespace epitrack

#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "algo/core/aligned_buffer.hpp"
#include "algo/image/image_view.hpp"

namespace epitrack {

/// An owning image whose rows start on 64-byte boundaries. It allocates once, in the constructor
/// or in `allocate`, and again only when asked for more bytes than it holds. Move-only.
template <typename T>
class Image {
 public:
  static constexpr std::size_t kRowAlignment = 64;

  Image() = default;
  Image(int width, int height) { allocate(width, height); }

  /// Sizes the image, reusing the buffer when it is large enough. Pixel contents are unspecified
  /// afterwards. Returns false (and keeps the old size) for a negative or overflowing size.
  bool allocate(int width, int height) {
    if (width < 0 || height < 0) return false;
    const std::size_t row_bytes =
        roundUpBytes(static_cast<std::size_t>(width) * sizeof(T), kRowAlignment);
    if (height > 0 &&
        row_bytes > static_cast<std::size_t>(PTRDIFF_MAX) / static_cast<std::size_t>(height)) {
      return false;
    }
    const std::size_t count = row_bytes / sizeof(T) * static_cast<std::size_t>(height);
    buffer_.reserve(count);
    view_ = ImageView<T>(buffer_.data(), width, height,
                         static_cast<std::ptrdiff_t>(row_bytes / sizeof(T)));
    return true;
  }

  void fill(const T& value) {
    for (int y = 0; y < view_.height; ++y) {
      T* r = view_.row(y);
      for (int x = 0; x < view_.width; ++x) r[x] = value;
    }
  }

  [[nodiscard]] ImageView<T> view() { return view_; }
  [[nodiscard]] ImageView<const T> view() const { return view_; }
  [[nodiscard]] ImageView<const T> constView() const { return view_; }
  [[nodiscard]] int width() const { return view_.width; }
  [[nodiscard]] int height() const { return view_.height; }
  [[nodiscard]] std::ptrdiff_t stride() const { return view_.stride; }
  [[nodiscard]] T* row(int y) { return view_.row(y); }
  [[nodiscard]] const T* row(int y) const { return view_.row(y); }
  [[nodiscard]] T& operator()(int x, int y) { return view_(x, y); }
  [[nodiscard]] const T& operator()(int x, int y) const { return view_(x, y); }
  [[nodiscard]] bool empty() const { return view_.empty(); }
  [[nodiscard]] std::size_t capacityBytes() const { return buffer_.capacity() * sizeof(T); }

 private:
  AlignedBuffer<T, kRowAlignment> buffer_;
  ImageView<T> view_;
};

/// Copies pixels between two views of the same size (the strides may differ).
template <typename T>
void copyPixels(ImageView<const T> src, ImageView<T> dst) {
  EPITRACK_ASSERT(sameSize(src, dst));
  for (int y = 0; y < src.height; ++y) {
    std::memcpy(dst.row(y), src.row(y), static_cast<std::size_t>(src.width) * sizeof(T));
  }
}

}  // namespace epitrack

#pragma once

#include <cstddef>
#include <memory>
#include <new>
#include <utility>

namespace epitrack {

/// A heap buffer of trivially copyable `T` aligned to `kAlignment` bytes. Allocates only in
/// `reserve` when the request exceeds the capacity; used for image and pyramid storage.
template <typename T, std::size_t kAlignment = 64>
class AlignedBuffer {
 public:
  AlignedBuffer() = default;
  explicit AlignedBuffer(std::size_t count) { reserve(count); }
  AlignedBuffer(AlignedBuffer&& other) noexcept { swap(other); }
  AlignedBuffer& operator=(AlignedBuffer&& other) noexcept {
    AlignedBuffer tmp(std::move(other));
    swap(tmp);
    return *this;
  }
  AlignedBuffer(const AlignedBuffer&) = delete;
  AlignedBuffer& operator=(const AlignedBuffer&) = delete;
  ~AlignedBuffer() = default;

  /// Ensures room for `count` elements; returns true when it had to allocate.
  bool reserve(std::size_t count) {
    if (count <= capacity_) return false;
    data_.reset(static_cast<T*>(::operator new (count * sizeof(T), std::align_val_t{kAlignment})));
    capacity_ = count;
    return true;
  }

  [[nodiscard]] T* data() { return data_.get(); }
  [[nodiscard]] const T* data() const { return data_.get(); }
  [[nodiscard]] std::size_t capacity() const { return capacity_; }

  void swap(AlignedBuffer& other) noexcept {
    std::swap(data_, other.data_);
    std::swap(capacity_, other.capacity_);
  }

 private:
  struct Delete {
    void operator()(T* p) const { ::operator delete (p, std::align_val_t{kAlignment}); }
  };
  std::unique_ptr<T, Delete> data_;
  std::size_t capacity_ = 0;
};

/// Rounds a byte count up to a multiple of `alignment` (a power of two).
constexpr std::size_t roundUpBytes(std::size_t bytes, std::size_t alignment) {
  return (bytes + alignment - 1) & ~(alignment - 1);
}

}  // namespace epitrack

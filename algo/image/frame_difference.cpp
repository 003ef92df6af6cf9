#include "algo/image/frame_difference.hpp"

namespace epitrack {

bool framesNearlyEqual(ImageView<const uint8_t> a, ImageView<const uint8_t> b,
                       uint32_t max_mean_abs_diff_q8) {
  if (a.empty() || b.empty() || a.width != b.width || a.height != b.height) return false;
  // sum |a - b| <= max / 256 * pixels, compared as sum * 256 <= max * pixels in 64 bits
  // (8.3e6 pixels * 255 * 256 < 2^40).
  const uint64_t pixels = static_cast<uint64_t>(a.width) * static_cast<uint64_t>(a.height);
  const uint64_t bound = static_cast<uint64_t>(max_mean_abs_diff_q8) * pixels;
  uint64_t sum_q8 = 0;
  for (int y = 0; y < a.height; ++y) {
    const uint8_t* ra = a.row(y);
    const uint8_t* rb = b.row(y);
    uint32_t row_sum = 0;  // <= 255 * width, fits for any width below 16.8 million
    for (int x = 0; x < a.width; ++x) {
      const int d = static_cast<int>(ra[x]) - static_cast<int>(rb[x]);
      row_sum += static_cast<uint32_t>(d < 0 ? -d : d);
    }
    sum_q8 += static_cast<uint64_t>(row_sum) << 8;
    if (sum_q8 > bound) return false;
  }
  return true;
}

}  // namespace epitrack

#pragma once

namespace epitrack {

/// Border rule of every epitrack filter: reflect-101 (`... 2 1 | 0 1 2 ... n-1 | n-2 ...`), the
/// edge pixel is not repeated (OpenCV's BORDER_REFLECT_101). Valid for any index when n >= 1;
/// a one-pixel extent maps everything to 0.
[[nodiscard]] constexpr int reflect101(int i, int n) {
  if (n == 1) return 0;
  const int period = 2 * (n - 1);
  i %= period;
  if (i < 0) i += period;
  return i < n ? i : period - i;
}

}  // namespace epitrack

#include "algo/geometry/point_normalization.hpp"

#include <cmath>
#include <utility>

namespace epitrack {

bool hartleyNormalization(std::span<const Eigen::Vector2d> points, std::span<const int> indices,
                          Eigen::Matrix3d& T) {
  const std::size_t n = indices.empty() ? points.size() : indices.size();
  if (n == 0) return false;
  auto at = [&](std::size_t i) -> const Eigen::Vector2d& {
    return indices.empty() ? points[i] : points[static_cast<std::size_t>(indices[i])];
  };
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < n; ++i) c += at(i);
  c /= static_cast<double>(n);
  double d = 0.0;
  for (std::size_t i = 0; i < n; ++i) d += (at(i) - c).norm();
  d /= static_cast<double>(n);
  if (!(d > 1e-12) || !std::isfinite(d)) return false;
  const double s = std::sqrt(2.0) / d;
  T << s, 0, -s * c.x(), 0, s, -s * c.y(), 0, 0, 1;
  return true;
}

bool nullVector8x9(Eigen::Matrix<double, 8, 9> A, Eigen::Matrix<double, 9, 1>& v) {
  int col_of[9] = {0, 1, 2, 3, 4, 5, 6, 7, 8};
  double max_abs = A.cwiseAbs().maxCoeff();
  if (!(max_abs > 0.0) || !std::isfinite(max_abs)) return false;
  for (int k = 0; k < 8; ++k) {
    // Full pivot over the remaining block.
    int pr = k, pc = k;
    double best = 0.0;
    for (int r = k; r < 8; ++r) {
      for (int c = k; c < 9; ++c) {
        const double a = std::abs(A(r, c));
        if (a > best) {
          best = a;
          pr = r;
          pc = c;
        }
      }
    }
    if (best <= 1e-12 * max_abs) return false;
    if (pr != k) A.row(pr).swap(A.row(k));
    if (pc != k) {
      A.col(pc).swap(A.col(k));
      std::swap(col_of[pc], col_of[k]);
    }
    const double inv = 1.0 / A(k, k);
    for (int r = 0; r < 8; ++r) {
      if (r == k) continue;
      const double f = A(r, k) * inv;
      if (f != 0.0) A.row(r) -= f * A.row(k);
    }
  }
  // Reduced form: A(k,k) x_k + A(k,8) x_8 = 0, with x_8 = 1 (in pivoted order).
  Eigen::Matrix<double, 9, 1> x;
  x(8) = 1.0;
  for (int k = 0; k < 8; ++k) x(k) = -A(k, 8) / A(k, k);
  for (int k = 0; k < 9; ++k) v(col_of[k]) = x(k);
  const double n = v.norm();
  if (!(n > 0.0) || !std::isfinite(n)) return false;
  v /= n;
  return true;
}

}  // namespace epitrack

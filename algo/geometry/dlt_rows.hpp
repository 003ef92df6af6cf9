#pragma once

#include <Eigen/Core>

namespace epitrack {

/// The coefficients of the epipolar constraint b^T M a = 0 as a linear equation in the row-major
/// 9-vector of M (Hartley & Zisserman eq. 11.3): one row of the eight-point and five-point systems.
inline Eigen::Matrix<double, 9, 1> epipolarCoefficients(const Eigen::Vector2d& a,
                                                        const Eigen::Vector2d& b) {
  Eigen::Matrix<double, 9, 1> r;
  r << b.x() * a.x(), b.x() * a.y(), b.x(), b.y() * a.x(), b.y() * a.y(), b.y(), a.x(), a.y(), 1.0;
  return r;
}

/// The 3x3 matrix whose rows are m(0..2), m(3..5), m(6..8): a direct linear transform's solution
/// vector (F, E or H) back in matrix form.
inline Eigen::Matrix3d matrix3FromRowMajor(const Eigen::Matrix<double, 9, 1>& m) {
  Eigen::Matrix3d M;
  M << m(0), m(1), m(2), m(3), m(4), m(5), m(6), m(7), m(8);
  return M;
}

}  // namespace epitrack

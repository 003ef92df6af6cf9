#pragma once

#include <span>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace epitrack {

/// Hartley normalization (Hartley 1997; Hartley & Zisserman §4.4.4): a similarity T moving the
/// centroid of the selected points to the origin with mean distance sqrt(2). `indices` empty means
/// all points. Returns false when the points coincide (no scale).
bool hartleyNormalization(std::span<const Eigen::Vector2d> points, std::span<const int> indices,
                          Eigen::Matrix3d& T);

/// The unit null vector of an 8x9 system by Gaussian elimination with full pivoting (the minimal
/// eight-point and four-point-DLT solves). Returns false when the rank is below 8.
bool nullVector8x9(Eigen::Matrix<double, 8, 9> A, Eigen::Matrix<double, 9, 1>& v);

}  // namespace epitrack

#pragma once

#include <cmath>

#include <Eigen/Core>

#include "algo/geometry/camera_intrinsics.hpp"

namespace epitrack {

/// Normalized undistorted coordinates of pixel (x, y): the radial model of CameraIntrinsics
/// (p_d = p (1 + k1 r^2 + k2 r^4)) inverted by fixed-point iteration p = p_d / (1 + k1 r^2 +
/// k2 r^4), which converges for the distortions of real lenses (|k1| < 0.5 over the image) in a
/// few steps.
inline Eigen::Vector2d undistortPixel(const CameraIntrinsics& K, double x, double y,
                                      int iterations = 10) {
  Eigen::Vector2d d((x - K.cx) / K.fx, (y - K.cy) / K.fy);  // not const: returned by move
  if (!K.hasDistortion()) return d;
  Eigen::Vector2d p = d;
  for (int i = 0; i < iterations; ++i) {
    const double r2 = p.squaredNorm();
    p = d / (1.0 + K.k1 * r2 + K.k2 * r2 * r2);
  }
  return p;
}

/// Pixel of the normalized undistorted point `p`: the radial model of CameraIntrinsics applied,
/// then the focal and principal point (the inverse of undistortPixel).
inline Eigen::Vector2d distortToPixel(const CameraIntrinsics& K, const Eigen::Vector2d& p) {
  const double r2 = p.squaredNorm();
  const double s = 1.0 + K.k1 * r2 + K.k2 * r2 * r2;
  return {K.cx + K.fx * s * p.x(), K.cy + K.fy * s * p.y()};
}

/// Normalized undistorted coordinates of the normalized distorted point `d` under the radial
/// model p_d = p (1 + k1 r^2 + k2 r^4), by Newton's method on the radius (r + k1 r^3 + k2 r^5 =
/// |d|). The fixed-point iteration of undistortPixel contracts only while |2 k1 r^2| is well
/// below 1 + k1 r^2: with k1 = -0.28 it is still 4e-3 px off after 10 steps at r = 0.64 and
/// diverges at r = 0.8, the corner of a 640x480 image at f = 500 px, where Newton converges in
/// four steps. Where the model folds (its radius stops growing), the radius is held at the fold.
inline Eigen::Vector2d undistortNormalized(double k1, double k2, const Eigen::Vector2d& d) {
  const double rd = d.norm();
  if ((k1 == 0.0 && k2 == 0.0) || !(rd > 0.0)) return d;
  double r = rd;
  for (int i = 0; i < 20; ++i) {
    const double r2 = r * r;
    const double g = r * (1.0 + k1 * r2 + k2 * r2 * r2) - rd;
    const double dg = 1.0 + 3.0 * k1 * r2 + 5.0 * k2 * r2 * r2;
    if (!(dg > 1e-6)) break;  // at or beyond the fold
    const double step = g / dg;
    r -= step;
    if (!(r > 0.0)) {
      r = 0.5 * (r + step);  // overshot through zero: halve back
    }
    if (std::abs(step) < 1e-14 * (1.0 + r)) break;
  }
  return d * (r / rd);
}

}  // namespace epitrack

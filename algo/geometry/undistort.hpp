#pragma once

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

}  // namespace epitrack

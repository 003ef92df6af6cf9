#pragma once

#include <Eigen/Core>

namespace epitrack::synth {

/// Pinhole camera with optional radial distortion, in the conventions of ARCHITECTURE.md: pixel
/// origin at the centre of the top-left pixel, x right, y down, z forward; distortion maps
/// normalized undistorted (x, y) to (x, y) * (1 + k1 r^2 + k2 r^4).
struct CameraModel {
  int width = 0;
  int height = 0;
  double fx = 0.0;
  double fy = 0.0;
  double cx = 0.0;
  double cy = 0.0;
  double k1 = 0.0;
  double k2 = 0.0;

  /// Square pixels, principal point at ((w-1)/2, (h-1)/2).
  static CameraModel centered(int width, int height, double focal) {
    CameraModel c;
    c.width = width;
    c.height = height;
    c.fx = c.fy = focal;
    c.cx = (width - 1) * 0.5;
    c.cy = (height - 1) * 0.5;
    return c;
  }
  [[nodiscard]] bool hasDistortion() const { return k1 != 0.0 || k2 != 0.0; }

  [[nodiscard]] Eigen::Vector2d distortNormalized(const Eigen::Vector2d& n) const {
    const double r2 = n.squaredNorm();
    return n * (1.0 + k1 * r2 + k2 * r2 * r2);
  }
  /// Inverse of distortNormalized by fixed-point iteration (converges for the mild distortion
  /// of real lenses; 30 iterations are plenty for |k1| < 0.5).
  [[nodiscard]] Eigen::Vector2d undistortNormalized(const Eigen::Vector2d& d) const {
    if (!hasDistortion()) return d;
    Eigen::Vector2d n = d;
    for (int i = 0; i < 30; ++i) {
      const double r2 = n.squaredNorm();
      n = d / (1.0 + k1 * r2 + k2 * r2 * r2);
    }
    return n;
  }
  /// Camera-frame point to pixel; false behind the camera.
  bool project(const Eigen::Vector3d& p_c, Eigen::Vector2d& px) const {
    if (p_c.z() <= 1e-9) return false;
    const Eigen::Vector2d d =
        distortNormalized(Eigen::Vector2d(p_c.x() / p_c.z(), p_c.y() / p_c.z()));
    px = Eigen::Vector2d(fx * d.x() + cx, fy * d.y() + cy);
    return true;
  }
  /// Pixel to the normalized undistorted ray (x, y) with z = 1.
  [[nodiscard]] Eigen::Vector2d pixelToNormalized(double x, double y) const {
    return undistortNormalized(Eigen::Vector2d((x - cx) / fx, (y - cy) / fy));
  }
};

}  // namespace epitrack::synth

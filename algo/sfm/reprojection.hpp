#pragma once

#include <limits>

#include <Eigen/Core>

#include "algo/geometry/pose.hpp"

namespace epitrack {

/// Reprojection error in pixels of a point already in camera coordinates, `X_c`, against the
/// normalized (undistorted) observation `n`, for a camera of focal `focal_px`: |pi(X_c) - n| f.
/// Returns false (and `error_px` = +inf) when the point is not in front of the camera (z <= 0 or
/// not a number): every caller of the solver and the live map skips or rejects such a point.
inline bool reprojectionErrorPx(const Eigen::Vector3d& X_c, const Eigen::Vector2d& n,
                                double focal_px, double& error_px) {
  if (!(X_c.z() > 0.0)) {
    error_px = std::numeric_limits<double>::infinity();
    return false;
  }
  error_px = (X_c.hnormalized() - n).norm() * focal_px;
  return true;
}

/// The same for a world point `X` seen by a camera of pose `pose` (world to camera).
inline bool reprojectionErrorPx(const PoseCw& pose, const Eigen::Vector3d& X,
                                const Eigen::Vector2d& n, double focal_px, double& error_px) {
  return reprojectionErrorPx(pose.toCamera(X), n, focal_px, error_px);
}

}  // namespace epitrack

#pragma once

#include <algorithm>
#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace epitrack {

/// A camera pose as the world-to-camera transform x_c = R_cw X_w + t_cw (the form projection
/// uses). The ARCHITECTURE.md output pose T_wc is its inverse: R_wc = R_cw^T, p_wc = -R_cw^T t_cw.
struct PoseCw {
  Eigen::Matrix3d R_cw = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t_cw = Eigen::Vector3d::Zero();

  [[nodiscard]] Eigen::Vector3d toCamera(const Eigen::Vector3d& X) const { return R_cw * X + t_cw; }
  [[nodiscard]] Eigen::Vector3d centre() const { return -R_cw.transpose() * t_cw; }
};

/// The cross-product matrix [v]x: [v]x u = v x u.
inline Eigen::Matrix3d skewSymmetric(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return S;
}

/// Rotation by the axis-angle vector w (Rodrigues), exact for small angles too.
inline Eigen::Matrix3d expSo3(const Eigen::Vector3d& w) {
  const double theta2 = w.squaredNorm();
  const Eigen::Matrix3d W = skewSymmetric(w);
  if (theta2 < 1e-16) return Eigen::Matrix3d::Identity() + W + 0.5 * W * W;
  const double theta = std::sqrt(theta2);
  return Eigen::Matrix3d::Identity() + (std::sin(theta) / theta) * W +
         ((1.0 - std::cos(theta)) / theta2) * W * W;
}

/// Rotation vector of R (the inverse of expSo3 for angles below pi).
inline Eigen::Vector3d logSo3(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

/// Angle in radians of the rotation R (0..pi).
inline double rotationAngle(const Eigen::Matrix3d& R) {
  const double c = std::clamp(0.5 * (R.trace() - 1.0), -1.0, 1.0);
  return std::acos(c);
}

}  // namespace epitrack

#pragma once

// Axis conventions shared by the exporters and their tests.
//
// Ours (ARCHITECTURE.md): camera x right, y down, z forward; poses T_wc. The scene frame of
// algo/sfm/scene_frame.hpp has +Z up.
// Blender: world +Z up (same as our scene frame, so the world is written unchanged); a camera
// object looks down its local -Z with +Y up, i.e. its axes in our camera frame are (x, -y, -z).
// Nuke: world +Y up; cameras look down -Z with +Y up. Our world is rotated by -90 degrees about X
// (x, y, z) -> (x, z, -y) so that our +Z up becomes Nuke's +Y up.

#include <algorithm>
#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace epitrack::io {

/// Our camera axes -> OpenGL-style camera axes (x right, y up, looking down -z).
inline Eigen::Matrix3d cameraToGlAxes() { return Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal(); }

/// World rotation applied for Nuke: our (x, y, z) -> Nuke (x, z, -y).
inline Eigen::Matrix3d ourWorldToNukeWorld() {
  Eigen::Matrix3d W;
  W << 1, 0, 0,  //
      0, 0, 1,   //
      0, -1, 0;
  return W;
}

/// Rotation of an OpenGL-style camera (Blender/Nuke camera object) in our world.
inline Eigen::Matrix3d glCameraRotation(const Eigen::Matrix3d& R_wc) {
  return R_wc * cameraToGlAxes();
}

inline Eigen::Matrix3d rotationX(double a) {
  return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitX()).toRotationMatrix();
}
inline Eigen::Matrix3d rotationY(double a) {
  return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitY()).toRotationMatrix();
}
inline Eigen::Matrix3d rotationZ(double a) {
  return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

/// Nuke rotation order ZXY: rotate about Z first, then X, then Y: R = Ry(ry) * Rx(rx) * Rz(rz)
/// (radians here; the chan file holds degrees).
inline Eigen::Matrix3d rotationFromNukeZxy(double rx, double ry, double rz) {
  return rotationY(ry) * rotationX(rx) * rotationZ(rz);
}

/// Inverse of rotationFromNukeZxy: angles (radians) with rx in [-pi/2, pi/2]. For
/// R = Ry Rx Rz: R(1,2) = -sin(rx); R(0,2) = sin(ry) cos(rx), R(2,2) = cos(ry) cos(rx);
/// R(1,0) = cos(rx) sin(rz), R(1,1) = cos(rx) cos(rz). At the gimbal lock (cos rx = 0) rz is set to
/// 0 and ry absorbs the remaining rotation.
inline Eigen::Vector3d nukeZxyFromRotation(const Eigen::Matrix3d& R) {
  const double s = std::clamp(-R(1, 2), -1.0, 1.0);
  const double rx = std::asin(s);
  const double c = std::sqrt(R(0, 2) * R(0, 2) + R(2, 2) * R(2, 2));
  double ry = 0.0;
  double rz = 0.0;
  if (c > 1e-9) {
    ry = std::atan2(R(0, 2), R(2, 2));
    rz = std::atan2(R(1, 0), R(1, 1));
  } else {
    // R = Ry(ry) Rx(+-pi/2) with rz = 0: first column = (cos ry, 0, -sin ry).
    ry = std::atan2(-R(2, 0), R(0, 0));
  }
  return {rx, ry, rz};
}

}  // namespace epitrack::io

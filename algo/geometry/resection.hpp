#pragma once

#include <span>

#include <Eigen/Core>

#include "algo/geometry/pose.hpp"

namespace epitrack {

/// The paper's linear resection (§5.4; Hartley & Zisserman §7.1 DLT) from at least six 3D-2D
/// matches in normalized image coordinates: the 3x4 [R|t] up to scale by the null vector of the
/// stacked equations, sign chosen so the points lie in front, then R projected onto SO(3) (SVD)
/// and t rescaled by the mean singular value. Returns false for fewer than six matches, coplanar
/// or otherwise singular configurations, or non-finite input.
bool resectLinear(std::span<const Eigen::Vector3d> X, std::span<const Eigen::Vector2d> normalized,
                  PoseCw& pose);

/// Minimal absolute pose from three matches (Grunert 1841, in Haralick et al. 1994's form): the
/// distances to the three points from a quartic, then the rigid transform aligning the camera-frame
/// points with the world points. Up to four solutions; returns how many.
int solveP3P(const Eigen::Vector3d X[3], const Eigen::Vector2d normalized[3], PoseCw poses[4]);

/// Rigid transform (R, t) minimising sum |R a_i + t - b_i|^2 (Kabsch / Horn, via SVD); b = R a + t.
bool alignRigid(std::span<const Eigen::Vector3d> a, std::span<const Eigen::Vector3d> b,
                Eigen::Matrix3d& R, Eigen::Vector3d& t);

}  // namespace epitrack

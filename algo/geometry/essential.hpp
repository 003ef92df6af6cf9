#pragma once

#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "algo/geometry/pose.hpp"

namespace epitrack {

/// E = K2^T F K1 (Hartley & Zisserman eq. 9.12), projected onto the essential manifold (two equal
/// singular values, one zero) and scaled to unit Frobenius norm / sqrt(2).
Eigen::Matrix3d essentialFromFundamental(const Eigen::Matrix3d& F, const Eigen::Matrix3d& K1,
                                         const Eigen::Matrix3d& K2);

/// The four (R, t) factorisations of E (H & Z Result 9.19): R in {U W V^T, U W^T V^T}, t = +-u3.
/// Pose of camera 2 relative to camera 1: x2 = R x1 + t, |t| = 1.
void decomposeEssential(const Eigen::Matrix3d& E, Eigen::Matrix3d R[2], Eigen::Vector3d& t);

struct RelativePoseResult {
  PoseCw pose;          ///< camera 2 when camera 1 is the identity
  int in_front = 0;     ///< inliers triangulated in front of both cameras for the chosen candidate
  int second_best = 0;  ///< the runner-up candidate's count (a close second: ambiguous)
  int considered = 0;   ///< inliers tested
};

/// The paper's §5.3 with the cheirality test over all inliers (not one point): each candidate
/// triangulates every inlier (`mask` empty: all) from normalized coordinates and counts those in
/// front of both cameras; the candidate with the most wins. Returns false when no candidate has
/// any point in front or the inputs are not finite.
bool recoverRelativePose(const Eigen::Matrix3d& E, std::span<const Eigen::Vector2d> n1,
                         std::span<const Eigen::Vector2d> n2, std::span<const uint8_t> mask,
                         RelativePoseResult& result);

/// Two-view refinement of the relative pose on the essential manifold (5 degrees of freedom:
/// R <- exp(w) R, t moved on the unit sphere): Levenberg-Marquardt on the Huber-weighted Sampson
/// distances of the masked correspondences (normalized coordinates; `focal_px` turns them into
/// pixels for the Huber threshold). Gold-standard-like accuracy without triangulating. Returns
/// false (pose unchanged) when a step is not finite.
bool refineRelativePose(std::span<const Eigen::Vector2d> n1, std::span<const Eigen::Vector2d> n2,
                        std::span<const uint8_t> mask, double focal_px, PoseCw& pose,
                        int max_iterations = 10, double huber_px = 1.0);

}  // namespace epitrack

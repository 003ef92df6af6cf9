#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/robust/ransac.hpp"

namespace epitrack {

/// The essential matrices of five correspondences in normalized coordinates (n2^T E n1 = 0),
/// by the Groebner-basis / action-matrix form of the five-point problem (Stewenius, Engels &
/// Nister, "Recent developments on direct relative orientation", ISPRS 2006): E in the
/// four-dimensional null space of the five epipolar constraints, E = x X + y Y + z Z + W; the ten
/// cubic constraints det(E) = 0 and 2 E E^T E - tr(E E^T) E = 0 reduced by Gauss-Jordan elimination
/// on their cubic monomials; the action matrix of x on the ten standard monomials
/// (x^2 xy xz y^2 yz z^2 x y z 1) has the solutions as eigenvectors. Writes up to 10 real
/// solutions (unit Frobenius norm) into `E`, returns how many. Fixed-size Eigen only: never
/// allocates.
int essentialFivePoint(const Eigen::Vector2d n1[5], const Eigen::Vector2d n2[5],
                       Eigen::Matrix3d E[10]);

struct EssentialRansacOptions {
  /// threshold: Sampson distance in pixels (normalized distance times focal_px)
  RansacOptions ransac{1.5, 0.999, 8, 1000, 1};
  double focal_px = 1.0;  ///< converts the normalized Sampson distance into pixels
  /// Each model is factorised into the (R, t) its minimal sample triangulates in front of both
  /// cameras, and a correspondence counts as an inlier only in front of both (the cheirality
  /// test inside RANSAC: a wrong E fitted to mismatches along a structure rarely keeps them in
  /// front).
  bool cheirality = true;
};

struct EssentialRansacResult {
  Eigen::Matrix3d E = Eigen::Matrix3d::Zero();
  int inliers = 0;
  int iterations = 0;
  std::span<const uint8_t> mask;  ///< 1 = inlier; owned by the estimator
};

/// Robust essential matrix from normalized correspondences (known intrinsics): five-point minimal
/// samples in RANSAC (MSAC score, adaptive iteration count, seeded), local optimisation by the
/// eight-point fit on the inliers projected onto the essential manifold. Five points instead of
/// eight: at 30 % inliers a clean sample is 13 times more likely than for F, and a wrong model
/// fits less by chance (5 degrees of freedom instead of 7). Buffers are sized for `max_points` at
/// construction; `estimate` never allocates.
class EssentialRansac {
 public:
  enum class Status { kOk, kTooFewPoints, kTooManyPoints, kNonFinite, kDegenerate };

  explicit EssentialRansac(int max_points);

  Status estimate(std::span<const Eigen::Vector2d> n1, std::span<const Eigen::Vector2d> n2,
                  const EssentialRansacOptions& options, EssentialRansacResult& result);

 private:
  int max_points_;
  std::vector<int> inlier_index_;
  std::vector<uint8_t> mask_;
};

/// Squared Sampson distance of n2^T E n1 = 0 in normalized units.
double essentialSampsonSquared(const Eigen::Matrix3d& E, const Eigen::Vector2d& n1,
                               const Eigen::Vector2d& n2);

/// The closest essential matrix (singular values (1, 1, 0)) to a 3x3 matrix, unit Frobenius norm
/// times sqrt(2) / sqrt(2) (i.e. singular values 1/sqrt(2), 1/sqrt(2), 0).
Eigen::Matrix3d projectToEssential(const Eigen::Matrix3d& M);

}  // namespace epitrack

#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/robust/ransac.hpp"

namespace epitrack {

/// Squared Sampson distance of x2^T F x1 = 0 (Hartley & Zisserman eq. 11.9), in pixels^2: the
/// first-order geometric error of a correspondence with respect to F.
double sampsonSquared(const Eigen::Matrix3d& F, const Eigen::Vector2d& x1,
                      const Eigen::Vector2d& x2);

/// Normalized eight-point algorithm (Hartley & Zisserman Alg. 11.1): Hartley normalization,
/// least-squares null vector of the stacked epipolar constraints (A^T A accumulated, no N x 9
/// matrix), rank 2 enforced by zeroing the smallest singular value, denormalized. `indices` empty
/// uses every correspondence; at least 8 are needed. `weights` (parallel to `indices`, optional)
/// scale each constraint row. Returns false when degenerate.
bool fitFundamentalEightPoint(std::span<const Eigen::Vector2d> x1,
                              std::span<const Eigen::Vector2d> x2, std::span<const int> indices,
                              Eigen::Matrix3d& F, std::span<const double> weights = {});

/// Forces a 3x3 matrix to rank 2 (closest in the Frobenius norm).
Eigen::Matrix3d enforceRank2(const Eigen::Matrix3d& F);

struct FundamentalOptions {
  RansacOptions ransac{1.0, 0.999, 8, 2000, 1};  ///< threshold: Sampson distance in pixels
  /// Final refit on the inliers by iteratively reweighted eight-point: each row weighted by the
  /// inverse of its Sampson denominator (so the algebraic residual becomes the geometric one) and a
  /// Cauchy weight on its Sampson distance at 2.5 robust sigmas (so a wrong match that happens to
  /// lie near its epipolar line does not bend F). Rounds of reweighting:
  int refit_rounds = 4;
};

struct FundamentalResult {
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
  int inliers = 0;
  int iterations = 0;
  double rms_sampson_px = 0.0;  ///< over the inliers
  std::span<const uint8_t>
      mask;  ///< 1 = inlier (the paper's §5.1 epipolar test); owned by the solver
};

/// Robust fundamental matrix: eight-point minimal samples in RANSAC (MSAC score, adaptive
/// iteration count, seeded), then refit on all inliers. The epipolar outlier test of the paper
/// (§5.1) is the final inlier mask: correspondences farther than the threshold from their epipolar
/// constraint are outliers. Buffers are sized for `max_points` at construction; `estimate` never
/// allocates.
class FundamentalRansac {
 public:
  enum class Status { kOk, kTooFewPoints, kTooManyPoints, kNonFinite, kDegenerate };

  explicit FundamentalRansac(int max_points);

  Status estimate(std::span<const Eigen::Vector2d> x1, std::span<const Eigen::Vector2d> x2,
                  const FundamentalOptions& options, FundamentalResult& result);

 private:
  int max_points_;
  std::vector<Eigen::Vector2d> n1_, n2_;  // Hartley-normalized copies
  std::vector<int> inlier_index_;
  std::vector<double> weight_;
  std::vector<double> residual_;
  std::vector<uint8_t> mask_;
};

const char* toString(FundamentalRansac::Status s);

}  // namespace epitrack

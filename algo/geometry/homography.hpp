#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/robust/ransac.hpp"

namespace epitrack {

/// Squared one-way transfer error |x2 - H x1|^2 in pixels^2 (infinite when H maps x1 to infinity).
double homographyTransferSquared(const Eigen::Matrix3d& H, const Eigen::Vector2d& x1,
                                 const Eigen::Vector2d& x2);

/// Normalized DLT (Hartley & Zisserman Alg. 4.2) over `indices` (empty: all), at least 4 points.
bool fitHomographyDlt(std::span<const Eigen::Vector2d> x1, std::span<const Eigen::Vector2d> x2,
                      std::span<const int> indices, Eigen::Matrix3d& H);

struct HomographyOptions {
  RansacOptions ransac{1.5, 0.999, 8, 2000, 2};  ///< threshold: transfer error in pixels
  int refit_rounds = 2;
};

struct HomographyResult {
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();
  int inliers = 0;
  int iterations = 0;
  double rms_transfer_px = 0.0;
  std::span<const uint8_t> mask;
};

/// Robust homography: four-point DLT in RANSAC (MSAC), refit on the inliers. Sized for
/// `max_points` at construction; `estimate` never allocates.
class HomographyRansac {
 public:
  enum class Status { kOk, kTooFewPoints, kTooManyPoints, kNonFinite, kDegenerate };
  explicit HomographyRansac(int max_points);
  Status estimate(std::span<const Eigen::Vector2d> x1, std::span<const Eigen::Vector2d> x2,
                  const HomographyOptions& options, HomographyResult& result);

 private:
  int max_points_;
  std::vector<int> inlier_index_;
  std::vector<uint8_t> mask_;
};

}  // namespace epitrack

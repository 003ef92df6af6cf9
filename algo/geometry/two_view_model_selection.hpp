#pragma once

#include <cstdint>
#include <span>

#include <Eigen/Core>

namespace epitrack {

/// Which two-view relation explains the correspondences.
enum class TwoViewModel {
  kFundamental,  ///< general motion with a 3D scene: F is meaningful
  kHomography,   ///< a plane, a pure rotation or no motion: F would be arbitrary
};

struct ModelSelectionResult {
  TwoViewModel model = TwoViewModel::kFundamental;
  double gric_f = 0.0;
  double gric_h = 0.0;
};

/// Torr's Geometric Robust Information Criterion (Torr 1998, "Geometric motion segmentation and
/// model selection"): GRIC = sum rho(e^2 / sigma^2) + lambda1 d n + lambda2 k with
/// rho(x) = min(x, lambda3 (r - d)), r = 4, lambda1 = ln r, lambda2 = ln(r n), lambda3 = 2;
/// F: d = 3, k = 7, e = Sampson distance; H: d = 2, k = 8, e^2 = half the squared transfer error
/// (the codimension-2 distance). The model with the lower score wins. `sigma_px` is the noise of
/// a point position. With both masks given, only correspondences that are inliers to F or to H
/// count: outliers to both say nothing about which relation holds, and their truncated cost would
/// otherwise favour F by a constant per outlier.
ModelSelectionResult selectTwoViewModel(const Eigen::Matrix3d& F, const Eigen::Matrix3d& H,
                                        std::span<const Eigen::Vector2d> x1,
                                        std::span<const Eigen::Vector2d> x2, double sigma_px,
                                        std::span<const uint8_t> f_mask = {},
                                        std::span<const uint8_t> h_mask = {});

}  // namespace epitrack

#pragma once

#include <algorithm>
#include <cstddef>
#include <span>

namespace epitrack {

/// The upper median of `values` (the element of rank size / 2), found in place by a partial
/// sort: `values` is reordered. 0 for an empty span. The one median of the solver, the live map
/// and their robust statistics (no allocation; pass a scratch copy to keep the order).
inline double upperMedian(std::span<double> values) {
  if (values.empty()) return 0.0;
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

/// Residual scale of 2D reprojection errors: for an isotropic Gaussian error of standard
/// deviation sigma the error's norm is Rayleigh distributed with median sigma sqrt(2 ln 2) =
/// 1.1774 sigma, so sigma = median / kRayleighMedianPerSigma.
inline constexpr double kRayleighMedianPerSigma = 1.1774;

}  // namespace epitrack

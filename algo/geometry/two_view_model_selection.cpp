#include "algo/geometry/two_view_model_selection.hpp"

#include <algorithm>
#include <cmath>

#include "algo/geometry/fundamental.hpp"
#include "algo/geometry/homography.hpp"

namespace epitrack {

ModelSelectionResult selectTwoViewModel(const Eigen::Matrix3d& F, const Eigen::Matrix3d& H,
                                        std::span<const Eigen::Vector2d> x1,
                                        std::span<const Eigen::Vector2d> x2, double sigma_px,
                                        std::span<const uint8_t> f_mask,
                                        std::span<const uint8_t> h_mask) {
  ModelSelectionResult r;
  const bool masked = f_mask.size() == x1.size() && h_mask.size() == x1.size();
  double n = 0.0;
  for (std::size_t i = 0; i < x1.size(); ++i) n += (!masked || f_mask[i] || h_mask[i]) ? 1.0 : 0.0;
  const double s2 = std::max(1e-6, sigma_px * sigma_px);
  constexpr double kR = 4.0;
  const double lambda1 = std::log(kR);
  const double lambda2 = std::log(kR * std::max(1.0, n));
  constexpr double kLambda3 = 2.0;
  double sum_f = 0.0, sum_h = 0.0;
  for (std::size_t i = 0; i < x1.size(); ++i) {
    if (masked && !f_mask[i] && !h_mask[i]) continue;
    const double ef = sampsonSquared(F, x1[i], x2[i]) / s2;
    const double eh = 0.5 * homographyTransferSquared(H, x1[i], x2[i]) / s2;
    sum_f += std::isfinite(ef) ? std::min(ef, kLambda3 * (kR - 3.0)) : kLambda3 * (kR - 3.0);
    sum_h += std::isfinite(eh) ? std::min(eh, kLambda3 * (kR - 2.0)) : kLambda3 * (kR - 2.0);
  }
  r.gric_f = sum_f + lambda1 * 3.0 * n + lambda2 * 7.0;
  r.gric_h = sum_h + lambda1 * 2.0 * n + lambda2 * 8.0;
  r.model = r.gric_h <= r.gric_f ? TwoViewModel::kHomography : TwoViewModel::kFundamental;
  return r;
}

}  // namespace epitrack

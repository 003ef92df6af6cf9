#include "algo/sfm/row_misfit.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Dense>

namespace epitrack {
namespace {

struct FrameShear {
  double shear_px = 0.0;  // |b|
  double chi2 = 0.0;
};

// The affine fit of one frame's residuals (row_misfit.hpp): returns false when the design is
// degenerate (every observation on one line) or the residuals are all zero.
bool fitFrameShear(std::span<const RowResidual> frame, double cx, double cy, double height,
                   FrameShear& out) {
  Eigen::Matrix3d AtA = Eigen::Matrix3d::Zero();
  Eigen::Matrix<double, 3, 2> Atr = Eigen::Matrix<double, 3, 2>::Zero();
  for (const RowResidual& r : frame) {
    const Eigen::Vector3d a(1.0, (r.x - cx) / height, (r.y - cy) / height);
    AtA += a * a.transpose();
    Atr.col(0) += a * r.dx;
    Atr.col(1) += a * r.dy;
  }
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(AtA);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-9 * AtA.trace()))
    return false;
  const Eigen::Matrix<double, 3, 2> coef = ldlt.solve(Atr);
  double sq = 0.0;
  for (const RowResidual& r : frame) {
    const Eigen::Vector3d a(1.0, (r.x - cx) / height, (r.y - cy) / height);
    const double ex = r.dx - a.dot(coef.col(0));
    const double ey = r.dy - a.dot(coef.col(1));
    sq += ex * ex + ey * ey;
  }
  // Residual variance per axis after the fit: 2n values, 6 parameters.
  const double dof = 2.0 * static_cast<double>(frame.size()) - 6.0;
  const double sigma2 = sq / dof;
  // B = [[b_xu, b_xv], [b_yu, b_yv]] (rows: residual axis; columns: u, v). Its similarity part
  // (zoom s, roll t: [[s, -t], [t, s]]) is what a focal error or a pose absorbs; the rest,
  // c1 = (b_yv - b_xu) / 2 (rows stretched against columns) and c2 = (b_xv + b_yu) / 2 (rows
  // sheared), is the rows' own. The x and y residuals are independent, so c1 and c2 are
  // uncorrelated with variance sigma^2 (M_uu + M_vv) / 4, M = (A^T A)^-1.
  const Eigen::Matrix3d M = ldlt.solve(Eigen::Matrix3d::Identity());
  const double var_c = sigma2 * (M(1, 1) + M(2, 2)) / 4.0;
  if (!(var_c > 0.0)) return false;
  const double c1 = (coef(2, 1) - coef(1, 0)) / 2.0;
  const double c2 = (coef(2, 0) + coef(1, 1)) / 2.0;
  // 2|c|: a row term k (x or y residual growing by k px from the top row to the bottom) gives k.
  out.shear_px = 2.0 * std::hypot(c1, c2);
  out.chi2 = (c1 * c1 + c2 * c2) / var_c;
  return std::isfinite(out.chi2);
}

double quantile(std::vector<double>& v, double q) {
  const auto k = static_cast<std::size_t>(std::lround(q * static_cast<double>(v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

}  // namespace

RowMisfit measureRowMisfit(std::span<const RowResidual> residuals, double cx, double cy,
                           double height, const RowMisfitOptions& options) {
  RowMisfit result;
  if (!(height > 0.0)) return result;
  std::vector<double> shears;
  std::size_t begin = 0;
  while (begin < residuals.size()) {
    std::size_t end = begin + 1;
    while (end < residuals.size() && residuals[end].frame == residuals[begin].frame) ++end;
    const auto frame = residuals.subspan(begin, end - begin);
    FrameShear fs;
    if (static_cast<int>(frame.size()) >= std::max(options.min_observations, 4) &&
        fitFrameShear(frame, cx, cy, height, fs)) {
      ++result.frames_tested;
      shears.push_back(fs.shear_px);
      if (fs.chi2 > options.chi2_threshold && fs.shear_px >= options.min_shear_px)
        ++result.frames_sheared;
      if (fs.shear_px > result.max_shear_px) {
        result.max_shear_px = fs.shear_px;
        result.max_shear_frame = frame.front().frame;
      }
    }
    begin = end;
  }
  if (shears.empty()) return result;
  result.median_shear_px = quantile(shears, 0.5);
  result.p90_shear_px = quantile(shears, 0.9);
  result.misfit = static_cast<double>(result.frames_sheared) >
                  options.max_sheared_fraction * static_cast<double>(result.frames_tested);
  return result;
}

}  // namespace epitrack

#include "algo/geometry/focal_self_calibration.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/LU>
#include <Eigen/SVD>

#include "algo/geometry/fundamental.hpp"
#include "algo/geometry/homography.hpp"
#include "algo/geometry/two_view_model_selection.hpp"

namespace epitrack {

namespace {

// F in coordinates centred on the principal point: x_pix = T x_c, so x2_c^T (T^T F T) x1_c = 0.
Eigen::Matrix3d centredF(const Eigen::Matrix3d& F, double cx, double cy) {
  Eigen::Matrix3d T;
  T << 1, 0, cx, 0, 1, cy, 0, 0, 1;
  const Eigen::Matrix3d Fc = T.transpose() * F * T;
  return Fc / Fc.norm();
}

double costCentred(const Eigen::Matrix3d& Fc, double f) {
  Eigen::Matrix3d E = Fc;
  E.topLeftCorner<2, 2>() *= f * f;
  E.topRightCorner<2, 1>() *= f;
  E.bottomLeftCorner<1, 2>() *= f;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(E);
  const Eigen::Vector3d& s = svd.singularValues();
  const double d = s(0) + s(1);
  if (!(d > 0.0)) return 1.0;
  return (s(0) - s(1)) / d;
}

// Golden-section search for the minimum of cost on [a, b] in log f.
template <typename Cost>
double goldenSection(const Cost& cost, double a, double b, int iterations) {
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double c = b - g * (b - a), d = a + g * (b - a);
  double fc = cost(c), fd = cost(d);
  for (int i = 0; i < iterations; ++i) {
    if (fc < fd) {
      b = d;
      d = c;
      fd = fc;
      c = b - g * (b - a);
      fc = cost(c);
    } else {
      a = c;
      c = d;
      fc = fd;
      d = a + g * (b - a);
      fd = cost(d);
    }
  }
  return 0.5 * (a + b);
}

}  // namespace

double focalCost(const Eigen::Matrix3d& F, double cx, double cy, double f) {
  return costCentred(centredF(F, cx, cy), f);
}

FocalPairEstimate estimateFocalFromFundamental(const Eigen::Matrix3d& F, int width, int height,
                                               const FocalSearchOptions& o) {
  FocalPairEstimate r;
  if (!F.allFinite() || width <= 0 || height <= 0 || F.norm() == 0.0) return r;
  const double cx = (width - 1) * 0.5, cy = (height - 1) * 0.5;
  const Eigen::Matrix3d Fc = centredF(F, cx, cy);
  const double lo = std::log(o.min_focal_widths * width), hi = std::log(o.max_focal_widths * width);
  const int n = std::max(8, o.grid_samples);
  int best = 0;
  double best_cost = 2.0;
  for (int i = 0; i < n; ++i) {
    const double lf = lo + (hi - lo) * i / (n - 1);
    const double c = costCentred(Fc, std::exp(lf));
    if (c < best_cost) {
      best_cost = c;
      best = i;
    }
  }
  const double step = (hi - lo) / (n - 1);
  auto cost_log = [&](double lf) { return costCentred(Fc, std::exp(lf)); };
  const double lf = goldenSection(cost_log, lo + std::max(0, best - 1) * step,
                                  lo + std::min(n - 1, best + 1) * step, 40);
  r.focal_px = std::exp(lf);
  r.cost = cost_log(lf);
  const double up = costCentred(Fc, r.focal_px * (1.0 + o.flatness_step));
  const double down = costCentred(Fc, r.focal_px / (1.0 + o.flatness_step));
  r.rise = std::min(up, down) - r.cost;
  const bool on_bound = best == 0 || best == n - 1;
  r.observable = !on_bound && std::isfinite(r.focal_px) && r.rise > o.min_rise &&
                 r.rise > o.min_rise_ratio * r.cost;
  return r;
}

FocalCalibrationResult calibrateFocalMultiPair(std::span<const Eigen::Matrix3d> Fs, int width,
                                               int height, std::span<FocalPairEstimate> per_pair,
                                               const FocalSearchOptions& o) {
  FocalCalibrationResult r;
  r.pairs = static_cast<int>(Fs.size());
  if (per_pair.size() < Fs.size() || width <= 0 || height <= 0) return r;
  // Median of the observable single-pair estimates (nth_element on a bounded scratch array would
  // allocate nothing; pairs are few, a simple insertion into a fixed array suffices).
  constexpr std::size_t kMaxPairs = 4096;
  std::array<double, kMaxPairs> logs{};
  std::size_t m = 0;
  for (std::size_t i = 0; i < Fs.size(); ++i) {
    per_pair[i] = estimateFocalFromFundamental(Fs[i], width, height, o);
    if (per_pair[i].observable && m < kMaxPairs) logs[m++] = std::log(per_pair[i].focal_px);
  }
  r.observable_pairs = static_cast<int>(m);
  if (m == 0) return r;
  std::sort(logs.begin(), logs.begin() + static_cast<std::ptrdiff_t>(m));
  const double median = std::exp(m % 2 ? logs[m / 2] : 0.5 * (logs[m / 2 - 1] + logs[m / 2]));
  std::size_t coherent = 0;
  for (std::size_t i = 0; i < Fs.size(); ++i) {
    per_pair[i].coherent = per_pair[i].observable &&
                           std::abs(per_pair[i].focal_px / median - 1.0) < o.coherence_tolerance;
    if (per_pair[i].coherent) ++coherent;
  }
  r.coherent_pairs = static_cast<int>(coherent);
  if (coherent == 0) return r;
  // Joint minimum of the summed coherent cost curves around the median.
  const double cx = (width - 1) * 0.5, cy = (height - 1) * 0.5;
  auto joint = [&](double lf) {
    double s = 0.0;
    const double f = std::exp(lf);
    for (std::size_t i = 0; i < Fs.size(); ++i)
      if (per_pair[i].coherent) s += focalCost(Fs[i], cx, cy, f);
    return s;
  };
  const double span_log = std::log(1.0 + o.coherence_tolerance);
  r.focal_px =
      std::exp(goldenSection(joint, std::log(median) - span_log, std::log(median) + span_log, 48));
  std::size_t k = 0;
  for (std::size_t i = 0; i < Fs.size(); ++i)
    if (per_pair[i].coherent) logs[k++] = std::abs(per_pair[i].focal_px / r.focal_px - 1.0);
  std::sort(logs.begin(), logs.begin() + static_cast<std::ptrdiff_t>(k));
  r.spread = logs[k / 2];
  r.observable = 2 * coherent > m || (m <= 2 && coherent >= 1);
  return r;
}

FocalFromMatches estimateFocalFromMatches(std::span<const Eigen::Vector2d> x1,
                                          std::span<const Eigen::Vector2d> x2, int width,
                                          int height, FundamentalRansac& f_ransac,
                                          HomographyRansac& h_ransac, double sigma_px,
                                          const FundamentalOptions& f_options,
                                          const FocalSearchOptions& options) {
  FocalFromMatches r;
  FundamentalResult fr;
  const bool have_f = f_ransac.estimate(x1, x2, f_options, fr) == FundamentalRansac::Status::kOk;
  HomographyResult hr;
  HomographyOptions ho;
  ho.ransac.threshold = f_options.ransac.threshold * std::sqrt(2.0);
  const bool have_h = h_ransac.estimate(x1, x2, ho, hr) == HomographyRansac::Status::kOk;
  if (!have_f) {
    // F is degenerate on a plane or under pure rotation; a homography still classifies the pair.
    if (have_h) {
      r.H = hr.H;
      r.model = PairModel::kHomography;
    }
    return r;
  }
  r.F = fr.F;
  if (have_h) {
    r.H = hr.H;
    const auto sel = selectTwoViewModel(fr.F, hr.H, x1, x2, sigma_px, fr.mask, hr.mask);
    if (sel.model == TwoViewModel::kHomography) {
      r.model = PairModel::kHomography;
      return r;
    }
  }
  r.model = PairModel::kFundamental;
  r.estimate = estimateFocalFromFundamental(fr.F, width, height, options);
  return r;
}

FocalPairEstimate estimateFocalFromRotation(const Eigen::Matrix3d& H, int width, int height,
                                            const FocalSearchOptions& o) {
  FocalPairEstimate r;
  if (!H.allFinite() || width <= 0 || height <= 0) return r;
  const double cx = (width - 1) * 0.5, cy = (height - 1) * 0.5;
  Eigen::Matrix3d T;
  T << 1, 0, cx, 0, 1, cy, 0, 0, 1;
  const Eigen::Matrix3d Hc = T.inverse() * H * T;  // centred coordinates
  auto cost = [&](double lf) {
    const double f = std::exp(lf);
    const Eigen::Matrix3d K = Eigen::Vector3d(f, f, 1.0).asDiagonal();
    const Eigen::Matrix3d Kinv = Eigen::Vector3d(1.0 / f, 1.0 / f, 1.0).asDiagonal();
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(Kinv * Hc * K);
    const Eigen::Vector3d& s = svd.singularValues();
    return (s(0) - s(2)) / (s(0) + s(2));
  };
  const double lo = std::log(o.min_focal_widths * width), hi = std::log(o.max_focal_widths * width);
  const int n = std::max(8, o.grid_samples);
  int best = 0;
  double best_cost = 2.0;
  for (int i = 0; i < n; ++i) {
    const double c = cost(lo + (hi - lo) * i / (n - 1));
    if (c < best_cost) {
      best_cost = c;
      best = i;
    }
  }
  const double step = (hi - lo) / (n - 1);
  const double lf = goldenSection(cost, lo + std::max(0, best - 1) * step,
                                  lo + std::min(n - 1, best + 1) * step, 40);
  r.focal_px = std::exp(lf);
  r.cost = cost(lf);
  r.rise =
      std::min(cost(lf + std::log1p(o.flatness_step)), cost(lf - std::log1p(o.flatness_step))) -
      r.cost;
  r.observable =
      best > 0 && best < n - 1 && r.rise > o.min_rise && r.rise > o.min_rise_ratio * r.cost;
  return r;
}

}  // namespace epitrack

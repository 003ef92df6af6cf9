#include "algo/tracking/global_motion.hpp"

#include <algorithm>
#include <cmath>

#include "algo/math/random.hpp"

namespace epitrack {
namespace {

// A frame-to-frame camera motion never scales the image by more than this (a sample that does
// is two points on different objects): keeps absurd models out of the consensus.
constexpr double kMaxScaleStep = 1.5;

bool plausible(const SimilarityMotion& m) {
  const double scale = std::hypot(m.a, m.b);
  return std::isfinite(scale) && std::isfinite(m.tx) && std::isfinite(m.ty) &&
         scale <= kMaxScaleStep && scale >= 1.0 / kMaxScaleStep;
}

}  // namespace

GlobalMotionEstimator::GlobalMotionEstimator(const GlobalMotionOptions& options)
    : options_(options) {
  options_.max_points = std::max(options_.max_points, 0);
  options_.iterations = std::max(options_.iterations, 1);
  options_.min_inliers = std::max(options_.min_inliers, 2);
  const auto n = static_cast<std::size_t>(options_.max_points);
  for (auto* v : {&x0_, &y0_, &x1_, &y1_}) v->assign(n, 0.0);
  inliers_.assign(n, 0);
}

bool GlobalMotionEstimator::add(double x0, double y0, double x1, double y1) {
  if (count_ >= options_.max_points) return false;
  const auto k = static_cast<std::size_t>(count_++);
  x0_[k] = x0;
  y0_[k] = y0;
  x1_[k] = x1;
  y1_[k] = y1;
  return true;
}

int GlobalMotionEstimator::classify(const SimilarityMotion& m) {
  const double t2 = options_.inlier_px * options_.inlier_px;
  int n = 0;
  for (int i = 0; i < count_; ++i) {
    const auto k = static_cast<std::size_t>(i);
    double px = 0.0, py = 0.0;
    m.apply(x0_[k], y0_[k], px, py);
    const double ex = px - x1_[k];
    const double ey = py - y1_[k];
    const bool in = ex * ex + ey * ey <= t2;
    inliers_[k] = in ? 1 : 0;
    n += in ? 1 : 0;
  }
  return n;
}

bool GlobalMotionEstimator::fitInliers(SimilarityMotion& m) const {
  // Closed-form least squares of q = s p + t with complex s = a + ib (Umeyama 1991 without the
  // reflection case): s = sum (q_i - q̄) conj(p_i - p̄) / sum |p_i - p̄|^2, t = q̄ - s p̄.
  int n = 0;
  double mx0 = 0.0, my0 = 0.0, mx1 = 0.0, my1 = 0.0;
  for (int i = 0; i < count_; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (inliers_[k] == 0) continue;
    ++n;
    mx0 += x0_[k];
    my0 += y0_[k];
    mx1 += x1_[k];
    my1 += y1_[k];
  }
  if (n < 2) return false;
  const double inv = 1.0 / static_cast<double>(n);
  mx0 *= inv;
  my0 *= inv;
  mx1 *= inv;
  my1 *= inv;
  double re = 0.0, im = 0.0, norm = 0.0;
  for (int i = 0; i < count_; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (inliers_[k] == 0) continue;
    const double px = x0_[k] - mx0, py = y0_[k] - my0;
    const double qx = x1_[k] - mx1, qy = y1_[k] - my1;
    re += qx * px + qy * py;
    im += qy * px - qx * py;
    norm += px * px + py * py;
  }
  if (!(norm > 1e-9)) return false;
  SimilarityMotion fit;
  fit.a = re / norm;
  fit.b = im / norm;
  fit.tx = mx1 - (fit.a * mx0 - fit.b * my0);
  fit.ty = my1 - (fit.b * mx0 + fit.a * my0);
  if (!plausible(fit)) return false;
  m = fit;
  return true;
}

GlobalMotionEstimator::Status GlobalMotionEstimator::estimate(SimilarityMotion& motion) {
  inlier_count_ = 0;
  if (count_ < std::max(options_.min_inliers, 2)) return Status::kTooFewPoints;
  SplitMix64 rng(options_.seed);
  const double t2 = options_.inlier_px * options_.inlier_px;
  const double min_pair2 = options_.min_pair_px * options_.min_pair_px;
  const auto n = static_cast<uint32_t>(count_);
  SimilarityMotion best;
  double best_cost = -1.0;
  for (int it = 0; it < options_.iterations; ++it) {
    const auto i = static_cast<std::size_t>(rng.below(n));
    auto j = static_cast<std::size_t>(rng.below(n - 1));
    if (j >= i) ++j;
    // The similarity through two correspondences: s = (q_j - q_i) / (p_j - p_i), complex.
    const double px = x0_[j] - x0_[i], py = y0_[j] - y0_[i];
    const double qx = x1_[j] - x1_[i], qy = y1_[j] - y1_[i];
    const double norm = px * px + py * py;
    if (norm < min_pair2) continue;
    SimilarityMotion m;
    m.a = (qx * px + qy * py) / norm;
    m.b = (qy * px - qx * py) / norm;
    m.tx = x1_[i] - (m.a * x0_[i] - m.b * y0_[i]);
    m.ty = y1_[i] - (m.b * x0_[i] + m.a * y0_[i]);
    if (!plausible(m)) continue;
    // MSAC: each point costs its squared error, capped at the threshold.
    double cost = 0.0;
    for (int p = 0; p < count_; ++p) {
      const auto k = static_cast<std::size_t>(p);
      double ox = 0.0, oy = 0.0;
      m.apply(x0_[k], y0_[k], ox, oy);
      const double ex = ox - x1_[k], ey = oy - y1_[k];
      cost += std::min(ex * ex + ey * ey, t2);
    }
    if (best_cost < 0.0 || cost < best_cost) {
      best_cost = cost;
      best = m;
    }
  }
  if (best_cost < 0.0) return Status::kNoConsensus;
  // Least squares over the consensus, re-classified and solved once more.
  SimilarityMotion model = best;
  int inliers = classify(model);
  for (int round = 0; round < 2 && inliers >= 2; ++round) {
    if (!fitInliers(model)) break;
    inliers = classify(model);
  }
  const double needed = std::max(static_cast<double>(options_.min_inliers),
                                 options_.min_inlier_fraction * static_cast<double>(count_));
  if (static_cast<double>(inliers) < needed) {
    inlier_count_ = 0;
    return Status::kNoConsensus;
  }
  inlier_count_ = inliers;
  motion = model;
  return Status::kOk;
}

}  // namespace epitrack

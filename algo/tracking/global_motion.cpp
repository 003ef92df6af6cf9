#include "algo/tracking/global_motion.hpp"

#include <algorithm>
#include <cmath>

#include "algo/math/random.hpp"

namespace epitrack {
namespace {

// A frame-to-frame camera motion never scales the image by more than this (a sample that does
// is two points on different objects): keeps absurd models out of the consensus.
constexpr double kMaxScaleStep = 1.5;

bool plausible(const SimilarityMotion& m, double max_row_term = 0.0) {
  const double scale = std::hypot(m.a, m.b);
  return std::isfinite(scale) && std::isfinite(m.tx) && std::isfinite(m.ty) &&
         scale <= kMaxScaleStep && scale >= 1.0 / kMaxScaleStep && std::abs(m.rx) <= max_row_term &&
         std::abs(m.ry) <= max_row_term;
}

// A RANSAC sample of `points` (2 or 3) distinct indices below n, drawn in order.
void drawSample(SplitMix64& rng, uint32_t n, int points, std::size_t (&idx)[3]) {
  idx[0] = static_cast<std::size_t>(rng.below(n));
  idx[1] = static_cast<std::size_t>(rng.below(n - 1));
  if (idx[1] >= idx[0]) ++idx[1];
  if (points < 3) return;
  idx[2] = static_cast<std::size_t>(rng.below(n - 2));
  for (const std::size_t taken : {std::min(idx[0], idx[1]), std::max(idx[0], idx[1])})
    if (idx[2] >= taken) ++idx[2];
}

// The similarity with a row term from the affine map x' = p x + q y + t, y' = u x + v y + w
// (SimilarityMotion: p = a, u = b, q = rx - b, v = a + ry).
SimilarityMotion fromAffine(double p, double q, double t, double u, double v, double w) {
  SimilarityMotion m;
  m.a = p;
  m.b = u;
  m.tx = t;
  m.ty = w;
  m.rx = q + u;
  m.ry = v - p;
  return m;
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

int GlobalMotionEstimator::inlierCentroids(double& mx0, double& my0, double& mx1,
                                           double& my1) const {
  int n = 0;
  mx0 = my0 = mx1 = my1 = 0.0;
  for (int i = 0; i < count_; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (inliers_[k] == 0) continue;
    ++n;
    mx0 += x0_[k];
    my0 += y0_[k];
    mx1 += x1_[k];
    my1 += y1_[k];
  }
  if (n == 0) return 0;
  const double inv = 1.0 / static_cast<double>(n);
  mx0 *= inv;
  my0 *= inv;
  mx1 *= inv;
  my1 *= inv;
  return n;
}

bool GlobalMotionEstimator::fitInliers(SimilarityMotion& m) const {
  // Closed-form least squares of q = s p + t with complex s = a + ib (Umeyama 1991 without the
  // reflection case): s = sum (q_i - q̄) conj(p_i - p̄) / sum |p_i - p̄|^2, t = q̄ - s p̄.
  double mx0 = 0.0, my0 = 0.0, mx1 = 0.0, my1 = 0.0;
  if (inlierCentroids(mx0, my0, mx1, my1) < 2) return false;
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

double GlobalMotionEstimator::msacCost(const SimilarityMotion& m) const {
  const double t2 = options_.inlier_px * options_.inlier_px;
  double cost = 0.0;
  for (int p = 0; p < count_; ++p) {
    const auto k = static_cast<std::size_t>(p);
    double ox = 0.0, oy = 0.0;
    m.apply(x0_[k], y0_[k], ox, oy);
    const double ex = ox - x1_[k], ey = oy - y1_[k];
    cost += std::min(ex * ex + ey * ey, t2);
  }
  return cost;
}

bool GlobalMotionEstimator::affineThrough(std::size_t i, std::size_t j, std::size_t k,
                                          SimilarityMotion& m) const {
  // About point i: [dx_j dy_j; dx_k dy_k] [p u; q v] = [dx'_j dy'_j; dx'_k dy'_k] (Cramer).
  const double ax = x0_[j] - x0_[i], ay = y0_[j] - y0_[i];
  const double bx = x0_[k] - x0_[i], by = y0_[k] - y0_[i];
  const double det = ax * by - ay * bx;  // twice the triangle's area
  if (std::abs(det) < options_.min_pair_px * options_.min_pair_px) return false;
  const double qax = x1_[j] - x1_[i], qay = y1_[j] - y1_[i];
  const double qbx = x1_[k] - x1_[i], qby = y1_[k] - y1_[i];
  const double p = (qax * by - qbx * ay) / det, q = (ax * qbx - bx * qax) / det;
  const double u = (qay * by - qby * ay) / det, v = (ax * qby - bx * qay) / det;
  m = fromAffine(p, q, x1_[i] - p * x0_[i] - q * y0_[i], u, v, y1_[i] - u * x0_[i] - v * y0_[i]);
  return plausible(m, options_.max_row_term);
}

bool GlobalMotionEstimator::fitInliersWithRows(SimilarityMotion& m) const {
  // Least squares about the centroids: [sxx sxy; sxy syy] [p u; q v] = [sxX sxY; syX syY].
  double mx0 = 0.0, my0 = 0.0, mx1 = 0.0, my1 = 0.0;
  if (inlierCentroids(mx0, my0, mx1, my1) < 3) return false;
  double sxx = 0.0, sxy = 0.0, syy = 0.0, sxX = 0.0, syX = 0.0, sxY = 0.0, syY = 0.0;
  for (int i = 0; i < count_; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (inliers_[k] == 0) continue;
    const double x = x0_[k] - mx0, y = y0_[k] - my0;
    const double X = x1_[k] - mx1, Y = y1_[k] - my1;
    sxx += x * x;
    sxy += x * y;
    syy += y * y;
    sxX += x * X;
    syX += y * X;
    sxY += x * Y;
    syY += y * Y;
  }
  const double det = sxx * syy - sxy * sxy;
  if (!(det > 1e-9)) return false;
  const double p = (sxX * syy - syX * sxy) / det, q = (sxx * syX - sxy * sxX) / det;
  const double u = (sxY * syy - syY * sxy) / det, v = (sxx * syY - sxy * sxY) / det;
  const SimilarityMotion fit =
      fromAffine(p, q, mx1 - p * mx0 - q * my0, u, v, my1 - u * mx0 - v * my0);
  if (!plausible(fit, options_.max_row_term)) return false;
  m = fit;
  return true;
}

bool GlobalMotionEstimator::estimateWithRows(SimilarityMotion& motion, int& inliers) {
  if (count_ < 3) return false;
  SplitMix64 rng(options_.seed ^ 0x7077);
  const auto n = static_cast<uint32_t>(count_);
  SimilarityMotion best;
  double best_cost = -1.0;
  std::size_t idx[3] = {};
  for (int it = 0; it < options_.iterations; ++it) {
    drawSample(rng, n, 3, idx);
    SimilarityMotion m;
    if (!affineThrough(idx[0], idx[1], idx[2], m)) continue;
    const double cost = msacCost(m);
    if (best_cost < 0.0 || cost < best_cost) {
      best_cost = cost;
      best = m;
    }
  }
  if (best_cost < 0.0) return false;
  inliers = classify(best);
  for (int round = 0; round < 2 && inliers >= 3; ++round) {
    if (!fitInliersWithRows(best)) break;
    inliers = classify(best);
  }
  motion = best;
  return true;
}

GlobalMotionEstimator::Status GlobalMotionEstimator::estimate(SimilarityMotion& motion) {
  inlier_count_ = 0;
  if (count_ < std::max(options_.min_inliers, 2)) return Status::kTooFewPoints;
  SplitMix64 rng(options_.seed);
  const double min_pair2 = options_.min_pair_px * options_.min_pair_px;
  const auto n = static_cast<uint32_t>(count_);
  SimilarityMotion best;
  double best_cost = -1.0;
  std::size_t idx[3] = {};
  for (int it = 0; it < options_.iterations; ++it) {
    drawSample(rng, n, 2, idx);
    const std::size_t i = idx[0], j = idx[1];
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
    const double cost = msacCost(m);
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
  // A rolling shutter's jerk: the rows moved by different amounts (see SimilarityMotion).
  if (options_.row_term &&
      static_cast<double>(inliers) < options_.row_term_below * static_cast<double>(count_)) {
    SimilarityMotion with_rows;
    int row_inliers = 0;
    if (estimateWithRows(with_rows, row_inliers) &&
        static_cast<double>(row_inliers) >=
            static_cast<double>(inliers) + options_.row_term_gain * static_cast<double>(count_)) {
      model = with_rows;
      inliers = row_inliers;
    } else {
      inliers = classify(model);  // the similarity's flags again
    }
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

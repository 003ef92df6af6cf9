#include "algo/geometry/fundamental.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include "algo/geometry/dlt_rows.hpp"
#include "algo/geometry/point_normalization.hpp"

namespace epitrack {

double sampsonSquared(const Eigen::Matrix3d& F, const Eigen::Vector2d& x1,
                      const Eigen::Vector2d& x2) {
  const Eigen::Vector3d p1(x1.x(), x1.y(), 1.0);
  const Eigen::Vector3d p2(x2.x(), x2.y(), 1.0);
  const Eigen::Vector3d Fx1 = F * p1;
  const Eigen::Vector3d Ftx2 = F.transpose() * p2;
  const double e = p2.dot(Fx1);
  const double d =
      Fx1.x() * Fx1.x() + Fx1.y() * Fx1.y() + Ftx2.x() * Ftx2.x() + Ftx2.y() * Ftx2.y();
  if (!(d > 0.0)) return std::numeric_limits<double>::infinity();
  return e * e / d;
}

Eigen::Matrix3d enforceRank2(const Eigen::Matrix3d& F) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d s = svd.singularValues();
  s(2) = 0.0;
  return svd.matrixU() * s.asDiagonal() * svd.matrixV().transpose();
}

namespace {

bool finite2(const Eigen::Vector2d& v) { return std::isfinite(v.x()) && std::isfinite(v.y()); }

// Kernel of the minimal eight-point solve on pre-normalized points; errors on the originals.
struct FundamentalKernel {
  static constexpr int kMinSamples = 8;
  static constexpr int kMaxModels = 1;
  using Model = Eigen::Matrix3d;
  std::span<const Eigen::Vector2d> x1, x2, n1, n2;
  Eigen::Matrix3d T1, T2;
  int* scratch = nullptr;  // inlier indices for the local optimisation (capacity: all points)

  // Refit on the inliers at a widened threshold first (a noisy minimal model misses inliers
  // near the edge of the image), then at the threshold itself (LO-RANSAC's shrinking scheme).
  bool localOptimize(Model& F, double t2) const {
    bool changed = false;
    for (const double widen : {4.0, 1.0, 1.0}) {
      int c = 0;
      for (std::size_t i = 0; i < x1.size(); ++i)
        if (squaredError(static_cast<int>(i), F) < widen * t2) scratch[c++] = static_cast<int>(i);
      if (c < 9) return changed;
      Eigen::Matrix3d refit;
      if (!fitFundamentalEightPoint(
              x1, x2, std::span<const int>(scratch, static_cast<std::size_t>(c)), refit))
        return changed;
      F = refit;
      changed = true;
    }
    return changed;
  }

  bool sampleIsDegenerate(std::span<const int>) const { return false; }
  int fit(std::span<const int> s, Model* models) const {
    Eigen::Matrix<double, 8, 9> A;
    for (int i = 0; i < 8; ++i) {
      const auto k = static_cast<std::size_t>(s[static_cast<std::size_t>(i)]);
      A.row(i) = epipolarCoefficients(n1[k], n2[k]).transpose();
    }
    Eigen::Matrix<double, 9, 1> f;
    if (!nullVector8x9(A, f)) return 0;
    const Eigen::Matrix3d Fn = enforceRank2(matrix3FromRowMajor(f));
    models[0] = T2.transpose() * Fn * T1;
    return 1;
  }
  double squaredError(int i, const Model& F) const {
    return sampsonSquared(F, x1[static_cast<std::size_t>(i)], x2[static_cast<std::size_t>(i)]);
  }
};

}  // namespace

bool fitFundamentalEightPoint(std::span<const Eigen::Vector2d> x1,
                              std::span<const Eigen::Vector2d> x2, std::span<const int> indices,
                              Eigen::Matrix3d& F, std::span<const double> weights) {
  const std::size_t n = indices.empty() ? x1.size() : indices.size();
  if (n < 8 || x1.size() != x2.size()) return false;
  Eigen::Matrix3d T1, T2;
  if (!hartleyNormalization(x1, indices, T1) || !hartleyNormalization(x2, indices, T2))
    return false;
  Eigen::Matrix<double, 9, 9> AtA = Eigen::Matrix<double, 9, 9>::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t k = indices.empty() ? i : static_cast<std::size_t>(indices[i]);
    const Eigen::Vector2d a = (T1 * x1[k].homogeneous()).hnormalized();
    const Eigen::Vector2d b = (T2 * x2[k].homogeneous()).hnormalized();
    const double w = weights.empty() ? 1.0 : weights[i];
    if (!(w > 0.0)) continue;
    const Eigen::Matrix<double, 9, 1> r = w * epipolarCoefficients(a, b);
    AtA.selfadjointView<Eigen::Upper>().rankUpdate(r);
  }
  Eigen::Matrix<double, 9, 9> full = AtA.selfadjointView<Eigen::Upper>();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> es(full);
  if (es.info() != Eigen::Success) return false;
  const Eigen::Vector<double, 9>& ev = es.eigenvalues();
  // A second (near-)zero eigenvalue means the constraints do not fix F (degenerate configuration).
  if (!(ev(1) > 1e-12 * std::max(1e-300, ev(8)))) return false;
  const Eigen::Matrix3d Fn = enforceRank2(matrix3FromRowMajor(es.eigenvectors().col(0)));
  F = T2.transpose() * Fn * T1;
  const double norm = F.norm();
  if (!(norm > 0.0) || !std::isfinite(norm)) return false;
  F /= norm;
  return true;
}

FundamentalRansac::FundamentalRansac(int max_points)
    : max_points_(max_points),
      n1_(static_cast<std::size_t>(max_points)),
      n2_(static_cast<std::size_t>(max_points)),
      inlier_index_(static_cast<std::size_t>(max_points)),
      weight_(static_cast<std::size_t>(max_points)),
      residual_(static_cast<std::size_t>(max_points)),
      mask_(static_cast<std::size_t>(max_points)) {}

FundamentalRansac::Status FundamentalRansac::estimate(std::span<const Eigen::Vector2d> x1,
                                                      std::span<const Eigen::Vector2d> x2,
                                                      const FundamentalOptions& options,
                                                      FundamentalResult& result) {
  result = {};
  const int n = static_cast<int>(x1.size());
  if (x1.size() != x2.size() || n < 8) return Status::kTooFewPoints;
  if (n > max_points_) return Status::kTooManyPoints;
  for (int i = 0; i < n; ++i) {
    if (!finite2(x1[static_cast<std::size_t>(i)]) || !finite2(x2[static_cast<std::size_t>(i)]))
      return Status::kNonFinite;
  }
  FundamentalKernel k;
  k.scratch = inlier_index_.data();
  k.x1 = x1;
  k.x2 = x2;
  if (!hartleyNormalization(x1, {}, k.T1) || !hartleyNormalization(x2, {}, k.T2))
    return Status::kDegenerate;
  for (int i = 0; i < n; ++i) {
    const auto u = static_cast<std::size_t>(i);
    n1_[u] = (k.T1 * x1[u].homogeneous()).hnormalized();
    n2_[u] = (k.T2 * x2[u].homogeneous()).hnormalized();
  }
  k.n1 = std::span<const Eigen::Vector2d>(n1_.data(), x1.size());
  k.n2 = std::span<const Eigen::Vector2d>(n2_.data(), x1.size());

  Ransac<FundamentalKernel> ransac;
  Eigen::Matrix3d F;
  RansacSummary summary;
  if (!ransac.run(k, n, options.ransac, F, summary)) return Status::kDegenerate;
  const double t2 = options.ransac.threshold * options.ransac.threshold;

  auto collect = [&](const Eigen::Matrix3d& model, double& score) {
    int count = 0;
    score = 0.0;
    for (int i = 0; i < n; ++i) {
      const double e2 = k.squaredError(i, model);
      if (e2 < t2) {
        inlier_index_[static_cast<std::size_t>(count++)] = i;
        score += e2;
      } else {
        score += t2;
      }
    }
    return count;
  };
  double score = 0.0;
  int count = collect(F, score);
  for (int round = 0; round < options.refit_rounds && count >= 8; ++round) {
    // Robust scale of the current inliers' Sampson distances (median absolute value * 1.4826).
    for (int j = 0; j < count; ++j) {
      const int i = inlier_index_[static_cast<std::size_t>(j)];
      residual_[static_cast<std::size_t>(j)] = std::sqrt(k.squaredError(i, F));
    }
    auto mid = residual_.begin() + count / 2;
    std::nth_element(residual_.begin(), mid, residual_.begin() + count);
    const double sigma = std::max(1.4826 * *mid, 1e-3 * options.ransac.threshold);
    const double c = 2.5 * sigma;
    for (int j = 0; j < count; ++j) {
      const auto u = static_cast<std::size_t>(inlier_index_[static_cast<std::size_t>(j)]);
      const Eigen::Vector3d p1 = x1[u].homogeneous(), p2 = x2[u].homogeneous();
      const Eigen::Vector3d Fx1 = F * p1, Ftx2 = F.transpose() * p2;
      const double d = Fx1.head<2>().squaredNorm() + Ftx2.head<2>().squaredNorm();
      const double e = p2.dot(Fx1);
      const double sampson2 = d > 0.0 ? e * e / d : 0.0;
      weight_[static_cast<std::size_t>(j)] =
          d > 0.0 ? 1.0 / std::sqrt(d) / std::sqrt(1.0 + sampson2 / (c * c)) : 0.0;
    }
    Eigen::Matrix3d refit;
    if (!fitFundamentalEightPoint(
            x1, x2, std::span<const int>(inlier_index_.data(), static_cast<std::size_t>(count)),
            refit, std::span<const double>(weight_.data(), static_cast<std::size_t>(count))))
      break;
    double s2 = 0.0;
    for (int i = 0; i < n; ++i) {
      const double e2 = k.squaredError(i, refit);
      s2 += e2 < t2 ? e2 : t2;
    }
    if (s2 > score * 1.05) break;  // the reweighted fit may trade a little MSAC cost for robustness
    F = refit;
    count = collect(F, score);
  }
  if (count < 8) return Status::kDegenerate;
  double sum = 0.0;
  for (int i = 0; i < n; ++i) {
    const double e2 = k.squaredError(i, F);
    const bool in = e2 < t2;
    mask_[static_cast<std::size_t>(i)] = in ? 1 : 0;
    if (in) sum += e2;
  }
  result.F = F / F.norm();
  result.inliers = count;
  result.iterations = summary.iterations;
  result.rms_sampson_px = std::sqrt(sum / count);
  result.mask = std::span<const uint8_t>(mask_.data(), x1.size());
  if (!result.F.allFinite()) return Status::kNonFinite;
  return Status::kOk;
}

const char* toString(FundamentalRansac::Status s) {
  switch (s) {
    case FundamentalRansac::Status::kOk:
      return "ok";
    case FundamentalRansac::Status::kTooFewPoints:
      return "too few correspondences (need 8)";
    case FundamentalRansac::Status::kTooManyPoints:
      return "more correspondences than the capacity";
    case FundamentalRansac::Status::kNonFinite:
      return "non-finite coordinates";
    case FundamentalRansac::Status::kDegenerate:
      return "degenerate configuration";
  }
  return "unknown";
}

}  // namespace epitrack

#include "algo/geometry/pnp.hpp"

#include <cmath>

#include <Eigen/Cholesky>

#include "algo/geometry/resection.hpp"

namespace epitrack {

const char* toString(PnpRansac::Status s) {
  switch (s) {
    case PnpRansac::Status::kOk:
      return "ok";
    case PnpRansac::Status::kTooFewPoints:
      return "too few 3D-2D matches";
    case PnpRansac::Status::kTooManyPoints:
      return "more matches than the capacity";
    case PnpRansac::Status::kNonFinite:
      return "non-finite coordinates";
    case PnpRansac::Status::kNoConsensus:
      return "no pose agrees with enough matches";
  }
  return "unknown";
}

namespace {

double reprojSquared(const PoseCw& pose, const Eigen::Vector3d& X, const Eigen::Vector2d& x,
                     double focal) {
  const Eigen::Vector3d p = pose.toCamera(X);
  if (!(p.z() > 1e-9)) return std::numeric_limits<double>::infinity();
  return (p.hnormalized() - x).squaredNorm() * focal * focal;
}

struct P3pKernel {
  static constexpr int kMinSamples = 3;
  static constexpr int kMaxModels = 4;
  using Model = PoseCw;
  std::span<const Eigen::Vector3d> X;
  std::span<const Eigen::Vector2d> x;
  double focal = 1.0;

  bool sampleIsDegenerate(std::span<const int> s) const {
    const Eigen::Vector3d& a = X[static_cast<std::size_t>(s[0])];
    const Eigen::Vector3d& b = X[static_cast<std::size_t>(s[1])];
    const Eigen::Vector3d& c = X[static_cast<std::size_t>(s[2])];
    const Eigen::Vector3d u = b - a, v = c - a;
    return u.cross(v).squaredNorm() < 1e-12 * u.squaredNorm() * v.squaredNorm();
  }
  int fit(std::span<const int> s, Model* models) const {
    Eigen::Vector3d P[3];
    Eigen::Vector2d p[3];
    for (int i = 0; i < 3; ++i) {
      P[i] = X[static_cast<std::size_t>(s[static_cast<std::size_t>(i)])];
      p[i] = x[static_cast<std::size_t>(s[static_cast<std::size_t>(i)])];
    }
    return solveP3P(P, p, models);
  }
  double squaredError(int i, const Model& m) const {
    return reprojSquared(m, X[static_cast<std::size_t>(i)], x[static_cast<std::size_t>(i)], focal);
  }
};

}  // namespace

bool refinePose(std::span<const Eigen::Vector3d> X, std::span<const Eigen::Vector2d> x,
                std::span<const uint8_t> mask, const PoseRefineOptions& o, PoseCw& pose,
                PoseRefineSummary* summary) {
  const double f = o.focal_px;
  auto cost = [&](const PoseCw& P, int& used) {
    double c = 0.0;
    used = 0;
    for (std::size_t i = 0; i < X.size(); ++i) {
      if (!mask.empty() && mask[i] == 0) continue;
      const Eigen::Vector3d p = P.toCamera(X[i]);
      if (!(p.z() > 1e-9)) return std::numeric_limits<double>::infinity();
      const double e = (p.hnormalized() - x[i]).norm() * f;
      c += (o.huber_px > 0.0 && e > o.huber_px) ? o.huber_px * (2.0 * e - o.huber_px) : e * e;
      ++used;
    }
    return c;
  };
  int used = 0;
  double current = cost(pose, used);
  if (summary != nullptr) {
    *summary = {};
    summary->initial_rms_px = used > 0 ? std::sqrt(current / used) : 0.0;
  }
  if (!std::isfinite(current) || used < 3) return false;
  double lambda = 1e-4;
  int it = 0;
  bool converged = false;
  for (; it < o.max_iterations; ++it) {
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    for (std::size_t i = 0; i < X.size(); ++i) {
      if (!mask.empty() && mask[i] == 0) continue;
      const Eigen::Vector3d p = pose.toCamera(X[i]);
      const double iz = 1.0 / p.z();
      const Eigen::Vector2d e = (Eigen::Vector2d(p.x() * iz, p.y() * iz) - x[i]) * f;
      Eigen::Matrix<double, 2, 3> Jp;
      Jp << f * iz, 0, -f * p.x() * iz * iz, 0, f * iz, -f * p.y() * iz * iz;
      Eigen::Matrix3d skew;
      skew << 0, -p.z(), p.y(), p.z(), 0, -p.x(), -p.y(), p.x(), 0;
      Eigen::Matrix<double, 2, 6> J;
      J.leftCols<3>() = -Jp * skew;  // d(exp(w) p)/dw = -[p]x
      J.rightCols<3>() = Jp;
      const double en = e.norm();
      const double w = (o.huber_px > 0.0 && en > o.huber_px) ? o.huber_px / en : 1.0;
      H += w * J.transpose() * J;
      g += w * J.transpose() * e;
    }
    bool accepted = false;
    for (int attempt = 0; attempt < 6 && !accepted; ++attempt) {
      Eigen::Matrix<double, 6, 6> A = H;
      A.diagonal() *= 1.0 + lambda;
      const Eigen::Matrix<double, 6, 1> d = A.ldlt().solve(-g);
      if (!d.allFinite()) return false;
      PoseCw next;
      const Eigen::Matrix3d dR = expSo3(d.head<3>());
      next.R_cw = dR * pose.R_cw;
      next.t_cw = dR * pose.t_cw + d.tail<3>();
      int u2 = 0;
      const double c2 = cost(next, u2);
      if (c2 < current) {
        const double gain = current - c2;
        pose = next;
        current = c2;
        lambda = std::max(1e-9, lambda * 0.3);
        accepted = true;
        if (gain < 1e-10 * (1.0 + current) || d.norm() < 1e-12) converged = true;
      } else {
        lambda *= 10.0;
      }
    }
    if (!accepted || converged) {
      converged = true;
      break;
    }
  }
  // Re-orthonormalize to keep R in SO(3) after many products.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(pose.R_cw, Eigen::ComputeFullU | Eigen::ComputeFullV);
  pose.R_cw = svd.matrixU() * svd.matrixV().transpose();
  if (summary != nullptr) {
    summary->iterations = it;
    summary->final_rms_px = used > 0 ? std::sqrt(current / used) : 0.0;
    summary->converged = converged;
  }
  return true;
}

PnpRansac::PnpRansac(int max_points)
    : max_points_(max_points), mask_(static_cast<std::size_t>(max_points)) {}

PnpRansac::Status PnpRansac::estimate(std::span<const Eigen::Vector3d> X,
                                      std::span<const Eigen::Vector2d> x, const PnpOptions& o,
                                      PnpResult& result) {
  result = {};
  const int n = static_cast<int>(X.size());
  if (X.size() != x.size() || n < 4) return Status::kTooFewPoints;
  if (n > max_points_) return Status::kTooManyPoints;
  for (std::size_t i = 0; i < X.size(); ++i)
    if (!X[i].allFinite() || !x[i].allFinite()) return Status::kNonFinite;
  P3pKernel k{X, x, o.focal_px};
  Ransac<P3pKernel> ransac;
  RansacSummary summary;
  PoseCw pose;
  if (!ransac.run(k, n, o.ransac, pose, summary)) return Status::kNoConsensus;
  const double t2 = o.ransac.threshold * o.ransac.threshold;
  auto classify = [&](const PoseCw& P) {
    int c = 0;
    for (int i = 0; i < n; ++i) {
      const bool in = k.squaredError(i, P) < t2;
      mask_[static_cast<std::size_t>(i)] = in ? 1 : 0;
      c += in ? 1 : 0;
    }
    return c;
  };
  int count = classify(pose);
  if (count < 4) return Status::kNoConsensus;
  const std::span<const uint8_t> mask(mask_.data(), X.size());
  if (o.refine) {
    for (int round = 0; round < 2; ++round) {
      PoseCw refined = pose;
      PoseRefineOptions ro = o.refine_options;
      ro.focal_px = o.focal_px;  // one focal for the threshold and the refinement
      if (!refinePose(X, x, mask, ro, refined)) break;
      pose = refined;
      const int c2 = classify(pose);
      if (c2 == count) break;
      count = c2;
    }
  }
  if (count < 4) return Status::kNoConsensus;
  double sum = 0.0;
  for (int i = 0; i < n; ++i)
    if (mask_[static_cast<std::size_t>(i)]) sum += k.squaredError(i, pose);
  result.pose = pose;
  result.inliers = count;
  result.iterations = summary.iterations;
  result.rms_px = std::sqrt(sum / count);
  result.mask = mask;
  if (!pose.R_cw.allFinite() || !pose.t_cw.allFinite()) return Status::kNonFinite;
  return Status::kOk;
}

}  // namespace epitrack

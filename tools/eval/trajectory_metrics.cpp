#include "tools/eval/trajectory_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <Eigen/SVD>

namespace epitrack::eval {
namespace {

double angleDeg(const Eigen::Matrix3d& R) {
  const double c = std::clamp((R.trace() - 1.0) * 0.5, -1.0, 1.0);
  // acos loses precision near 0; use atan2 of the axis part instead.
  const Eigen::Vector3d w(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));
  return std::atan2(0.5 * w.norm(), c) * 180.0 / 3.14159265358979323846;
}

// The rotation nearest (Frobenius) to M, reflection excluded (Umeyama 1991, eq. 39-40); not
// finite when M is.
Eigen::Matrix3d nearestRotation(const Eigen::Matrix3d& M) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) D(2, 2) = -1.0;
  return svd.matrixU() * D * svd.matrixV().transpose();
}

// The chordal L2 mean of the rotations summed in `sum` (Hartley et al. 2013, "Rotation
// averaging", sec. 5.3): the rotation nearest to it; identity when `sum` is degenerate.
Eigen::Matrix3d chordalMeanRotation(const Eigen::Matrix3d& sum) {
  const Eigen::Matrix3d R = nearestRotation(sum);
  return R.allFinite() ? R : Eigen::Matrix3d::Identity();
}

// Mean and largest angle between each ground-truth orientation and the aligned estimate's.
void rotationErrors(
    const std::vector<std::pair<const hal::TrajectoryEntry*, const hal::TrajectoryEntry*>>& pairs,
    const Eigen::Matrix3d& R_align, double& mean_deg, double& max_deg) {
  double sum = 0.0;
  max_deg = 0.0;
  for (const auto& [g, e] : pairs) {
    const double a = angleDeg(g->rotation.toRotationMatrix().transpose() * R_align *
                              e->rotation.toRotationMatrix());
    sum += a;
    max_deg = std::max(max_deg, a);
  }
  mean_deg = sum / static_cast<double>(pairs.size());
}

// The centres' means, cross-covariance (target x source) and source variance, each over n
// (Umeyama 1991, eqs. 34-38).
struct CentreMoments {
  Eigen::Vector3d mu_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d mu_t = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  double var_s = 0.0;
};

CentreMoments centreMoments(const std::vector<Eigen::Vector3d>& source,
                            const std::vector<Eigen::Vector3d>& target) {
  const std::size_t n = source.size();
  CentreMoments c;
  for (std::size_t i = 0; i < n; ++i) {
    c.mu_s += source[i];
    c.mu_t += target[i];
  }
  c.mu_s /= static_cast<double>(n);
  c.mu_t /= static_cast<double>(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d ds = source[i] - c.mu_s;
    c.cov += (target[i] - c.mu_t) * ds.transpose();
    c.var_s += ds.squaredNorm();
  }
  c.cov /= static_cast<double>(n);
  c.var_s /= static_cast<double>(n);
  return c;
}

// The least-squares scale for the rotation R (Umeyama's eq. 42 with R fixed).
double scaleForRotation(const CentreMoments& c, const Eigen::Matrix3d& R) {
  return (R.transpose() * c.cov).trace() / c.var_s;
}

// RMSE of the centres under the rotation R with the least-squares scale and translation for it.
double centreRmseForRotation(const std::vector<Eigen::Vector3d>& source,
                             const std::vector<Eigen::Vector3d>& target, const Eigen::Matrix3d& R) {
  const CentreMoments c = centreMoments(source, target);
  Similarity S;
  S.R = R;
  S.s = c.var_s > 0.0 ? std::max(0.0, scaleForRotation(c, R)) : 0.0;
  S.t = c.mu_t - S.s * R * c.mu_s;
  double sq = 0.0;
  for (std::size_t i = 0; i < source.size(); ++i)
    sq += (S.apply(source[i]) - target[i]).squaredNorm();
  return std::sqrt(sq / static_cast<double>(source.size()));
}

}  // namespace

bool umeyamaAlignment(const std::vector<Eigen::Vector3d>& source,
                      const std::vector<Eigen::Vector3d>& target, Similarity& out) {
  return umeyamaAlignment(source, target, Eigen::Matrix3d::Zero(), out);
}

bool umeyamaAlignment(const std::vector<Eigen::Vector3d>& source,
                      const std::vector<Eigen::Vector3d>& target,
                      const Eigen::Matrix3d& orientation_sum, Similarity& out) {
  const std::size_t n = source.size();
  if (n < 3 || target.size() != n) return false;
  const CentreMoments c = centreMoments(source, target);
  const Eigen::Matrix3d& cov = c.cov;
  const double var_s = c.var_s;
  if (!(var_s > 1e-300)) return false;
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d& d = svd.singularValues();
  if (!(d(1) > 1e-12 * std::max(1.0, d(0))))
    return false;  // collinear: rotation about the line is free
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) S(2, 2) = -1.0;
  out.R = svd.matrixU() * S * svd.matrixV().transpose();
  out.s = (d.asDiagonal() * S).trace() / var_s;
  if (!orientation_sum.isZero(0.0)) {
    // max tr(Rᵀ (cov + w M)): the positions' term plus w times the orientations' chordal
    // agreement; the orientations matter only where the positions' singular values are below w.
    const Eigen::JacobiSVD<Eigen::Matrix3d> so(orientation_sum, Eigen::ComputeFullU);
    const double m0 = so.singularValues()(0);
    if (m0 > 0.0) {
      const Eigen::Matrix3d C = cov + (kOrientationTieBreak * d(0) / m0) * orientation_sum;
      const Eigen::Matrix3d R = nearestRotation(C);
      if (R.allFinite()) {
        out.R = R;
        out.s = scaleForRotation(c, R);  // least squares for this rotation
      }
    }
  }
  out.t = c.mu_t - out.s * out.R * c.mu_s;
  return std::isfinite(out.s) && out.s > 0.0;
}

bool evaluateTrajectory(const std::vector<hal::TrajectoryEntry>& gt,
                        const std::vector<hal::TrajectoryEntry>& est, double max_dt,
                        TrajectoryMetrics& m, std::string& error) {
  m = TrajectoryMetrics{};
  m.gt_frames = static_cast<int>(gt.size());
  m.est_frames = static_cast<int>(est.size());
  // Association by time (frame index): for each estimate, the ground-truth entry closest in t.
  std::vector<const hal::TrajectoryEntry*> gt_sorted;
  for (const auto& g : gt) gt_sorted.push_back(&g);
  std::sort(gt_sorted.begin(), gt_sorted.end(), [](auto a, auto b) { return a->t < b->t; });
  std::vector<std::pair<const hal::TrajectoryEntry*, const hal::TrajectoryEntry*>> pairs;
  std::vector<const hal::TrajectoryEntry*> est_sorted;
  for (const auto& e : est) est_sorted.push_back(&e);
  std::sort(est_sorted.begin(), est_sorted.end(), [](auto a, auto b) { return a->t < b->t; });
  for (const auto* e : est_sorted) {
    const auto it =
        std::lower_bound(gt_sorted.begin(), gt_sorted.end(), e->t,
                         [](const hal::TrajectoryEntry* g, double t) { return g->t < t; });
    const hal::TrajectoryEntry* best = nullptr;
    double best_dt = max_dt;
    for (auto c = it == gt_sorted.begin() ? it : it - 1; c != gt_sorted.end() && c <= it; ++c) {
      const double dt = std::abs((*c)->t - e->t);
      if (dt <= best_dt) {
        best_dt = dt;
        best = *c;
      }
    }
    if (best != nullptr && (pairs.empty() || pairs.back().first != best))
      pairs.emplace_back(best, e);
  }
  m.matched_frames = static_cast<int>(pairs.size());
  if (pairs.size() < 2) {
    error = "only " + std::to_string(pairs.size()) +
            " frames match between the trajectories (by frame index)";
    return false;
  }
  std::vector<Eigen::Vector3d> src;
  std::vector<Eigen::Vector3d> dst;
  for (const auto& [g, e] : pairs) {
    src.push_back(e->position);
    dst.push_back(g->position);
  }
  Eigen::Matrix3d orientation_sum = Eigen::Matrix3d::Zero();
  for (const auto& [g, e] : pairs)
    orientation_sum += g->rotation.toRotationMatrix() * e->rotation.toRotationMatrix().transpose();
  Similarity S;
  m.aligned = umeyamaAlignment(src, dst, orientation_sum, S);
  if (!m.aligned) {  // two frames or a straight line: align centroids and scale only
    Eigen::Vector3d ms = Eigen::Vector3d::Zero();
    Eigen::Vector3d md = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < src.size(); ++i) {
      ms += src[i];
      md += dst[i];
    }
    ms /= static_cast<double>(src.size());
    md /= static_cast<double>(src.size());
    double ns = 0.0;
    double nd = 0.0;
    for (std::size_t i = 0; i < src.size(); ++i) {
      ns += (src[i] - ms).norm();
      nd += (dst[i] - md).norm();
    }
    S.s = ns > 0.0 ? nd / ns : 1.0;
    // The centres do not fix the rotation (a tripod, a straight line): take it from the camera
    // orientations instead, the chordal mean of R_gt,i R_est,iᵀ projected onto SO(3).
    S.R = chordalMeanRotation(orientation_sum);
    S.t = md - S.s * S.R * ms;
  }
  m.scale = S.s;
  double sq = 0.0;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const double e = (S.apply(src[i]) - dst[i]).norm();
    sq += e * e;
    m.ate_max = std::max(m.ate_max, e);
  }
  m.ate_rmse = std::sqrt(sq / static_cast<double>(pairs.size()));
  rotationErrors(pairs, S.R, m.rot_err_deg_mean, m.rot_err_deg_max);
  const Eigen::Matrix3d R_orient = chordalMeanRotation(orientation_sum);
  rotationErrors(pairs, R_orient, m.rot_err_deg_mean_orient_aligned,
                 m.rot_err_deg_max_orient_aligned);
  m.ate_rmse_orient_aligned = centreRmseForRotation(src, dst, R_orient);
  double rpe_sum = 0.0;
  double rpe_rot = 0.0;
  for (std::size_t i = 0; i + 1 < pairs.size(); ++i) {
    m.gt_path_length += (dst[i + 1] - dst[i]).norm();
    // Relative motion from pose i to pose i+1 in camera i's frame; invariant to the global
    // alignment except for the scale.
    const Eigen::Matrix3d Rg0 = pairs[i].first->rotation.toRotationMatrix();
    const Eigen::Matrix3d Rg1 = pairs[i + 1].first->rotation.toRotationMatrix();
    const Eigen::Matrix3d Re0 = pairs[i].second->rotation.toRotationMatrix();
    const Eigen::Matrix3d Re1 = pairs[i + 1].second->rotation.toRotationMatrix();
    const Eigen::Vector3d dg = Rg0.transpose() * (dst[i + 1] - dst[i]);
    const Eigen::Vector3d de = S.s * (Re0.transpose() * (src[i + 1] - src[i]));
    rpe_sum += (dg - de).norm();
    rpe_rot += angleDeg((Rg0.transpose() * Rg1).transpose() * (Re0.transpose() * Re1));
  }
  m.rpe_trans_rel = m.gt_path_length > 0.0 ? rpe_sum / m.gt_path_length : 0.0;
  m.rpe_rot_deg_mean = rpe_rot / static_cast<double>(pairs.size() - 1);
  m.ate_rmse_rel = m.gt_path_length > 0.0 ? m.ate_rmse / m.gt_path_length : 0.0;
  return true;
}

}  // namespace epitrack::eval

#include "algo/geometry/essential.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/SVD>

namespace epitrack {

Eigen::Matrix3d essentialFromFundamental(const Eigen::Matrix3d& F, const Eigen::Matrix3d& K1,
                                         const Eigen::Matrix3d& K2) {
  const Eigen::Matrix3d E = K2.transpose() * F * K1;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(E, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * Eigen::Vector3d(1.0, 1.0, 0.0).asDiagonal() * svd.matrixV().transpose();
}

void decomposeEssential(const Eigen::Matrix3d& E, Eigen::Matrix3d R[2], Eigen::Vector3d& t) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(E, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU(), V = svd.matrixV();
  if (U.determinant() < 0) U.col(2) *= -1.0;
  if (V.determinant() < 0) V.col(2) *= -1.0;
  Eigen::Matrix3d W;
  W << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  R[0] = U * W * V.transpose();
  R[1] = U * W.transpose() * V.transpose();
  t = U.col(2);
}

namespace {

// Depths (d1, d2) of the midpoint of the closest approach of the two rays x1 (camera 1 at the
// origin) and x2 (camera 2: X2 = R X1 + t). Returns false for parallel rays.
bool rayDepths(const Eigen::Matrix3d& R, const Eigen::Vector3d& t, const Eigen::Vector2d& a,
               const Eigen::Vector2d& b, double& d1, double& d2) {
  const Eigen::Vector3d f1 = a.homogeneous();
  const Eigen::Vector3d f2 = R.transpose() * b.homogeneous();  // ray 2 in camera 1's frame
  const Eigen::Vector3d c2 = -R.transpose() * t;               // centre of camera 2
  // Solve d1 f1 - d2' f2 = c2 in least squares.
  const double a11 = f1.dot(f1), a12 = -f1.dot(f2), a22 = f2.dot(f2);
  const double b1 = f1.dot(c2), b2 = -f2.dot(c2);
  const double det = a11 * a22 - a12 * a12;
  if (!(std::abs(det) > 1e-14 * a11 * a22)) return false;
  d1 = (a22 * b1 - a12 * b2) / det;
  const double s2 =
      (a11 * b2 - a12 * b1) / det;  // scale along f2 (depth in camera 2 since f2 z=1 there)
  d2 = s2;
  return true;
}

}  // namespace

bool recoverRelativePose(const Eigen::Matrix3d& E, std::span<const Eigen::Vector2d> n1,
                         std::span<const Eigen::Vector2d> n2, std::span<const uint8_t> mask,
                         RelativePoseResult& result) {
  result = {};
  if (!E.allFinite() || n1.size() != n2.size()) return false;
  Eigen::Matrix3d R[2];
  Eigen::Vector3d t;
  decomposeEssential(E, R, t);
  int counts[4] = {0, 0, 0, 0};
  int considered = 0;
  for (std::size_t i = 0; i < n1.size(); ++i) {
    if (!mask.empty() && mask[i] == 0) continue;
    if (!n1[i].allFinite() || !n2[i].allFinite()) continue;
    ++considered;
    for (int c = 0; c < 4; ++c) {
      const Eigen::Vector3d tc = (c & 1) ? Eigen::Vector3d(-t) : t;
      double d1 = 0.0, d2 = 0.0;
      if (rayDepths(R[c >> 1], tc, n1[i], n2[i], d1, d2) && d1 > 0.0 && d2 > 0.0) ++counts[c];
    }
  }
  int best = 0;
  for (int c = 1; c < 4; ++c)
    if (counts[c] > counts[best]) best = c;
  int second = 0;
  for (int c = 0; c < 4; ++c)
    if (c != best) second = std::max(second, counts[c]);
  if (counts[best] == 0) return false;
  result.pose.R_cw = R[best >> 1];
  result.pose.t_cw = (best & 1) ? Eigen::Vector3d(-t) : t;
  result.in_front = counts[best];
  result.second_best = second;
  result.considered = considered;
  return true;
}

namespace {

// Signed Sampson distance of x2^T E x1 = 0 in normalized units.
double signedSampson(const Eigen::Matrix3d& E, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector3d p1 = a.homogeneous(), p2 = b.homogeneous();
  const Eigen::Vector3d Ex1 = E * p1, Etx2 = E.transpose() * p2;
  const double d = Ex1.head<2>().squaredNorm() + Etx2.head<2>().squaredNorm();
  return d > 0.0 ? p2.dot(Ex1) / std::sqrt(d) : 0.0;
}

struct PoseParams {
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  [[nodiscard]] PoseParams moved(const Eigen::Matrix<double, 5, 1>& d) const {
    // Tangent basis of the unit sphere at t.
    Eigen::Vector3d a = std::abs(t.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    const Eigen::Vector3d b1 = t.cross(a).normalized();
    const Eigen::Vector3d b2 = t.cross(b1).normalized();
    PoseParams p;
    p.R = expSo3(d.head<3>()) * R;
    p.t = (t + d(3) * b1 + d(4) * b2).normalized();
    return p;
  }
};

}  // namespace

bool refineRelativePose(std::span<const Eigen::Vector2d> n1, std::span<const Eigen::Vector2d> n2,
                        std::span<const uint8_t> mask, double focal_px, PoseCw& pose,
                        int max_iterations, double huber_px) {
  if (n1.size() != n2.size() || !(pose.t_cw.norm() > 0.0)) return false;
  PoseParams cur{pose.R_cw, pose.t_cw.normalized()};
  // Cauchy loss whose scale follows the data: 2.5 robust sigmas of the current residuals, capped
  // by `huber_px` (a wrong match lying near its epipolar line then weighs little even when the
  // inliers fit to a fraction of a pixel).
  double h = huber_px / focal_px;
  auto cost = [&](const PoseParams& p) {
    const Eigen::Matrix3d E = skewSymmetric(p.t) * p.R;
    double c = 0.0;
    for (std::size_t i = 0; i < n1.size(); ++i) {
      if (!mask.empty() && !mask[i]) continue;
      const double e = signedSampson(E, n1[i], n2[i]);
      c += h * h * std::log1p(e * e / (h * h));
    }
    return c;
  };
  double lambda = 1e-3;
  constexpr double kStep = 1e-7;
  for (int it = 0; it < max_iterations; ++it) {
    {
      const Eigen::Matrix3d E = skewSymmetric(cur.t) * cur.R;
      double sorted[1024];
      std::size_t m = 0;
      for (std::size_t i = 0; i < n1.size() && m < 1024; ++i)
        if (mask.empty() || mask[i]) sorted[m++] = std::abs(signedSampson(E, n1[i], n2[i]));
      if (m == 0) return false;
      std::nth_element(sorted, sorted + m / 2, sorted + m);
      h = std::clamp(2.5 * 1.4826 * sorted[m / 2], 1e-4 / focal_px, huber_px / focal_px);
    }
    double current = cost(cur);
    Eigen::Matrix<double, 5, 5> H = Eigen::Matrix<double, 5, 5>::Zero();
    Eigen::Matrix<double, 5, 1> g = Eigen::Matrix<double, 5, 1>::Zero();
    const Eigen::Matrix3d E0 = skewSymmetric(cur.t) * cur.R;
    Eigen::Matrix3d Ek[5];
    for (int k = 0; k < 5; ++k) {
      Eigen::Matrix<double, 5, 1> d = Eigen::Matrix<double, 5, 1>::Zero();
      d(k) = kStep;
      const PoseParams p = cur.moved(d);
      Ek[k] = skewSymmetric(p.t) * p.R;
    }
    for (std::size_t i = 0; i < n1.size(); ++i) {
      if (!mask.empty() && !mask[i]) continue;
      const double e = signedSampson(E0, n1[i], n2[i]);
      Eigen::Matrix<double, 5, 1> J;
      for (int k = 0; k < 5; ++k) J(k) = (signedSampson(Ek[k], n1[i], n2[i]) - e) / kStep;
      const double w = 1.0 / (1.0 + e * e / (h * h));
      H += w * J * J.transpose();
      g += w * J * e;
    }
    bool accepted = false;
    for (int attempt = 0; attempt < 6 && !accepted; ++attempt) {
      Eigen::Matrix<double, 5, 5> A = H;
      A.diagonal() *= 1.0 + lambda;
      const Eigen::Matrix<double, 5, 1> d = A.ldlt().solve(-g);
      if (!d.allFinite()) return false;
      const PoseParams next = cur.moved(d);
      const double c2 = cost(next);
      if (c2 < current) {
        const bool tiny = current - c2 < 1e-12 * current;
        cur = next;
        current = c2;
        lambda = std::max(1e-9, lambda * 0.3);
        accepted = true;
        if (tiny) it = max_iterations;
      } else {
        lambda *= 10.0;
      }
    }
    if (!accepted) break;
  }
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cur.R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  pose.R_cw = svd.matrixU() * svd.matrixV().transpose();
  pose.t_cw = cur.t;
  return pose.R_cw.allFinite() && pose.t_cw.allFinite();
}

}  // namespace epitrack

#include "algo/geometry/resection.hpp"

#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include "algo/math/polynomial.hpp"

namespace epitrack {

bool alignRigid(std::span<const Eigen::Vector3d> a, std::span<const Eigen::Vector3d> b,
                Eigen::Matrix3d& R, Eigen::Vector3d& t) {
  if (a.size() != b.size() || a.size() < 3) return false;
  Eigen::Vector3d ca = Eigen::Vector3d::Zero(), cb = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < a.size(); ++i) {
    ca += a[i];
    cb += b[i];
  }
  ca /= static_cast<double>(a.size());
  cb /= static_cast<double>(a.size());
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < a.size(); ++i) S += (b[i] - cb) * (a[i] - ca).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(S, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) D(2, 2) = -1.0;
  R = svd.matrixU() * D * svd.matrixV().transpose();
  t = cb - R * ca;
  return R.allFinite() && t.allFinite();
}

bool resectLinear(std::span<const Eigen::Vector3d> X, std::span<const Eigen::Vector2d> x,
                  PoseCw& pose) {
  const std::size_t n = X.size();
  if (n < 6 || x.size() != n) return false;
  // Normalize the world points (centroid, mean distance sqrt(3)) for conditioning (H & Z §7.1).
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : X) {
    if (!p.allFinite()) return false;
    c += p;
  }
  c /= static_cast<double>(n);
  double d = 0.0;
  for (const auto& p : X) d += (p - c).norm();
  d /= static_cast<double>(n);
  if (!(d > 1e-12)) return false;
  const double s = std::sqrt(3.0) / d;
  Eigen::Matrix<double, 12, 12> AtA = Eigen::Matrix<double, 12, 12>::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    if (!x[i].allFinite()) return false;
    const Eigen::Vector4d Xh((X[i] - c).x() * s, (X[i] - c).y() * s, (X[i] - c).z() * s, 1.0);
    Eigen::Matrix<double, 12, 1> r0 = Eigen::Matrix<double, 12, 1>::Zero(), r1 = r0;
    r0.segment<4>(0) = Xh;
    r0.segment<4>(8) = -x[i].x() * Xh;
    r1.segment<4>(4) = Xh;
    r1.segment<4>(8) = -x[i].y() * Xh;
    AtA += r0 * r0.transpose() + r1 * r1.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> es(AtA);
  if (es.info() != Eigen::Success) return false;
  const auto& ev = es.eigenvalues();
  if (!(ev(1) > 1e-10 * ev(11))) return false;  // a second null direction: coplanar or too few
  const Eigen::Matrix<double, 12, 1> p = es.eigenvectors().col(0);
  Eigen::Matrix<double, 3, 4> P;
  P << p(0), p(1), p(2), p(3), p(4), p(5), p(6), p(7), p(8), p(9), p(10), p(11);
  // Undo the world normalization: P_world = P * [s I, -s c; 0 1].
  Eigen::Matrix3d M = P.leftCols<3>() * s;
  Eigen::Vector3d t = P.col(3) - M * c;
  // Sign: points in front (positive depth) for the majority.
  int front = 0;
  for (std::size_t i = 0; i < n; ++i) front += (M.row(2).dot(X[i]) + t.z()) > 0 ? 1 : -1;
  if (front < 0) {
    M = -M;
    t = -t;
  }
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const double scale = svd.singularValues().mean();
  if (!(scale > 0.0)) return false;
  Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
  if (R.determinant() < 0) return false;
  pose.R_cw = R;
  pose.t_cw = t / scale;
  return pose.R_cw.allFinite() && pose.t_cw.allFinite();
}

int solveP3P(const Eigen::Vector3d X[3], const Eigen::Vector2d normalized[3], PoseCw poses[4]) {
  const Eigen::Vector3d j1 = normalized[0].homogeneous().normalized();
  const Eigen::Vector3d j2 = normalized[1].homogeneous().normalized();
  const Eigen::Vector3d j3 = normalized[2].homogeneous().normalized();
  const double a2 = (X[1] - X[2]).squaredNorm();
  const double b2 = (X[0] - X[2]).squaredNorm();
  const double c2 = (X[0] - X[1]).squaredNorm();
  if (!(a2 > 0.0 && b2 > 0.0 && c2 > 0.0)) return 0;
  const double ca = j2.dot(j3), cb = j1.dot(j3), cg = j1.dot(j2);
  // Grunert's quartic in v = s3 / s1 (Haralick et al. 1994, §2.1).
  const double amc = (a2 - c2) / b2, apc = (a2 + c2) / b2;
  const double bmc = (b2 - c2) / b2, bma = (b2 - a2) / b2;
  double coeffs[5];
  coeffs[4] = (amc - 1.0) * (amc - 1.0) - 4.0 * c2 / b2 * ca * ca;
  coeffs[3] = 4.0 * (amc * (1.0 - amc) * cb - (1.0 - apc) * ca * cg + 2.0 * c2 / b2 * ca * ca * cb);
  coeffs[2] = 2.0 * (amc * amc - 1.0 + 2.0 * amc * amc * cb * cb + 2.0 * bmc * ca * ca -
                     4.0 * apc * ca * cb * cg + 2.0 * bma * cg * cg);
  coeffs[1] =
      4.0 * (-amc * (1.0 + amc) * cb + 2.0 * a2 / b2 * cg * cg * cb - (1.0 - apc) * ca * cg);
  coeffs[0] = (1.0 + amc) * (1.0 + amc) - 4.0 * a2 / b2 * cg * cg;
  double roots[4];
  const int nr = solveQuarticReal(coeffs, roots);
  int count = 0;
  for (int k = 0; k < nr; ++k) {
    const double v = roots[k];
    if (!(v > 0.0)) continue;
    const double den = 2.0 * (cg - v * ca);
    if (std::abs(den) < 1e-12) continue;
    const double u = ((-1.0 + amc) * v * v - 2.0 * amc * cb * v + 1.0 + amc) / den;
    if (!(u > 0.0)) continue;
    const double s1sq = b2 / (1.0 + v * v - 2.0 * v * cb);
    if (!(s1sq > 0.0)) continue;
    const double s1 = std::sqrt(s1sq);
    const Eigen::Vector3d P[3] = {s1 * j1, u * s1 * j2, v * s1 * j3};
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    if (!alignRigid(std::span<const Eigen::Vector3d>(X, 3), std::span<const Eigen::Vector3d>(P, 3),
                    R, t))
      continue;
    poses[count].R_cw = R;
    poses[count].t_cw = t;
    ++count;
  }
  return count;
}

}  // namespace epitrack

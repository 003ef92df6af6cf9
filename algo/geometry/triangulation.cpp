#include "algo/geometry/triangulation.hpp"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

namespace epitrack {

const char* toString(TriangulationStatus s) {
  switch (s) {
    case TriangulationStatus::kOk:
      return "ok";
    case TriangulationStatus::kDegenerate:
      return "degenerate";
    case TriangulationStatus::kBehindCamera:
      return "behind a camera";
    case TriangulationStatus::kLowParallax:
      return "parallax too small";
    case TriangulationStatus::kHighReprojection:
      return "reprojection error too high";
  }
  return "unknown";
}

bool triangulateDlt(std::span<const PoseCw> poses, std::span<const Eigen::Vector2d> normalized,
                    Eigen::Vector3d& X) {
  if (poses.size() < 2 || poses.size() != normalized.size()) return false;
  Eigen::Matrix4d AtA = Eigen::Matrix4d::Zero();
  for (std::size_t i = 0; i < poses.size(); ++i) {
    if (!normalized[i].allFinite()) return false;
    Eigen::Matrix<double, 3, 4> P;
    P.leftCols<3>() = poses[i].R_cw;
    P.col(3) = poses[i].t_cw;
    const Eigen::Vector4d r0 = normalized[i].x() * P.row(2).transpose() - P.row(0).transpose();
    const Eigen::Vector4d r1 = normalized[i].y() * P.row(2).transpose() - P.row(1).transpose();
    AtA += r0 * r0.transpose() + r1 * r1.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> es(AtA);
  if (es.info() != Eigen::Success) return false;
  const Eigen::Vector4d h = es.eigenvectors().col(0);
  if (!(std::abs(h(3)) > 1e-12 * h.head<3>().norm()) || !h.allFinite()) return false;
  X = h.head<3>() / h(3);
  return X.allFinite();
}

TriangulationResult triangulatePoint(std::span<const PoseCw> poses,
                                     std::span<const Eigen::Vector2d> normalized,
                                     const TriangulationOptions& o) {
  TriangulationResult r;
  if (!triangulateDlt(poses, normalized, r.X)) return r;
  // Gauss-Newton on sum |pi(R X + t) - x|^2 (3 unknowns).
  for (int it = 0; it < o.refine_iterations; ++it) {
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < poses.size(); ++i) {
      const Eigen::Vector3d p = poses[i].toCamera(r.X);
      if (!(p.z() > 1e-12)) break;
      const double iz = 1.0 / p.z();
      const Eigen::Vector2d e(p.x() * iz - normalized[i].x(), p.y() * iz - normalized[i].y());
      Eigen::Matrix<double, 2, 3> Jp;
      Jp << iz, 0, -p.x() * iz * iz, 0, iz, -p.y() * iz * iz;
      const Eigen::Matrix<double, 2, 3> J = Jp * poses[i].R_cw;
      H += J.transpose() * J;
      g += J.transpose() * e;
    }
    const Eigen::Vector3d dx = H.ldlt().solve(-g);
    if (!dx.allFinite()) break;
    r.X += dx;
    if (dx.norm() < 1e-9 * (1.0 + r.X.norm())) break;  // far below any pixel
  }
  if (!r.X.allFinite()) return r;
  double max_angle = 0.0;
  r.max_reproj_px = 0.0;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Eigen::Vector3d p = poses[i].toCamera(r.X);
    if (!(p.z() > 0.0)) {
      r.status = TriangulationStatus::kBehindCamera;
      return r;
    }
    const double e = (p.hnormalized() - normalized[i]).norm() * o.focal_px;
    r.max_reproj_px = std::max(r.max_reproj_px, e);
    // Parallax against the first and the last view (linear in the view count; the extreme
    // views of a track carry the largest angle in practice).
    const Eigen::Vector3d ri = (r.X - poses[i].centre()).normalized();
    for (const std::size_t j : {std::size_t{0}, poses.size() - 1}) {
      const Eigen::Vector3d rj = (r.X - poses[j].centre()).normalized();
      max_angle = std::max(max_angle, std::acos(std::clamp(ri.dot(rj), -1.0, 1.0)));
    }
  }
  r.parallax_deg = max_angle * 180.0 / M_PI;
  if (r.parallax_deg < o.min_parallax_deg) {
    r.status = TriangulationStatus::kLowParallax;
  } else if (r.max_reproj_px > o.max_reproj_px) {
    r.status = TriangulationStatus::kHighReprojection;
  } else {
    r.status = TriangulationStatus::kOk;
  }
  return r;
}

}  // namespace epitrack

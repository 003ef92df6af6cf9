// RotationAdjuster: the bundle adjustment of a rotating camera (see the header).
#include "algo/sfm/rotation_adjustment.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

#include "algo/geometry/pose.hpp"
#include "algo/math/huber.hpp"

namespace epitrack {

namespace {

// An orthonormal basis of the plane orthogonal to the unit vector d: the direction's two degrees
// of freedom. The same d always gives the same basis (linearisation and update agree).
Eigen::Matrix<double, 3, 2> tangentBasis(const Eigen::Vector3d& d) {
  const Eigen::Vector3d helper =
      std::abs(d.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d a = d.cross(helper).normalized();
  Eigen::Matrix<double, 3, 2> B;
  B.col(0) = a;
  B.col(1) = d.cross(a);
  return B;
}

// Pixel of x_c with radial distortion, its derivative in x_c and in the focal; false behind the
// camera.
bool projectDirection(const BaIntrinsics& k, const Eigen::Vector3d& x_c, Eigen::Vector2d& px,
                      Eigen::Matrix<double, 2, 3>* J_x, Eigen::Vector2d* J_f) {
  if (!(x_c.z() > 0.0)) return false;
  const double iz = 1.0 / x_c.z();
  const Eigen::Vector2d n(x_c.x() * iz, x_c.y() * iz);
  const double r2 = n.squaredNorm();
  const double s = 1.0 + k.k1 * r2 + k.k2 * r2 * r2;
  const Eigen::Vector2d fxy(k.f, k.f * k.aspect);
  px = Eigen::Vector2d(fxy.x() * s * n.x() + k.cx, fxy.y() * s * n.y() + k.cy);
  if (J_x != nullptr) {
    Eigen::Matrix<double, 2, 3> dn;
    dn << iz, 0.0, -n.x() * iz, 0.0, iz, -n.y() * iz;
    // d(s n)/dn = s I + n (ds/dn)^T, ds/dn = (2 k1 + 4 k2 r2) n.
    const Eigen::Matrix2d dsn =
        s * Eigen::Matrix2d::Identity() + (2.0 * k.k1 + 4.0 * k.k2 * r2) * n * n.transpose();
    *J_x = fxy.asDiagonal() * dsn * dn;
  }
  if (J_f != nullptr) *J_f = Eigen::Vector2d(s * n.x(), k.aspect * s * n.y());
  return true;
}

}  // namespace

RotationAdjuster::RotationAdjuster(int max_cameras, int max_directions, int max_observations)
    : max_cameras_(max_cameras),
      max_directions_(max_directions),
      max_observations_(max_observations) {
  const auto nc = static_cast<std::size_t>(std::max(0, max_cameras));
  const auto nd = static_cast<std::size_t>(std::max(0, max_directions));
  const auto no = static_cast<std::size_t>(std::max(0, max_observations));
  const int max_columns = 3 * max_cameras + 1;
  camera_column_.resize(nc);
  angular_.resize(nc);
  dw_.resize(3 * nc);
  cameras_.resize(nc);
  linear_.resize(no);
  obs_order_.resize(no);
  dir_offset_.resize(nd + 1);
  cursor_.resize(nd);
  S_.resize(max_columns, max_columns);
  g_.resize(max_columns);
  A_.resize(max_columns, max_columns);
  b_.resize(max_columns);
  step_.resize(max_columns);
  V_.resize(nd);
  bv_.resize(nd);
  dstep_.resize(nd);
  W_.setZero(max_columns, 2);
  WV_.setZero(max_columns, 2);
  runs_.reserve(static_cast<std::size_t>(max_columns));
  touched_.reserve(static_cast<std::size_t>(max_columns));
  is_touched_.assign(static_cast<std::size_t>(max_columns), 0);
  rot_trial_.resize(nc);
  dir_trial_.resize(nd);
}

void RotationAdjuster::updateMotions(std::span<const Eigen::Matrix3d> rotations,
                                     std::span<const BaTrajectoryNeighbours> neighbours) {
  if (shutter_.line_delay == 0.0) return;
  for (std::size_t c = 0; c < rotations.size(); ++c) cameras_[c].R_cw = rotations[c];
  const std::span<const BaCamera> cams(cameras_.data(), rotations.size());
  Eigen::Matrix<double, 6, 18> D;
  for (std::size_t c = 0; c < rotations.size(); ++c) {
    angular_[c] =
        BundleAdjuster::trajectoryMotion(cams, neighbours[c], static_cast<int>(c), &D).angular;
    for (int s = 0; s < 3; ++s) dw_[3 * c + static_cast<std::size_t>(s)] = D.block<3, 3>(0, 6 * s);
  }
}

double RotationAdjuster::evaluate(std::span<const Eigen::Matrix3d> rotations,
                                  std::span<const Eigen::Vector3d> directions,
                                  std::span<const RotationObservation> observations,
                                  std::span<const BaTrajectoryNeighbours> neighbours,
                                  const BaIntrinsics& k, double huber, double* rms) {
  updateMotions(rotations, neighbours);
  double cost = 0.0, sq = 0.0;
  int seen = 0;
  for (const RotationObservation& o : observations) {
    const auto c = static_cast<std::size_t>(o.camera);
    const double tau = shutter_.rowTime(o.xy.y());
    Eigen::Vector3d x_c = rotations[c] * directions[static_cast<std::size_t>(o.direction)];
    if (tau != 0.0) x_c = expSo3(angular_[c] * tau).transpose() * x_c;
    Eigen::Vector2d px;
    if (!projectDirection(k, x_c, px, nullptr, nullptr)) continue;
    const double e = (px - o.xy).norm();
    cost += huberCost(e, huber);
    sq += e * e;
    ++seen;
  }
  if (rms != nullptr) *rms = seen > 0 ? std::sqrt(sq / seen) : 0.0;
  return cost;
}

void RotationAdjuster::linearise(std::span<const Eigen::Matrix3d> rotations,
                                 std::span<const Eigen::Vector3d> directions,
                                 std::span<const RotationObservation> observations,
                                 std::span<const BaTrajectoryNeighbours> neighbours,
                                 const BaIntrinsics& k, double huber) {
  updateMotions(rotations, neighbours);
  const bool rs = shutter_.line_delay != 0.0;
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const RotationObservation& o = observations[i];
    Linear& L = linear_[i];
    L.columns = 0;
    L.weight = 0.0;
    const auto c = static_cast<std::size_t>(o.camera);
    const Eigen::Vector3d& d = directions[static_cast<std::size_t>(o.direction)];
    const double tau = rs ? shutter_.rowTime(o.xy.y()) : 0.0;
    const Eigen::Matrix3d E = tau != 0.0 ? Eigen::Matrix3d(expSo3(angular_[c] * tau).transpose())
                                         : Eigen::Matrix3d::Identity();
    const Eigen::Vector3d y = rotations[c] * d;
    Eigen::Vector2d px, J_f;
    Eigen::Matrix<double, 2, 3> J_x;
    if (!projectDirection(k, E * y, px, &J_x, &J_f)) continue;
    L.r = px - o.xy;
    const double e = L.r.norm();
    L.weight = huberWeight(e, huber);
    L.Jd = J_x * E * rotations[c] * tangentBasis(d);
    // x_c = Exp(-w tau) R_c d: left update of R_c gives -E [y]x; w's update gives tau E [y]x,
    // and w depends on the previous camera, this one and the next (the trajectory's motion).
    const Eigen::Matrix<double, 2, 3> J_y = J_x * E * skewSymmetric(y);
    const int cams[3] = {rs ? neighbours[c].previous : -1, o.camera, rs ? neighbours[c].next : -1};
    for (int s = 0; s < 3; ++s) {
      if (cams[s] < 0) continue;
      const int col = camera_column_[static_cast<std::size_t>(cams[s])];
      if (col < 0) continue;
      Eigen::Matrix<double, 2, 3> J =
          s == 1 ? Eigen::Matrix<double, 2, 3>(-J_y) : Eigen::Matrix<double, 2, 3>::Zero();
      if (tau != 0.0) J += tau * J_y * dw_[3 * c + static_cast<std::size_t>(s)];
      for (int a = 0; a < 3; ++a) {
        L.col[L.columns] = col + a;
        L.Jg.col(L.columns++) = J.col(a);
      }
    }
    if (refine_focal_) {
      L.col[L.columns] = columns_ - 1;
      L.Jg.col(L.columns++) = J_f;
    }
  }
  // The undamped normal equations of the cameras and the directions.
  S_.topLeftCorner(columns_, columns_).setZero();
  g_.head(columns_).setZero();
  for (std::size_t j = 0; j + 1 < dir_offset_.size() && static_cast<int>(j) < max_directions_;
       ++j) {
    V_[j].setZero();
    bv_[j].setZero();
  }
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const Linear& L = linear_[i];
    if (L.weight == 0.0) continue;
    const auto j = static_cast<std::size_t>(observations[i].direction);
    V_[j] += L.weight * L.Jd.transpose() * L.Jd;
    bv_[j] -= L.weight * L.Jd.transpose() * L.r;
    for (int a = 0; a < L.columns; ++a) {
      g_(L.col[a]) -= L.weight * L.Jg.col(a).dot(L.r);
      for (int b = 0; b < L.columns; ++b)
        S_(L.col[a], L.col[b]) += L.weight * L.Jg.col(a).dot(L.Jg.col(b));
    }
  }
}

// One direction's Schur term, A -= W V^-1 W^T and b -= W V^-1 bv, over the columns it touches.
// A track is seen by consecutive cameras, so its columns form a few contiguous runs (the
// cameras, the focal): the term is a few dense block products instead of one 2-vector dot
// product per pair of columns, which was half of a tripod solve's time.
void RotationAdjuster::subtractDirection(const Eigen::Matrix2d& Vinv, const Eigen::Vector2d& bv) {
  std::sort(touched_.begin(), touched_.end());
  runs_.clear();
  for (const int col : touched_) {
    if (!runs_.empty() && runs_.back().first + runs_.back().second == col)
      ++runs_.back().second;
    else
      runs_.emplace_back(col, 1);
  }
  for (const auto& [first, count] : runs_) {
    WV_.middleRows(first, count).noalias() = W_.middleRows(first, count) * Vinv;
    b_.segment(first, count).noalias() -= WV_.middleRows(first, count) * bv;
  }
  // Only the lower triangle: the Cholesky factorisation reads nothing else.
  for (std::size_t i = 0; i < runs_.size(); ++i) {
    const auto [row, rows] = runs_[i];
    A_.block(row, row, rows, rows).triangularView<Eigen::Lower>() -=
        WV_.middleRows(row, rows) * W_.middleRows(row, rows).transpose();
    for (std::size_t j = 0; j < i; ++j) {
      const auto [col, cols] = runs_[j];
      A_.block(row, col, rows, cols).noalias() -=
          WV_.middleRows(row, rows) * W_.middleRows(col, cols).transpose();
    }
  }
  for (const auto& [first, count] : runs_) {
    W_.middleRows(first, count).setZero();
    std::fill_n(is_touched_.begin() + first, count, uint8_t{0});
  }
}

// The damped step: the directions eliminated by the Schur complement (Triggs et al. §6.1), the
// reduced system factored by Cholesky, the directions back-substituted.
bool RotationAdjuster::solveStep(double lambda, int directions) {
  const int n = columns_;
  A_.topLeftCorner(n, n) = S_.topLeftCorner(n, n);
  for (int i = 0; i < n; ++i) A_(i, i) += lambda * std::max(S_(i, i), 1e-12);
  b_.head(n) = g_.head(n);
  for (int j = 0; j < directions; ++j) {
    const auto ju = static_cast<std::size_t>(j);
    Eigen::Matrix2d Vd = V_[ju];
    Vd.diagonal() += lambda * V_[ju].diagonal().cwiseMax(1e-12);
    const Eigen::Matrix2d Vinv = Vd.inverse();
    touched_.clear();
    for (int p = dir_offset_[ju]; p < dir_offset_[ju + 1]; ++p) {
      const Linear& L = linear_[static_cast<std::size_t>(obs_order_[static_cast<std::size_t>(p)])];
      if (L.weight == 0.0) continue;
      for (int a = 0; a < L.columns; ++a) {
        const int col = L.col[a];
        if (!is_touched_[static_cast<std::size_t>(col)]) {
          is_touched_[static_cast<std::size_t>(col)] = 1;
          touched_.push_back(col);
        }
        W_.row(col) += L.weight * L.Jg.col(a).transpose() * L.Jd;
      }
    }
    subtractDirection(Vinv, bv_[ju]);
  }
  Eigen::Ref<Eigen::MatrixXd> reduced = A_.topLeftCorner(n, n);
  Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> llt(reduced);  // in place: no allocation
  if (llt.info() != Eigen::Success) return false;
  step_.head(n) = llt.solve(b_.head(n));
  if (!step_.head(n).allFinite()) return false;
  for (int j = 0; j < directions; ++j) {
    const auto ju = static_cast<std::size_t>(j);
    Eigen::Matrix2d Vd = V_[ju];
    Vd.diagonal() += lambda * V_[ju].diagonal().cwiseMax(1e-12);
    Eigen::Vector2d rhs = bv_[ju];
    for (int p = dir_offset_[ju]; p < dir_offset_[ju + 1]; ++p) {
      const Linear& L = linear_[static_cast<std::size_t>(obs_order_[static_cast<std::size_t>(p)])];
      if (L.weight == 0.0) continue;
      Eigen::Vector2d jg = Eigen::Vector2d::Zero();
      for (int a = 0; a < L.columns; ++a) jg += L.Jg.col(a) * step_(L.col[a]);
      rhs -= L.weight * L.Jd.transpose() * jg;
    }
    dstep_[ju] = Vd.inverse() * rhs;
  }
  return true;
}

RotationAdjustmentSummary RotationAdjuster::solve(
    std::span<Eigen::Matrix3d> rotations, std::span<const uint8_t> fixed,
    std::span<Eigen::Vector3d> directions, std::span<const RotationObservation> observations,
    std::span<const BaTrajectoryNeighbours> neighbours, BaIntrinsics& intrinsics,
    const RotationAdjustmentOptions& options) {
  RotationAdjustmentSummary summary;
  const int nc = static_cast<int>(rotations.size());
  const int nd = static_cast<int>(directions.size());
  const bool rs = options.shutter.line_delay != 0.0;
  if (nc > max_cameras_ || nd > max_directions_ ||
      static_cast<int>(observations.size()) > max_observations_ ||
      fixed.size() != rotations.size() || (rs && neighbours.size() != rotations.size())) {
    summary.failed = true;
    return summary;
  }
  for (const RotationObservation& o : observations)
    if (o.camera < 0 || o.camera >= nc || o.direction < 0 || o.direction >= nd ||
        !o.xy.allFinite()) {
      summary.failed = true;
      return summary;
    }
  shutter_ = options.shutter;
  refine_focal_ = options.refine_focal;
  columns_ = 0;
  for (int c = 0; c < nc; ++c) {
    camera_column_[static_cast<std::size_t>(c)] =
        fixed[static_cast<std::size_t>(c)] ? -1 : columns_;
    if (!fixed[static_cast<std::size_t>(c)]) columns_ += 3;
  }
  if (refine_focal_) ++columns_;
  // Observations grouped by direction (counting sort).
  std::fill(dir_offset_.begin(), dir_offset_.begin() + nd + 1, 0);
  for (const RotationObservation& o : observations)
    ++dir_offset_[static_cast<std::size_t>(o.direction) + 1];
  for (int j = 0; j < nd; ++j)
    dir_offset_[static_cast<std::size_t>(j) + 1] += dir_offset_[static_cast<std::size_t>(j)];
  std::copy_n(dir_offset_.begin(), nd, cursor_.begin());
  for (std::size_t i = 0; i < observations.size(); ++i)
    obs_order_[static_cast<std::size_t>(
        cursor_[static_cast<std::size_t>(observations[i].direction)]++)] = static_cast<int>(i);

  const double huber = options.huber_px;
  double cost = evaluate(rotations, directions, observations, neighbours, intrinsics, huber,
                         &summary.initial_rms_px);
  summary.final_rms_px = summary.initial_rms_px;
  double lambda = options.initial_lambda;
  for (int it = 0; it < options.max_iterations && columns_ + nd > 0; ++it) {
    summary.iterations = it + 1;
    linearise(rotations, directions, observations, neighbours, intrinsics, huber);
    bool improved = false;
    for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
      if (!solveStep(lambda, nd)) {
        lambda *= 10.0;
        continue;
      }
      for (int c = 0; c < nc; ++c) {
        const auto cu = static_cast<std::size_t>(c);
        const int col = camera_column_[cu];
        rot_trial_[cu] = col < 0 ? rotations[cu]
                                 : Eigen::Matrix3d(expSo3(step_.segment<3>(col)) * rotations[cu]);
      }
      for (int j = 0; j < nd; ++j) {
        const auto ju = static_cast<std::size_t>(j);
        dir_trial_[ju] = (directions[ju] + tangentBasis(directions[ju]) * dstep_[ju]).normalized();
      }
      BaIntrinsics k_trial = intrinsics;
      if (refine_focal_) k_trial.f += step_(columns_ - 1);
      double rms = 0.0;
      const double trial_cost = k_trial.f > 0.0
                                    ? evaluate({rot_trial_.data(), rotations.size()},
                                               {dir_trial_.data(), directions.size()}, observations,
                                               neighbours, k_trial, huber, &rms)
                                    : cost + 1.0;
      if (trial_cost < cost) {
        std::copy_n(rot_trial_.begin(), nc, rotations.begin());
        std::copy_n(dir_trial_.begin(), nd, directions.begin());
        intrinsics = k_trial;
        const double decrease = (cost - trial_cost) / std::max(cost, 1e-300);
        cost = trial_cost;
        summary.final_rms_px = rms;
        lambda = std::max(lambda / 10.0, 1e-12);
        improved = true;
        if (decrease < options.function_tolerance) summary.converged = true;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) {
      summary.converged = true;  // no step lowers the cost: a minimum at this damping
      break;
    }
    if (summary.converged) break;
  }
  return summary;
}

}  // namespace epitrack

#include "algo/geometry/rolling_shutter.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

namespace epitrack {

PoseCw poseAtTime(const PoseCw& pose, const RollingShutterMotion& motion, double tau) {
  if (tau == 0.0) return pose;
  // x_c(tau) = Exp(w tau)^T R_cw (X - c - v tau) = R(tau) X + t(tau).
  const Eigen::Matrix3d step = expSo3(motion.angular * tau).transpose();
  PoseCw at;
  at.R_cw = step * pose.R_cw;
  at.t_cw = step * (pose.t_cw - pose.R_cw * (motion.linear * tau));
  return at;
}

namespace {

// Pinhole projection with radial distortion; false behind the camera.
bool projectPinhole(const CameraIntrinsics& k, const Eigen::Vector3d& x_c, Eigen::Vector2d& px) {
  if (!(x_c.z() > 0.0)) return false;
  const Eigen::Vector2d n = x_c.hnormalized();
  const double r2 = n.squaredNorm();
  const double d = 1.0 + r2 * (k.k1 + k.k2 * r2);
  px = Eigen::Vector2d(k.fx * n.x() * d + k.cx, k.fy * n.y() * d + k.cy);
  return px.allFinite();
}

}  // namespace

RollingShutterPixel projectRollingShutter(const CameraIntrinsics& k, const RollingShutter& shutter,
                                          const PoseCw& pose, const RollingShutterMotion& motion,
                                          const Eigen::Vector3d& X, int max_iterations,
                                          double tolerance_px) {
  RollingShutterPixel out;
  if (!projectPinhole(k, pose.toCamera(X), out.px)) {
    out.status = RollingShutterProjection::kBehindCamera;
    return out;
  }
  if (shutter.line_delay == 0.0) return out;  // the global shutter: the reference pose is it
  for (out.iterations = 1; out.iterations <= max_iterations; ++out.iterations) {
    out.tau = shutter.rowTime(out.px.y());
    Eigen::Vector2d next;
    if (!projectPinhole(k, poseAtTime(pose, motion, out.tau).toCamera(X), next)) {
      out.status = RollingShutterProjection::kBehindCamera;
      return out;
    }
    const double moved = std::fabs(next.y() - out.px.y());
    out.px = next;
    if (moved < tolerance_px) {
      out.tau = shutter.rowTime(out.px.y());
      return out;
    }
  }
  out.iterations = max_iterations;
  out.status = RollingShutterProjection::kNoConvergence;
  return out;
}

namespace {

constexpr int kParams = 12;  // pose increment (rotation, translation), w, v
using ParamVector = Eigen::Matrix<double, kParams, 1>;

// The parameters applied to the start: R_cw <- Exp(dr) R_cw, t_cw <- t_cw + dt.
void applyParams(const PoseCw& pose0, const ParamVector& p, PoseCw& pose,
                 RollingShutterMotion& motion) {
  pose.R_cw = expSo3(p.segment<3>(0)) * pose0.R_cw;
  pose.t_cw = pose0.t_cw + p.segment<3>(3);
  motion.angular = p.segment<3>(6);
  motion.linear = p.segment<3>(9);
}

struct Problem {
  const CameraIntrinsics& k;
  const RollingShutter& shutter;
  std::span<const Eigen::Vector3d> X;
  std::span<const Eigen::Vector2d> observed;
  const RollingShutterResectionOptions& options;
  PoseCw pose0;

  // Residual of observation i (pixels) for a pose and motion; false when it cannot be projected.
  bool residual(const PoseCw& pose, const RollingShutterMotion& motion, std::size_t i,
                Eigen::Vector2d& r) const {
    const RollingShutterPixel px = projectRollingShutter(k, shutter, pose, motion, X[i]);
    if (px.status != RollingShutterProjection::kOk) return false;
    r = px.px - observed[i];
    return true;
  }
  bool residual(const ParamVector& p, std::size_t i, Eigen::Vector2d& r) const {
    PoseCw pose;
    RollingShutterMotion motion;
    applyParams(pose0, p, pose, motion);
    return residual(pose, motion, i, r);
  }

  // d pixel / d x_c of the pinhole with radial distortion p = f n (1 + k1 r^2 + k2 r^4) + c.
  Eigen::Matrix<double, 2, 3> pixelJacobian(const Eigen::Vector3d& x_c) const {
    const double iz = 1.0 / x_c.z();
    const Eigen::Vector2d n(x_c.x() * iz, x_c.y() * iz);
    const double r2 = n.squaredNorm();
    const double d = 1.0 + r2 * (k.k1 + k.k2 * r2);
    const Eigen::Vector2d dd_dn = (2.0 * k.k1 + 4.0 * k.k2 * r2) * n;
    Eigen::Matrix2d dp_dn = d * Eigen::Matrix2d::Identity() + n * dd_dn.transpose();
    dp_dn.row(0) *= k.fx;
    dp_dn.row(1) *= k.fy;
    Eigen::Matrix<double, 2, 3> dn_dx;
    dn_dx << iz, 0.0, -n.x() * iz, 0.0, iz, -n.y() * iz;
    return dp_dn * dn_dx;
  }

  double huberWeight(double e) const { return e <= options.huber_px ? 1.0 : options.huber_px / e; }

  // Robust cost: Huber over the observations plus the velocity prior; squared pixels.
  double cost(const ParamVector& p, int& used) const {
    PoseCw pose;
    RollingShutterMotion motion;
    applyParams(pose0, p, pose, motion);
    double c = 0.0;
    used = 0;
    for (std::size_t i = 0; i < X.size(); ++i) {
      Eigen::Vector2d r;
      if (!residual(pose, motion, i, r)) continue;
      const double e = r.norm();
      c += e <= options.huber_px ? e * e : options.huber_px * (2.0 * e - options.huber_px);
      ++used;
    }
    const double prior = options.velocity_prior;
    return c + prior * prior * p.tail<6>().squaredNorm();
  }

  // Normal equations J^T W J and J^T W r at p. The Jacobian holds each point's row time tau at
  // its current value (the fixed point's own dependence on the parameters moves the row by
  // line_delay x row speed, about 6 % of the step, which only slows Gauss-Newton down a little):
  // with y = R_cw (X - v tau) + t_cw and x_c = Exp(-w tau) y = E y,
  //   d x_c / d rotation = -E [R_cw (X - v tau)]x,   d x_c / d t = E,
  //   d x_c / d w = tau E [y]x (first order in w tau),   d x_c / d v = -tau E R_cw,
  // then through the pinhole and the radial distortion.
  void normalEquations(const ParamVector& p, Eigen::Matrix<double, kParams, kParams>& A,
                       ParamVector& b) const {
    A.setZero();
    b.setZero();
    PoseCw pose;
    RollingShutterMotion motion;
    applyParams(pose0, p, pose, motion);
    for (std::size_t i = 0; i < X.size(); ++i) {
      const RollingShutterPixel px = projectRollingShutter(k, shutter, pose, motion, X[i]);
      if (px.status != RollingShutterProjection::kOk) continue;
      const Eigen::Vector2d r = px.px - observed[i];
      const double tau = px.tau;
      const Eigen::Matrix3d E = expSo3(motion.angular * tau).transpose();
      const Eigen::Vector3d a = pose.R_cw * (X[i] - motion.linear * tau);
      const Eigen::Vector3d y = a + pose.t_cw;
      const Eigen::Vector3d x_c = E * y;
      Eigen::Matrix<double, 3, kParams> dx;
      dx.block<3, 3>(0, 0) = -E * skewSymmetric(a);
      dx.block<3, 3>(0, 3) = E;
      dx.block<3, 3>(0, 6) = tau * E * skewSymmetric(y);
      dx.block<3, 3>(0, 9) = -tau * E * pose.R_cw;
      const Eigen::Matrix<double, 2, kParams> J = pixelJacobian(x_c) * dx;
      const double w = huberWeight(r.norm());
      A.noalias() += w * J.transpose() * J;
      b.noalias() += w * J.transpose() * r;
    }
    const double prior2 = options.velocity_prior * options.velocity_prior;
    A.bottomRightCorner<6, 6>().diagonal().array() += prior2;
    b.tail<6>() += prior2 * p.tail<6>();
  }
};

}  // namespace

RollingShutterResectionResult refineRollingShutterPose(
    const CameraIntrinsics& k, const RollingShutter& shutter, std::span<const Eigen::Vector3d> X,
    std::span<const Eigen::Vector2d> observed, PoseCw& pose, RollingShutterMotion& motion,
    const RollingShutterResectionOptions& options) {
  RollingShutterResectionResult result;
  if (X.size() != observed.size() || X.size() < 6) return result;
  Problem problem{k, shutter, X, observed, options, pose};
  ParamVector p = ParamVector::Zero();
  p.segment<3>(6) = motion.angular;
  p.segment<3>(9) = motion.linear;
  int used = 0;
  double cost = problem.cost(p, used);
  double lambda = 1e-3;
  Eigen::Matrix<double, kParams, kParams> A;
  ParamVector b;
  for (result.iterations = 0; result.iterations < options.max_iterations; ++result.iterations) {
    problem.normalEquations(p, A, b);
    bool improved = false;
    for (int attempt = 0; attempt < 8 && !improved; ++attempt) {
      Eigen::Matrix<double, kParams, kParams> damped = A;
      damped.diagonal() += lambda * A.diagonal().cwiseMax(1e-12);
      const ParamVector step = damped.ldlt().solve(-b);
      if (!step.allFinite()) break;
      int used_next = 0;
      const double next = problem.cost(p + step, used_next);
      if (next < cost && used_next >= used) {
        p += step;
        // Converged when the step is tiny or the cost no longer falls by a relative 1e-6 (the
        // noise-level minimum of a few hundred points is reached well before).
        if (step.norm() < options.stop_step || cost - next < 1e-6 * cost) result.converged = true;
        cost = next;
        used = used_next;
        lambda = std::max(lambda / 3.0, 1e-9);
        improved = true;
      } else {
        lambda *= 4.0;
      }
    }
    if (!improved) result.converged = true;  // no step lowers the cost: at the minimum
    if (result.converged) break;
  }
  applyParams(problem.pose0, p, pose, motion);
  double sum = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < X.size(); ++i) {
    Eigen::Vector2d r;
    if (!problem.residual(p, i, r)) continue;
    sum += r.squaredNorm();
    ++n;
  }
  result.rms_px = n > 0 ? std::sqrt(sum / n) : 0.0;
  return result;
}

}  // namespace epitrack

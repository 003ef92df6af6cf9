#include "algo/sfm/bundle_adjustment.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "algo/geometry/pose.hpp"
#include "algo/math/huber.hpp"

namespace epitrack {
namespace {

// sin(theta) / theta and (1 - cos(theta)) / theta^2 of theta^2. Below theta^2 = 1e-4 (a
// readout's rotation, a late LM step) their series to theta^4: the next terms, theta^6 / 5040
// and / 40320, are under 2e-16, while the closed form of the second loses 1e-12 relative to the
// cancellation in 1 - cos(theta); and no sin/cos.
struct RodriguesCoefficients {
  double s = 1.0;
  double c = 0.5;
};
RodriguesCoefficients rodriguesCoefficients(double theta2) {
  if (theta2 < 1e-4)
    return {1.0 - theta2 / 6.0 + theta2 * theta2 / 120.0,
            0.5 - theta2 / 24.0 + theta2 * theta2 / 720.0};
  const double theta = std::sqrt(theta2);
  return {std::sin(theta) / theta, (1.0 - std::cos(theta)) / theta2};
}

// exp([w]x) by Rodrigues' formula.
Eigen::Matrix3d rodrigues(const Eigen::Vector3d& w) {
  const RodriguesCoefficients k = rodriguesCoefficients(w.squaredNorm());
  const Eigen::Matrix3d W = skewSymmetric(w);
  return Eigen::Matrix3d::Identity() + k.s * W + k.c * (W * W);
}

constexpr double kMinDepth = 1e-8;

// The right Jacobian of SO(3): Exp(phi + d) = Exp(phi) Exp(Jr(phi) d) to first order in d;
// Jr = I - c [phi]x + (1 - s) / theta^2 [phi]x^2 (the Rodrigues coefficients), the last one's
// series 1/6 - theta^2 / 120 + theta^4 / 5040 below theta^2 = 1e-4.
double rightJacobianSquareCoefficient(double theta2, const RodriguesCoefficients& k) {
  return theta2 < 1e-4 ? 1.0 / 6.0 - theta2 / 120.0 + theta2 * theta2 / 5040.0
                       : (1.0 - k.s) / theta2;
}
Eigen::Matrix3d rightJacobianSo3(const Eigen::Vector3d& phi) {
  const double theta2 = phi.squaredNorm();
  const RodriguesCoefficients k = rodriguesCoefficients(theta2);
  const double d = rightJacobianSquareCoefficient(theta2, k);
  const Eigen::Matrix3d P = skewSymmetric(phi);
  return Eigen::Matrix3d::Identity() - k.c * P + d * (P * P);
}

// Jr(phi)^T v as vectors: Jr^T = I + c [phi]x + d [phi]x^2 (rightJacobianSo3 transposed).
Eigen::Vector3d rightJacobianSo3TransposeTimes(const Eigen::Vector3d& phi,
                                               const RodriguesCoefficients& k,
                                               const Eigen::Vector3d& v) {
  const double d = rightJacobianSquareCoefficient(phi.squaredNorm(), k);
  const Eigen::Vector3d pv = phi.cross(v);
  return v + k.c * pv + d * phi.cross(pv);
}

// Exp([phi]x) y by Rodrigues' formula on the vector (no matrix), with phi's coefficients.
Eigen::Vector3d rotateByExp(const Eigen::Vector3d& phi, const RodriguesCoefficients& k,
                            const Eigen::Vector3d& y) {
  const Eigen::Vector3d py = phi.cross(y);
  return y + k.s * py + k.c * phi.cross(py);
}
Eigen::Vector3d rotateByExp(const Eigen::Vector3d& phi, const Eigen::Vector3d& y) {
  return rotateByExp(phi, rodriguesCoefficients(phi.squaredNorm()), y);
}

// Fixed point of the row: at most this many steps, stopping below this row change (pixels).
// A row off by d moves the projection by about (readout per row x image speed) d, a few
// percent of d under the fastest motion solved here, so 1e-6 px of row is < 1e-7 px of
// projection: far below the noise, and a step fewer per projection than 1e-9.
constexpr int kMaxRowSteps = 20;
constexpr double kRowTolerancePx = 1e-6;

}  // namespace

BundleAdjuster::BundleAdjuster(int max_cameras, int max_points, int max_observations,
                               BaCapacity capacity)
    : max_cameras_(max_cameras),
      max_points_(max_points),
      max_observations_(max_observations),
      capacity_(capacity) {
  const bool rolling_shutter = capacity != BaCapacity::kGlobalShutter;
  const auto nc = static_cast<std::size_t>(std::max(0, max_cameras));
  const auto np = static_cast<std::size_t>(std::max(0, max_points));
  const auto no = static_cast<std::size_t>(std::max(0, max_observations));
  camera_slot_.resize(nc);
  point_obs_offset_.resize(np + 1);
  point_obs_index_.resize(no);
  point_obs_cursor_.resize(np);
  // With a rolling shutter an observation has two entries (its pose and its motion slot), with
  // the smooth trajectory up to three (its camera and the neighbours).
  const std::size_t pairs = rolling_shutter ? 3 * no : no;
  pair_obs_.resize(pairs);
  pair_slot_.resize(pairs);
  pair_begin_.resize(np);
  pair_end_.resize(np);
  pair_Wc_.resize(pairs);
  V_.resize(np);
  gp_.resize(np);
  Vinv_.resize(np);
  dp_.resize(np);
  Wc_.resize(no);
  Wk_.resize(no);
  cameras_backup_.resize(nc);
  points_backup_.resize(np);
  if (rolling_shutter) {
    Wv_.resize(no);
    motions_backup_.resize(nc);
    motion_D_.resize(nc);
    camera_gradient_.resize(nc);
    motion_gradient_.resize(nc);
    obs_entry_.resize(no);
    row_.resize(no);
  }
  // The reduced system: 6 or 12 per camera, then the intrinsics (f, k1, k2; the line delay too
  // in solveTrajectory).
  const Eigen::Index per_camera = capacity == BaCapacity::kRollingShutter ? 12 : 6;
  const Eigen::Index n = per_camera * static_cast<Eigen::Index>(nc) + 4;
  S_.resize(n, n);
  A_.resize(n, n);
  rhs_.resize(n);
  b_.resize(n);
  delta_.resize(n);
  diag_.resize(n);
}

bool BundleAdjuster::project(const BaCamera& c, const BaIntrinsics& k, const Eigen::Vector3d& X,
                             Eigen::Vector2d& uv) {
  return projectCameraPoint(k, c.R_cw * X + c.t_cw, uv);
}

bool BundleAdjuster::projectCameraPoint(const BaIntrinsics& k, const Eigen::Vector3d& p,
                                        Eigen::Vector2d& uv) {
  if (!(p.z() > kMinDepth)) return false;
  const double xn = p.x() / p.z();
  const double yn = p.y() / p.z();
  const double r2 = xn * xn + yn * yn;
  const double d = 1.0 + k.k1 * r2 + k.k2 * r2 * r2;
  uv = Eigen::Vector2d(k.f * d * xn + k.cx, k.f * k.aspect * d * yn + k.cy);
  return true;
}

namespace {

// The pinhole-with-radial-distortion projection of a camera-frame point p, d uv / d p and
// d uv / d (f, k1, k2); false behind the camera.
bool cameraPointJacobians(const BaIntrinsics& k, const Eigen::Vector3d& p, Eigen::Vector2d& uv,
                          Eigen::Matrix<double, 2, 3>& J_uv_p,
                          Eigen::Matrix<double, 2, 3>& J_intr) {
  if (!(p.z() > kMinDepth)) return false;
  const double iz = 1.0 / p.z();
  const double xn = p.x() * iz;
  const double yn = p.y() * iz;
  const double r2 = xn * xn + yn * yn;
  const double d = 1.0 + k.k1 * r2 + k.k2 * r2 * r2;
  const double dd_dr2 = k.k1 + 2.0 * k.k2 * r2;
  const double fx = k.f;
  const double fy = k.f * k.aspect;
  uv = Eigen::Vector2d(fx * d * xn + k.cx, fy * d * yn + k.cy);
  // d(uv)/d(xn, yn)
  Eigen::Matrix2d J_n;
  J_n(0, 0) = fx * (d + 2.0 * xn * xn * dd_dr2);
  J_n(0, 1) = fx * 2.0 * xn * yn * dd_dr2;
  J_n(1, 0) = fy * 2.0 * xn * yn * dd_dr2;
  J_n(1, 1) = fy * (d + 2.0 * yn * yn * dd_dr2);
  // d(xn, yn)/d(p)
  Eigen::Matrix<double, 2, 3> J_p;
  J_p << iz, 0.0, -xn * iz, 0.0, iz, -yn * iz;
  J_uv_p = J_n * J_p;
  J_intr(0, 0) = d * xn;
  J_intr(1, 0) = k.aspect * d * yn;
  J_intr(0, 1) = fx * xn * r2;
  J_intr(1, 1) = fy * yn * r2;
  J_intr(0, 2) = fx * xn * r2 * r2;
  J_intr(1, 2) = fy * yn * r2 * r2;
  return true;
}

}  // namespace

bool BundleAdjuster::projectWithJacobians(const BaCamera& c, const BaIntrinsics& k,
                                          const Eigen::Vector3d& X, Eigen::Vector2d& uv,
                                          Eigen::Matrix<double, 2, 6>& J_cam,
                                          Eigen::Matrix<double, 2, 3>& J_point,
                                          Eigen::Matrix<double, 2, 3>& J_intr) {
  const Eigen::Vector3d RX = c.R_cw * X;
  Eigen::Matrix<double, 2, 3> J_uv_p;
  if (!cameraPointJacobians(k, RX + c.t_cw, uv, J_uv_p, J_intr)) return false;
  // p = exp(dtheta) R X + t + dt  =>  dp/ddtheta = -[R X]x, dp/ddt = I, dp/dX = R.
  J_cam.leftCols<3>() = -J_uv_p * skewSymmetric(RX);
  J_cam.rightCols<3>() = J_uv_p;
  J_point = J_uv_p * c.R_cw;
  return true;
}

bool BundleAdjuster::projectRollingShutter(const BaCamera& c, const RollingShutterMotion& m,
                                           const RollingShutter& shutter, const BaIntrinsics& k,
                                           const Eigen::Vector3d& X, Eigen::Vector2d& uv,
                                           double& tau, double start_row) {
  tau = 0.0;
  // The point in the camera of the row exposed at tau: x_c(tau) = Exp(-w tau) (R_cw (X - v tau) +
  // t_cw) = Exp(-w tau) (x_0 - tau R_cw v), x_0 the reference row's.
  const Eigen::Vector3d x_0 = c.R_cw * X + c.t_cw;
  const Eigen::Vector3d Rv = c.R_cw * m.linear;
  // The row y where g(y) = pi_y(x_c(tau(y))) - y = 0, from the reference row's projection (or a
  // previous projection's row). The plain iteration y <- pi_y contracts by line delay x row speed
  // (a few %: 6-8 steps to 1e-9 px, algo/geometry/rolling_shutter.hpp); g is nearly linear in y,
  // so secant steps on g reach the same tolerance in 3-4 projections.
  double y = start_row;
  if (!std::isfinite(start_row)) {
    if (!projectCameraPoint(k, x_0, uv)) return false;
    y = uv.y();
  }
  double y_prev = 0.0, g_prev = 0.0;
  for (int step = 0; step < kMaxRowSteps; ++step) {
    tau = shutter.rowTime(y);
    Eigen::Vector2d next;
    if (!projectCameraPoint(k, rotateByExp(-tau * m.angular, x_0 - tau * Rv), next)) return false;
    const double g = next.y() - y;
    uv = next;
    if (std::fabs(g) < kRowTolerancePx) {
      tau = shutter.rowTime(uv.y());
      return uv.allFinite();
    }
    double y_next = next.y();
    if (step > 0 && g != g_prev) {
      const double secant = y - g * (y - y_prev) / (g - g_prev);
      if (std::isfinite(secant)) y_next = secant;
    }
    y_prev = y;
    g_prev = g;
    y = y_next;
  }
  return false;
}

bool BundleAdjuster::projectRollingShutterWithJacobians(
    const BaCamera& c, const RollingShutterMotion& m, const RollingShutter& shutter,
    const BaIntrinsics& k, const Eigen::Vector3d& X, Eigen::Vector2d& uv,
    Eigen::Matrix<double, 2, 6>& J_cam, Eigen::Matrix<double, 2, 6>& J_motion,
    Eigen::Matrix<double, 2, 3>& J_point, Eigen::Matrix<double, 2, 3>& J_intr,
    Eigen::Vector2d* J_line_delay) {
  double tau = 0.0;
  if (!projectRollingShutter(c, m, shutter, k, X, uv, tau)) return false;
  // At the row's camera: d uv / d x_c (G) and d uv / d intrinsics with the row held.
  // x_c = E y, E = Exp(-w tau), y = a + t_cw, a = R_cw (X - v tau):
  //   d x_c / d dtheta = -E [a]x,  d x_c / d dt = E,
  //   d x_c / d w = tau E [y]x Jr(-w tau),  d x_c / d v = -tau E R_cw,
  //   d x_c / d tau = -w x x_c - E R_cw v.
  const Eigen::Matrix3d E = rodrigues(-tau * m.angular);
  const Eigen::Vector3d a = c.R_cw * (X - m.linear * tau);
  const Eigen::Vector3d y = a + c.t_cw;
  const Eigen::Vector3d x_c = E * y;
  Eigen::Matrix<double, 2, 3> G;
  if (!cameraPointJacobians(k, x_c, uv, G, J_intr)) return false;
  const Eigen::Matrix<double, 2, 3> GE = G * E;
  J_point = GE * c.R_cw;
  J_cam.leftCols<3>() = -GE * skewSymmetric(a);
  J_cam.rightCols<3>() = GE;
  J_motion.leftCols<3>() = tau * GE * skewSymmetric(y) * rightJacobianSo3(-tau * m.angular);
  J_motion.rightCols<3>() = -tau * GE * c.R_cw;
  const Eigen::Vector2d u_tau = G * (-m.angular.cross(x_c) - E * (c.R_cw * m.linear));
  // The row moves with the parameters: uv = pi(q, tau(uv_y)) gives
  // d uv_y = D_y / (1 - l u_tau_y) and d uv = D + l u_tau d uv_y (l: the line delay, D the
  // derivative with the row held), i.e. every Jacobian times M = I + l / (1 - l u_tau_y) u_tau
  // e_y^T.
  const double l = shutter.line_delay;
  const double denom = 1.0 - l * u_tau.y();
  if (!(std::fabs(denom) > 1e-6)) return false;
  Eigen::Matrix2d M = Eigen::Matrix2d::Identity();
  M.col(1) += (l / denom) * u_tau;
  J_cam = M * J_cam;
  J_motion = M * J_motion;
  J_point = M * J_point;
  J_intr = M * J_intr;
  // The line delay moves the row's time at a held row by (y - reference_row).
  if (J_line_delay != nullptr) *J_line_delay = M * u_tau * (uv.y() - shutter.reference_row);
  return true;
}

bool BundleAdjuster::rollingShutterGradient(const BaCamera& c, const RollingShutterMotion& m,
                                            const RollingShutter& shutter, const BaIntrinsics& k,
                                            const Eigen::Vector3d& X, double tau,
                                            const Eigen::Vector2d& v, RollingShutterGradient& out) {
  // projectRollingShutterWithJacobians transposed: with q = M^T v and u = (G E)^T q,
  //   J_cam^T v = (a x u, u), J_motion^T v = (-tau Jr^T (y x u), -tau R_cw^T u),
  //   J_point^T v = R_cw^T u, J_intr^T v = J_intr0^T q, J_l^T v = (u_tau . q) (row - reference).
  const Eigen::Vector3d a = c.R_cw * (X - m.linear * tau);
  const Eigen::Vector3d y = a + c.t_cw;
  // E = Exp(-w tau) and E^T = Exp(w tau) share their coefficients (functions of theta^2).
  const Eigen::Vector3d phi = -tau * m.angular;
  const RodriguesCoefficients coefficients = rodriguesCoefficients(phi.squaredNorm());
  const Eigen::Vector3d x_c = rotateByExp(phi, coefficients, y);
  Eigen::Vector2d uv;
  Eigen::Matrix<double, 2, 3> G;
  Eigen::Matrix<double, 2, 3> J_intr0;
  if (!cameraPointJacobians(k, x_c, uv, G, J_intr0)) return false;
  const Eigen::Vector2d u_tau =
      G * (-m.angular.cross(x_c) - rotateByExp(phi, coefficients, c.R_cw * m.linear));
  const double l = shutter.line_delay;
  const double denom = 1.0 - l * u_tau.y();
  if (!(std::fabs(denom) > 1e-6)) return false;
  Eigen::Vector2d q = v;
  q.y() += (l / denom) * u_tau.dot(v);
  const Eigen::Vector3d u = rotateByExp(-phi, coefficients, G.transpose() * q);  // E^T
  out.camera.head<3>() = a.cross(u);
  out.camera.tail<3>() = u;
  out.point = c.R_cw.transpose() * u;
  out.motion.head<3>() = -tau * rightJacobianSo3TransposeTimes(phi, coefficients, y.cross(u));
  out.motion.tail<3>() = -tau * out.point;
  out.intrinsics = J_intr0.transpose() * q;
  out.line_delay = u_tau.dot(q) * (uv.y() - shutter.reference_row);
  return true;
}

namespace {

// The inverse of the right Jacobian of SO(3): Log(Exp(phi) Exp(d)) = phi + Jr^-1(phi) d to first
// order; the left one is Jr^-1(-phi).
Eigen::Matrix3d rightJacobianInverseSo3(const Eigen::Vector3d& phi) {
  const double theta2 = phi.squaredNorm();
  const Eigen::Matrix3d P = skewSymmetric(phi);
  if (theta2 < 1e-10) return Eigen::Matrix3d::Identity() + 0.5 * P + (1.0 / 12.0) * (P * P);
  const double theta = std::sqrt(theta2);
  const double c = 1.0 / theta2 - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta));
  return Eigen::Matrix3d::Identity() + 0.5 * P + c * (P * P);
}

Eigen::Vector3d centreOf(const BaCamera& c) { return -c.R_cw.transpose() * c.t_cw; }

// d centre / d (dtheta, dt) for x_c = Exp(dtheta) R X + t + dt: c = -R^T t moves by
// -R^T [t]x dtheta - R^T dt.
Eigen::Matrix<double, 3, 6> centreJacobian(const BaCamera& c) {
  Eigen::Matrix<double, 3, 6> J;
  J.leftCols<3>() = -c.R_cw.transpose() * skewSymmetric(c.t_cw);
  J.rightCols<3>() = -c.R_cw.transpose();
  return J;
}

}  // namespace

RollingShutterMotion BundleAdjuster::trajectoryMotion(std::span<const BaCamera> cameras,
                                                      const BaTrajectoryNeighbours& nb, int c,
                                                      Eigen::Matrix<double, 6, 18>* D) {
  RollingShutterMotion m;
  if (D != nullptr) D->setZero();
  const BaCamera& cc = cameras[static_cast<std::size_t>(c)];
  const bool has_prev = nb.previous >= 0, has_next = nb.next >= 0;
  if (!has_prev && !has_next) return m;
  // R_cw(f + d) = Exp(-w d) R_cw(f), c(f + d) = c(f) + v d (rolling_shutter.hpp); each side's
  // difference weighted 1/2 when both exist.
  const double half = has_prev && has_next ? 0.5 : 1.0;
  if (has_prev) {
    const BaCamera& cp = cameras[static_cast<std::size_t>(nb.previous)];
    const Eigen::Vector3d phi = logSo3(cp.R_cw * cc.R_cw.transpose());  // = w
    m.angular += half * phi;
    m.linear += half * (centreOf(cc) - centreOf(cp));
    if (D != nullptr) {
      // Log(Exp(dp) X Exp(-dc)) = phi + Jl^-1 dp - Jr^-1 dc.
      D->block<3, 3>(0, 0) += half * rightJacobianInverseSo3(-phi);
      D->block<3, 3>(0, 6) -= half * rightJacobianInverseSo3(phi);
      D->block<3, 6>(3, 6) += half * centreJacobian(cc);
      D->block<3, 6>(3, 0) -= half * centreJacobian(cp);
    }
  }
  if (has_next) {
    const BaCamera& cn = cameras[static_cast<std::size_t>(nb.next)];
    const Eigen::Vector3d phi = logSo3(cn.R_cw * cc.R_cw.transpose());  // = -w
    m.angular -= half * phi;
    m.linear += half * (centreOf(cn) - centreOf(cc));
    if (D != nullptr) {
      D->block<3, 3>(0, 12) -= half * rightJacobianInverseSo3(-phi);
      D->block<3, 3>(0, 6) += half * rightJacobianInverseSo3(phi);
      D->block<3, 6>(3, 12) += half * centreJacobian(cn);
      D->block<3, 6>(3, 6) -= half * centreJacobian(cc);
    }
  }
  return m;
}

void BundleAdjuster::updateTrajectoryMotions(std::span<const BaCamera> cameras) {
  for (std::size_t c = 0; c < cameras.size(); ++c)
    motions_[c] = trajectoryMotion(cameras, neighbours_[c], static_cast<int>(c), &motion_D_[c]);
}

Eigen::Matrix<double, 6, 1> BundleAdjuster::motionPriorResidual(std::size_t c) const {
  Eigen::Matrix<double, 6, 1> r;
  r.head<3>() = motions_[c].angular;
  r.tail<3>() = motions_[c].linear;
  if (!motion_prior_mean_.empty()) {
    r.head<3>() -= motion_prior_mean_[c].angular;
    r.tail<3>() -= motion_prior_mean_[c].linear;
  }
  return r;
}

double BundleAdjuster::evaluateCost(std::span<const BaCamera> cameras,
                                    std::span<const Eigen::Vector3d> points,
                                    std::span<const BaObservation> observations,
                                    const BaIntrinsics& k, double huber, double* rms) const {
  double cost = 0.0;
  double sq = 0.0;
  const bool rs = !motions_.empty();
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const BaObservation& o = observations[i];
    Eigen::Vector2d uv;
    double tau = 0.0;
    const bool seen =
        rs ? projectRollingShutter(cameras[static_cast<std::size_t>(o.camera)],
                                   motions_[static_cast<std::size_t>(o.camera)], shutter_, k,
                                   points[static_cast<std::size_t>(o.point)], uv, tau, row_[i])
           : project(cameras[static_cast<std::size_t>(o.camera)], k,
                     points[static_cast<std::size_t>(o.point)], uv);
    if (rs) row_[i] = seen ? uv.y() : kNoRow;
    if (!seen) {
      cost += 1e6;  // behind the camera: never an improvement
      sq += 1e6;
      continue;
    }
    const double e = (uv - o.xy).norm();
    cost += huberCost(e, huber);
    sq += e * e;
  }
  if (rms != nullptr)
    *rms = observations.empty() ? 0.0 : std::sqrt(sq / static_cast<double>(observations.size()));
  return rs ? addMotionPriorCost(cost) : cost;
}

double BundleAdjuster::addMotionPriorCost(double cost) const {
  // The motion prior of the free cameras (0.5 |prior x (motion - mean)|^2, as the residuals).
  const double prior2 = velocity_prior_ * velocity_prior_;
  for (std::size_t c = 0; c < motions_.size(); ++c)
    if (camera_slot_[c] >= 0) cost += 0.5 * prior2 * motionPriorResidual(c).squaredNorm();
  return cost;
}

namespace {
bool pointIsFixed(std::span<const uint8_t> points_fixed, int p) {
  return !points_fixed.empty() && points_fixed[static_cast<std::size_t>(p)] != 0;
}
}  // namespace

bool BundleAdjuster::validInput(std::span<const BaCamera> cameras,
                                std::span<const uint8_t> camera_fixed,
                                std::span<const Eigen::Vector3d> points,
                                std::span<const uint8_t> points_fixed,
                                std::span<const BaObservation> observations,
                                const BundleAdjustmentOptions& options) const {
  const auto nc = static_cast<int>(cameras.size());
  const auto np = static_cast<int>(points.size());
  const auto no = static_cast<int>(observations.size());
  if (nc > max_cameras_ || np > max_points_ || no > max_observations_ ||
      camera_fixed.size() != cameras.size() ||
      (!points_fixed.empty() && points_fixed.size() != points.size()) ||
      options.refine_distortion < 0 || options.refine_distortion > 2) {
    return false;
  }
  for (const BaObservation& o : observations) {
    if (o.camera < 0 || o.camera >= nc || o.point < 0 || o.point >= np || !o.xy.allFinite())
      return false;
  }
  return true;
}

BundleAdjuster::Layout BundleAdjuster::buildLayout(std::span<const uint8_t> camera_fixed,
                                                   std::span<const BaObservation> observations,
                                                   int np, const BundleAdjustmentOptions& options) {
  Layout L;
  L.nc = static_cast<int>(camera_fixed.size());
  L.np = np;
  L.no = static_cast<int>(observations.size());
  const int nc = L.nc, no = L.no;
  // Reduced-system layout: 6 per free camera (12 with the rolling shutter's motion), then the
  // intrinsics.
  L.traj = !neighbours_.empty();
  L.rs = !motions_.empty() && !L.traj;
  const int width = L.rs ? 12 : 6;
  int n_free = 0;
  for (int c = 0; c < nc; ++c)
    camera_slot_[static_cast<std::size_t>(c)] =
        camera_fixed[static_cast<std::size_t>(c)] != 0 ? -1 : width * n_free++;
  L.nk = (options.refine_focal ? 1 : 0) + options.refine_distortion;
  L.k0 = width * n_free;  // first intrinsics index
  L.n = L.k0 + L.nk;
  // Which intrinsics columns (f, k1, k2) are refined, in order.
  {
    int j = 0;
    if (options.refine_focal) L.kcol[j++] = 0;
    for (int d = 0; d < options.refine_distortion; ++d) L.kcol[j++] = 1 + d;
    if (L.traj && options.refine_readout) {
      L.kcol[j++] = 3;
      ++L.nk;
      ++L.n;
    }
  }
  // Observations grouped by point (CSR).
  std::fill(point_obs_offset_.begin(), point_obs_offset_.begin() + np + 1, 0);
  for (const BaObservation& o : observations)
    ++point_obs_offset_[static_cast<std::size_t>(o.point) + 1];
  for (int p = 0; p < np; ++p)
    point_obs_offset_[static_cast<std::size_t>(p) + 1] +=
        point_obs_offset_[static_cast<std::size_t>(p)];
  for (int p = 0; p < np; ++p)
    point_obs_cursor_[static_cast<std::size_t>(p)] = point_obs_offset_[static_cast<std::size_t>(p)];
  for (int i = 0; i < no; ++i) {
    const auto p = static_cast<std::size_t>(observations[static_cast<std::size_t>(i)].point);
    point_obs_index_[static_cast<std::size_t>(point_obs_cursor_[p]++)] = i;
  }
  if (L.traj) {
    // Each point's entries: the distinct free slots its observations touch (their cameras and
    // those cameras' neighbours), sorted; each observation's three entries (-1: none or fixed).
    // touchedSlot(i, j): the free slot of observation i's previous (j = 0), own (1) or next (2)
    // camera, -1 when there is none or it is fixed.
    const auto touchedSlot = [&](int i, int j) {
      const int cam = observations[static_cast<std::size_t>(i)].camera;
      const BaTrajectoryNeighbours& nb = neighbours_[static_cast<std::size_t>(cam)];
      const int touched = j == 0 ? nb.previous : (j == 1 ? cam : nb.next);
      return touched < 0 ? -1 : camera_slot_[static_cast<std::size_t>(touched)];
    };
    for (int p = 0; p < np; ++p) {
      const int begin = 3 * point_obs_offset_[static_cast<std::size_t>(p)];
      pair_begin_[static_cast<std::size_t>(p)] = begin;
      int end = begin;
      for (int a = point_obs_offset_[static_cast<std::size_t>(p)];
           a < point_obs_offset_[static_cast<std::size_t>(p) + 1]; ++a) {
        const int i = point_obs_index_[static_cast<std::size_t>(a)];
        // Inserted from the back: a track's observations come in frame order, so a new slot
        // is usually the last (linear in the track's length, not quadratic).
        for (int j = 0; j < 3; ++j) {
          const int slot = touchedSlot(i, j);
          if (slot < 0) continue;
          int e = end;
          while (e > begin && pair_slot_[static_cast<std::size_t>(e - 1)] > slot) --e;
          if (e > begin && pair_slot_[static_cast<std::size_t>(e - 1)] == slot) continue;
          for (int q = end; q > e; --q)
            pair_slot_[static_cast<std::size_t>(q)] = pair_slot_[static_cast<std::size_t>(q - 1)];
          pair_slot_[static_cast<std::size_t>(e)] = slot;
          ++end;
        }
      }
      pair_end_[static_cast<std::size_t>(p)] = end;
      // The entries are final and sorted: each observation's by binary search.
      const auto first = pair_slot_.begin() + begin;
      const auto last = pair_slot_.begin() + end;
      for (int a = point_obs_offset_[static_cast<std::size_t>(p)];
           a < point_obs_offset_[static_cast<std::size_t>(p) + 1]; ++a) {
        const int i = point_obs_index_[static_cast<std::size_t>(a)];
        for (int j = 0; j < 3; ++j) {
          int& entry = obs_entry_[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)];
          const int slot = touchedSlot(i, j);
          entry = slot < 0
                      ? -1
                      : static_cast<int>(std::lower_bound(first, last, slot) - pair_slot_.begin());
        }
      }
    }
    return L;
  }
  // Each point's observations by free cameras, sorted by slot (insertion sort: a few dozen each);
  // with the rolling shutter, a second entry at the camera's motion slot.
  const int entries = L.rs ? 2 : 1;
  for (int p = 0; p < np; ++p) {
    const int begin = entries * point_obs_offset_[static_cast<std::size_t>(p)];
    pair_begin_[static_cast<std::size_t>(p)] = begin;
    int end = begin;
    for (int a = point_obs_offset_[static_cast<std::size_t>(p)];
         a < point_obs_offset_[static_cast<std::size_t>(p) + 1]; ++a) {
      const int i = point_obs_index_[static_cast<std::size_t>(a)];
      const int camera_slot =
          camera_slot_[static_cast<std::size_t>(observations[static_cast<std::size_t>(i)].camera)];
      if (camera_slot < 0) continue;
      for (int entry = 0; entry < entries; ++entry) {
        const int slot = camera_slot + 6 * entry;
        int e = end++;
        for (; e > begin && pair_slot_[static_cast<std::size_t>(e - 1)] > slot; --e) {
          pair_slot_[static_cast<std::size_t>(e)] = pair_slot_[static_cast<std::size_t>(e - 1)];
          pair_obs_[static_cast<std::size_t>(e)] = pair_obs_[static_cast<std::size_t>(e - 1)];
        }
        pair_slot_[static_cast<std::size_t>(e)] = slot;
        pair_obs_[static_cast<std::size_t>(e)] = i;
      }
    }
    pair_end_[static_cast<std::size_t>(p)] = end;
  }
  return L;
}

void BundleAdjuster::linearize(std::span<const BaCamera> cameras,
                               std::span<const Eigen::Vector3d> points,
                               std::span<const BaObservation> observations, const BaIntrinsics& k,
                               const BundleAdjustmentOptions& options, const Layout& L) {
  const int n = L.n, np = L.np, no = L.no, nk = L.nk, k0 = L.k0;
  const int* kcol = L.kcol;
  // -- linearise: U (in S), g_c (in rhs), V, g_p, and the coupling blocks --
  Eigen::MatrixXd& H = S_;
  H.topLeftCorner(n, n).setZero();
  Eigen::VectorXd& g = rhs_;
  g.head(n).setZero();
  for (int p = 0; p < np; ++p) {
    V_[static_cast<std::size_t>(p)].setZero();
    gp_[static_cast<std::size_t>(p)].setZero();
  }
  for (int i = 0; i < no; ++i) {
    const BaObservation& o = observations[static_cast<std::size_t>(i)];
    const auto pi = static_cast<std::size_t>(o.point);
    Eigen::Vector2d uv;
    Eigen::Matrix<double, 2, 6> Jc;
    Eigen::Matrix<double, 2, 6> Jm;
    Eigen::Matrix<double, 2, 3> Jp;
    Eigen::Matrix<double, 2, 3> Jk_all;
    Wc_[static_cast<std::size_t>(i)].setZero();
    Wk_[static_cast<std::size_t>(i)].setZero();
    if (L.rs) {
      Wv_[static_cast<std::size_t>(i)].setZero();
      if (!projectRollingShutterWithJacobians(cameras[static_cast<std::size_t>(o.camera)],
                                              motions_[static_cast<std::size_t>(o.camera)],
                                              shutter_, k, points[pi], uv, Jc, Jm, Jp, Jk_all))
        continue;
    } else if (!projectWithJacobians(cameras[static_cast<std::size_t>(o.camera)], k, points[pi], uv,
                                     Jc, Jp, Jk_all)) {
      continue;
    }
    const Eigen::Vector2d r = uv - o.xy;
    const double w = huberWeight(r.norm(), options.huber_px);
    Eigen::Matrix<double, 2, 3> Jk = Eigen::Matrix<double, 2, 3>::Zero();
    for (int j = 0; j < nk; ++j) Jk.col(j) = Jk_all.col(kcol[j]);
    const int s = camera_slot_[static_cast<std::size_t>(o.camera)];
    if (s >= 0) {
      H.block<6, 6>(s, s) += w * Jc.transpose() * Jc;
      g.segment<6>(s) += w * Jc.transpose() * r;
      Wc_[static_cast<std::size_t>(i)] = w * Jc.transpose() * Jp;
      if (nk > 0) H.block(s, k0, 6, nk) += w * Jc.transpose() * Jk.leftCols(nk);
      if (L.rs) {  // the motion at s + 6: its blocks of the upper triangle
        H.block<6, 6>(s, s + 6) += w * Jc.transpose() * Jm;
        H.block<6, 6>(s + 6, s + 6) += w * Jm.transpose() * Jm;
        g.segment<6>(s + 6) += w * Jm.transpose() * r;
        Wv_[static_cast<std::size_t>(i)] = w * Jm.transpose() * Jp;
        if (nk > 0) H.block(s + 6, k0, 6, nk) += w * Jm.transpose() * Jk.leftCols(nk);
      }
    }
    if (nk > 0) {
      H.block(k0, k0, nk, nk) += w * Jk.leftCols(nk).transpose() * Jk.leftCols(nk);
      g.segment(k0, nk) += w * Jk.leftCols(nk).transpose() * r;
      Wk_[static_cast<std::size_t>(i)].topRows<3>() = w * Jk.transpose() * Jp;
    }
    V_[pi] += w * Jp.transpose() * Jp;
    gp_[pi] += w * Jp.transpose() * r;
  }
  if (L.rs) {  // the motion prior of the free cameras
    const double prior2 = velocity_prior_ * velocity_prior_;
    for (int c = 0; c < L.nc; ++c) {
      const int s = camera_slot_[static_cast<std::size_t>(c)];
      if (s < 0) continue;
      for (int j = 0; j < 6; ++j) H(s + 6 + j, s + 6 + j) += prior2;
      g.segment<6>(s + 6) += prior2 * motionPriorResidual(static_cast<std::size_t>(c));
    }
  }
  // Symmetrise the camera-intrinsics coupling.
  if (nk > 0) {
    for (int c = 0; c < k0; ++c)
      for (int j = 0; j < nk; ++j) H(k0 + j, c) = H(c, k0 + j);
  }
  for (int i = 0; i < n; ++i) diag_(i) = H(i, i);
  for (int p = 0; p < np; ++p) {
    for (int e = pair_begin_[static_cast<std::size_t>(p)];
         e < pair_end_[static_cast<std::size_t>(p)]; ++e) {
      const auto i = static_cast<std::size_t>(pair_obs_[static_cast<std::size_t>(e)]);
      // The pose entry sits at its camera's slot, the motion entry 6 further.
      const bool motion_entry =
          L.rs && pair_slot_[static_cast<std::size_t>(e)] !=
                      camera_slot_[static_cast<std::size_t>(observations[i].camera)];
      pair_Wc_[static_cast<std::size_t>(e)] = motion_entry ? Wv_[i] : Wc_[i];
    }
  }
}

void BundleAdjuster::trajectorySlots(int camera, int slot[3]) const {
  const BaTrajectoryNeighbours& nb = neighbours_[static_cast<std::size_t>(camera)];
  const int touched[3] = {nb.previous, camera, nb.next};
  for (int a = 0; a < 3; ++a)
    slot[a] = touched[a] < 0 ? -1 : camera_slot_[static_cast<std::size_t>(touched[a])];
}

bool BundleAdjuster::trajectoryObservationJacobian(std::span<const BaCamera> cameras,
                                                   std::span<const Eigen::Vector3d> points,
                                                   const BaObservation& o, const BaIntrinsics& k,
                                                   const BundleAdjustmentOptions& options,
                                                   const Layout& L,
                                                   TrajectoryObservationJacobian& out) const {
  const auto ci = static_cast<std::size_t>(o.camera);
  Eigen::Vector2d uv;
  Eigen::Matrix<double, 2, 6> Jc;
  Eigen::Matrix<double, 2, 6> Jm;
  Eigen::Matrix<double, 2, 3> Jk_intr;
  Eigen::Vector2d Jl;
  if (!projectRollingShutterWithJacobians(cameras[ci], motions_[ci], shutter_, k,
                                          points[static_cast<std::size_t>(o.point)], uv, Jc, Jm,
                                          out.Jp, Jk_intr, &Jl))
    return false;
  out.r = uv - o.xy;
  out.w = huberWeight(out.r.norm(), options.huber_px);
  out.Jk.setZero();
  for (int j = 0; j < L.nk; ++j) out.Jk.col(j) = L.kcol[j] == 3 ? Jl : Jk_intr.col(L.kcol[j]);
  // The motion is the trajectory's: its Jacobian goes to the previous, own and next pose.
  const Eigen::Matrix<double, 2, 18> JmD = Jm * motion_D_[ci];
  out.J[0] = JmD.middleCols<6>(0);
  out.J[1] = Jc + JmD.middleCols<6>(6);
  out.J[2] = JmD.middleCols<6>(12);
  trajectorySlots(o.camera, out.slot);
  return true;
}

void BundleAdjuster::linearizeTrajectory(std::span<const BaCamera> cameras,
                                         std::span<const Eigen::Vector3d> points,
                                         std::span<const BaObservation> observations,
                                         const BaIntrinsics& k,
                                         const BundleAdjustmentOptions& options, const Layout& L) {
  const int n = L.n, np = L.np, no = L.no, nk = L.nk, k0 = L.k0;
  Eigen::MatrixXd& H = S_;
  H.topLeftCorner(n, n).setZero();
  Eigen::VectorXd& g = rhs_;
  g.head(n).setZero();
  for (int p = 0; p < np; ++p) {
    gp_[static_cast<std::size_t>(p)].setZero();
    V_[static_cast<std::size_t>(p)].setZero();
    for (int e = pair_begin_[static_cast<std::size_t>(p)];
         e < pair_end_[static_cast<std::size_t>(p)]; ++e)
      pair_Wc_[static_cast<std::size_t>(e)].setZero();
  }
  updateTrajectoryMotions(cameras);
  for (int i = 0; i < no; ++i) {
    const auto ii = static_cast<std::size_t>(i);
    const auto pi = static_cast<std::size_t>(observations[ii].point);
    Wk_[ii].setZero();
    TrajectoryObservationJacobian oj;
    if (!trajectoryObservationJacobian(cameras, points, observations[ii], k, options, L, oj))
      continue;
    const Eigen::Vector2d& r = oj.r;
    const double w = oj.w;
    const auto& J = oj.J;
    const auto& Jk = oj.Jk;
    const auto& Jp = oj.Jp;
    const int* slot = oj.slot;
    for (int a = 0; a < 3; ++a) {
      const int sa = slot[a];
      if (sa < 0) continue;
      g.segment<6>(sa) += w * J[a].transpose() * r;
      pair_Wc_[static_cast<std::size_t>(obs_entry_[ii][static_cast<std::size_t>(a)])] +=
          w * J[a].transpose() * Jp;
      if (nk > 0) H.block(sa, k0, 6, nk) += w * J[a].transpose() * Jk.leftCols(nk);
      for (int b = 0; b < 3; ++b) {  // the upper triangle's blocks
        const int sb = slot[b];
        if (sb < sa) continue;
        H.block<6, 6>(sa, sb) += w * J[a].transpose() * J[b];
      }
    }
    if (nk > 0) {
      H.block(k0, k0, nk, nk) += w * Jk.leftCols(nk).transpose() * Jk.leftCols(nk);
      g.segment(k0, nk) += w * Jk.leftCols(nk).transpose() * r;
      Wk_[ii] = w * Jk.transpose() * Jp;
    }
    V_[pi] += w * Jp.transpose() * Jp;
    gp_[pi] += w * Jp.transpose() * r;
  }
  if (nk > 0) {
    for (int c = 0; c < k0; ++c)
      for (int j = 0; j < nk; ++j) H(k0 + j, c) = H(c, k0 + j);
  }
  for (int i = 0; i < n; ++i) diag_(i) = H(i, i);
}

double BundleAdjuster::trajectoryCostAndGradient(std::span<const BaCamera> cameras,
                                                 std::span<const Eigen::Vector3d> points,
                                                 std::span<const BaObservation> observations,
                                                 const BaIntrinsics& k,
                                                 const BundleAdjustmentOptions& options,
                                                 const Layout& L, double* rms) {
  const int nk = L.nk, k0 = L.k0;
  rhs_.head(L.n).setZero();
  for (int p = 0; p < L.np; ++p) gp_[static_cast<std::size_t>(p)].setZero();
  for (int c = 0; c < L.nc; ++c) {
    camera_gradient_[static_cast<std::size_t>(c)].setZero();
    motion_gradient_[static_cast<std::size_t>(c)].setZero();
  }
  double cost = 0.0;
  double sq = 0.0;
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const BaObservation& o = observations[i];
    const auto ci = static_cast<std::size_t>(o.camera);
    const Eigen::Vector3d& X = points[static_cast<std::size_t>(o.point)];
    Eigen::Vector2d uv;
    double tau = 0.0;
    const bool seen =
        projectRollingShutter(cameras[ci], motions_[ci], shutter_, k, X, uv, tau, row_[i]);
    row_[i] = seen ? uv.y() : kNoRow;
    if (!seen) {
      cost += 1e6;  // as evaluateCost
      sq += 1e6;
      continue;
    }
    const Eigen::Vector2d r = uv - o.xy;
    const double e = r.norm();
    cost += huberCost(e, options.huber_px);
    sq += e * e;
    RollingShutterGradient gr;
    if (!rollingShutterGradient(cameras[ci], motions_[ci], shutter_, k, X, tau,
                                huberWeight(e, options.huber_px) * r, gr))
      continue;
    camera_gradient_[ci] += gr.camera;
    motion_gradient_[ci] += gr.motion;
    for (int j = 0; j < nk; ++j)
      rhs_(k0 + j) += L.kcol[j] == 3 ? gr.line_delay : gr.intrinsics(L.kcol[j]);
    gp_[static_cast<std::size_t>(o.point)] += gr.point;
  }
  // The motion is the trajectory's, linear in its camera's observations' pulls: D^T once per
  // camera onto its previous, own and next pose (trajectoryObservationJacobian).
  for (int c = 0; c < L.nc; ++c) {
    const auto cc = static_cast<std::size_t>(c);
    const Eigen::Matrix<double, 18, 1> gD = motion_D_[cc].transpose() * motion_gradient_[cc];
    int slot[3];
    trajectorySlots(c, slot);
    if (slot[0] >= 0) rhs_.segment<6>(slot[0]) += gD.segment<6>(0);
    if (slot[1] >= 0) rhs_.segment<6>(slot[1]) += camera_gradient_[cc] + gD.segment<6>(6);
    if (slot[2] >= 0) rhs_.segment<6>(slot[2]) += gD.segment<6>(12);
  }
  if (rms != nullptr)
    *rms = observations.empty() ? 0.0 : std::sqrt(sq / static_cast<double>(observations.size()));
  return addMotionPriorCost(cost);
}

bool BundleAdjuster::chordStep(std::span<BaCamera> cameras, std::span<Eigen::Vector3d> points,
                               std::span<const uint8_t> points_fixed,
                               std::span<const BaObservation> observations, BaIntrinsics& k,
                               const BundleAdjustmentOptions& options, const Layout& L,
                               double& cost, double& rms, double& step2) {
  const int n = L.n, np = L.np;
  if (!gradient_current_) trajectoryCostAndGradient(cameras, points, observations, k, options, L);
  formReducedRhs(points_fixed, L);  // with the last form's W and V^-1
  auto dc = delta_.head(n);
  dc = b_.head(n);
  const auto factor = A_.topLeftCorner(n, n).triangularView<Eigen::Lower>();
  factor.solveInPlace(dc);
  factor.transpose().solveInPlace(dc);
  if (!dc.allFinite()) return false;
  step2 = backSubstitute(observations, points_fixed, L);
  // The frozen Hessian may overshoot where the Huber weights moved: the step, then up to three
  // halvings of it (a halved trial is one pass, cheaper than forming the system again).
  constexpr int kChordTrials = 4;
  for (int trial = 0; trial < kChordTrials; ++trial) {
    applyStep(cameras, points, k, L);
    // The trial's cost and, from the same projections, its gradient: the next chord step's.
    double new_rms = 0.0;
    const double new_cost =
        trajectoryCostAndGradient(cameras, points, observations, k, options, L, &new_rms);
    if (std::isfinite(new_cost) && new_cost < cost) {
      cost = new_cost;
      rms = new_rms;
      gradient_current_ = true;
      return true;
    }
    gradient_current_ = false;
    undoStep(cameras, points);
    k = k_backup_;
    if (trial + 1 == kChordTrials) break;  // no step left to try: the caller forms the system
    dc *= 0.5;
    for (int p = 0; p < np; ++p) dp_[static_cast<std::size_t>(p)] *= 0.5;
    step2 *= 0.25;
  }
  return false;
}

bool BundleAdjuster::solveReducedSystem(double lambda, std::span<const uint8_t> points_fixed,
                                        const Layout& L) {
  formReducedSystem(lambda, points_fixed, L);
  // In-place Cholesky (the damped reduced system is positive definite); no allocation.
  auto A = A_.topLeftCorner(L.n, L.n);
  Eigen::Ref<Eigen::MatrixXd> A_ref(A);
  const Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> llt(A_ref);
  auto dc = delta_.head(L.n);
  dc = b_.head(L.n);
  if (llt.info() == Eigen::Success) llt.solveInPlace(dc);
  return llt.info() == Eigen::Success && dc.allFinite();
}

void BundleAdjuster::formReducedSystem(double lambda, std::span<const uint8_t> points_fixed,
                                       const Layout& L) {
  const int n = L.n, np = L.np, nk = L.nk, k0 = L.k0;
  const Eigen::MatrixXd& H = S_;
  // Reduced camera system: (U + lambda D) - sum_p W_p (V_p + lambda D_p)^-1 W_p^T, rebuilt from
  // the undamped blocks at each attempt, in the preallocated A_ / b_.
  auto A = A_.topLeftCorner(n, n);
  A = H.topLeftCorner(n, n);
  for (int i = 0; i < n; ++i) A(i, i) = diag_(i) * (1.0 + lambda) + 1e-12;
  for (int p = 0; p < np; ++p) {
    if (pointIsFixed(points_fixed, p)) continue;
    const auto pp = static_cast<std::size_t>(p);
    Eigen::Matrix3d Vd = V_[pp];
    for (int j = 0; j < 3; ++j) Vd(j, j) = V_[pp](j, j) * (1.0 + lambda) + 1e-12;
    const Eigen::Matrix3d Vinv = Vd.inverse();
    Vinv_[pp] = Vinv;
    const Eigen::Matrix<double, 4, 3> Wk_sum = intrinsicsCoupling(pp);
    const int begin = pair_begin_[pp];
    const int pair_end = pair_end_[pp];
    // Upper triangle (sb >= sa), mirrored below; a camera seen twice pairs with both copies.
    // noalias: the 6x6 products go straight into A, not through a temporary.
    int group = begin;  // first entry of the current slot
    for (int e = begin; e < pair_end; ++e) {
      const auto ee = static_cast<std::size_t>(e);
      const int sa = pair_slot_[ee];
      const Eigen::Matrix<double, 6, 3> WV = pair_Wc_[ee] * Vinv;
      if (nk > 0) A.block(sa, k0, 6, nk) -= (WV * Wk_sum.transpose()).leftCols(nk);
      if (pair_slot_[static_cast<std::size_t>(group)] != sa) group = e;
      for (int f = group; f < pair_end; ++f) {
        const auto ff = static_cast<std::size_t>(f);
        A.block<6, 6>(sa, pair_slot_[ff]).noalias() -= WV * pair_Wc_[ff].transpose();
      }
    }
    if (nk > 0)
      A.block(k0, k0, nk, nk) -= (Wk_sum * Vinv * Wk_sum.transpose()).topLeftCorner(nk, nk);
  }
  // Mirror the upper triangle.
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) A(j, i) = A(i, j);
  formReducedRhs(points_fixed, L);
}

Eigen::Matrix<double, 4, 3> BundleAdjuster::intrinsicsCoupling(std::size_t p) const {
  Eigen::Matrix<double, 4, 3> Wk_sum = Eigen::Matrix<double, 4, 3>::Zero();
  for (int a = point_obs_offset_[p]; a < point_obs_offset_[p + 1]; ++a)
    Wk_sum += Wk_[static_cast<std::size_t>(point_obs_index_[static_cast<std::size_t>(a)])];
  return Wk_sum;
}

void BundleAdjuster::formReducedRhs(std::span<const uint8_t> points_fixed, const Layout& L) {
  const int n = L.n, np = L.np, nk = L.nk, k0 = L.k0;
  // b = -g_c + sum_p W_p V_p^-1 g_p (the points' part of the gradient carried to the cameras).
  auto b = b_.head(n);
  b = -rhs_.head(n);
  for (int p = 0; p < np; ++p) {
    if (pointIsFixed(points_fixed, p)) continue;
    const auto pp = static_cast<std::size_t>(p);
    const Eigen::Vector3d Vg = Vinv_[pp] * gp_[pp];
    for (int e = pair_begin_[pp]; e < pair_end_[pp]; ++e)
      b.segment<6>(pair_slot_[static_cast<std::size_t>(e)]).noalias() +=
          pair_Wc_[static_cast<std::size_t>(e)] * Vg;
    if (nk > 0) b.segment(k0, nk) += (intrinsicsCoupling(pp) * Vg).head(nk);
  }
}

double BundleAdjuster::backSubstitute(std::span<const BaObservation> observations,
                                      std::span<const uint8_t> points_fixed, const Layout& L) {
  const int n = L.n, np = L.np, nk = L.nk, k0 = L.k0;
  const auto dc = delta_.head(n);
  // Back-substitution: dp = V^-1 (-g_p - W^T dc).
  double step2 = dc.squaredNorm();
  for (int p = 0; p < np; ++p) {
    const auto pp = static_cast<std::size_t>(p);
    if (pointIsFixed(points_fixed, p)) {
      dp_[pp].setZero();
      continue;
    }
    Eigen::Vector3d rhs = -gp_[pp];
    if (L.traj) {  // the merged entries, then the intrinsics per observation
      for (int e = pair_begin_[pp]; e < pair_end_[pp]; ++e)
        rhs -= pair_Wc_[static_cast<std::size_t>(e)].transpose() *
               dc.segment<6>(pair_slot_[static_cast<std::size_t>(e)]);
      if (nk > 0)
        for (int a = point_obs_offset_[pp]; a < point_obs_offset_[pp + 1]; ++a)
          rhs -= Wk_[static_cast<std::size_t>(point_obs_index_[static_cast<std::size_t>(a)])]
                     .topRows(nk)
                     .transpose() *
                 dc.segment(k0, nk);
      dp_[pp] = Vinv_[pp] * rhs;
      step2 += dp_[pp].squaredNorm();
      continue;
    }
    for (int a = point_obs_offset_[pp]; a < point_obs_offset_[pp + 1]; ++a) {
      const int ia = point_obs_index_[static_cast<std::size_t>(a)];
      const int sa =
          camera_slot_[static_cast<std::size_t>(observations[static_cast<std::size_t>(ia)].camera)];
      if (sa >= 0) rhs -= Wc_[static_cast<std::size_t>(ia)].transpose() * dc.segment<6>(sa);
      if (sa >= 0 && L.rs)
        rhs -= Wv_[static_cast<std::size_t>(ia)].transpose() * dc.segment<6>(sa + 6);
      if (nk > 0)
        rhs -= Wk_[static_cast<std::size_t>(ia)].topRows(nk).transpose() * dc.segment(k0, nk);
    }
    dp_[pp] = Vinv_[pp] * rhs;
    step2 += dp_[pp].squaredNorm();
  }
  return step2;
}

void BundleAdjuster::applyStep(std::span<BaCamera> cameras, std::span<Eigen::Vector3d> points,
                               BaIntrinsics& k, const Layout& L) {
  const int nc = L.nc, np = L.np, nk = L.nk, k0 = L.k0;
  const int* kcol = L.kcol;
  const auto dc = delta_.head(L.n);
  // Back up, then step.
  for (int c = 0; c < nc; ++c)
    cameras_backup_[static_cast<std::size_t>(c)] = cameras[static_cast<std::size_t>(c)];
  for (int p = 0; p < np; ++p)
    points_backup_[static_cast<std::size_t>(p)] = points[static_cast<std::size_t>(p)];
  k_backup_ = k;
  line_delay_backup_ = shutter_.line_delay;
  if (L.rs)
    for (int c = 0; c < nc; ++c)
      motions_backup_[static_cast<std::size_t>(c)] = motions_[static_cast<std::size_t>(c)];
  for (int c = 0; c < nc; ++c) {
    const int s = camera_slot_[static_cast<std::size_t>(c)];
    if (s < 0) continue;
    BaCamera& cam = cameras[static_cast<std::size_t>(c)];
    // x_c = exp([dtheta]x) R X + t + dt (the parametrisation of the Jacobians).
    cam.R_cw = rodrigues(dc.segment<3>(s)) * cam.R_cw;
    cam.t_cw += dc.segment<3>(s + 3);
    if (L.rs) {
      RollingShutterMotion& m = motions_[static_cast<std::size_t>(c)];
      m.angular += dc.segment<3>(s + 6);
      m.linear += dc.segment<3>(s + 9);
    }
  }
  for (int p = 0; p < np; ++p)
    points[static_cast<std::size_t>(p)] += dp_[static_cast<std::size_t>(p)];
  for (int j = 0; j < nk; ++j) {
    const double v = dc(k0 + j);
    if (kcol[j] == 0) k.f += v;
    if (kcol[j] == 1) k.k1 += v;
    if (kcol[j] == 2) k.k2 += v;
    if (kcol[j] == 3) shutter_.line_delay += v;
  }
  if (L.traj) updateTrajectoryMotions(cameras);
}

void BundleAdjuster::undoStep(std::span<BaCamera> cameras, std::span<Eigen::Vector3d> points) {
  for (std::size_t c = 0; c < cameras.size(); ++c) cameras[c] = cameras_backup_[c];
  for (std::size_t p = 0; p < points.size(); ++p) points[p] = points_backup_[p];
  if (!neighbours_.empty()) {
    shutter_.line_delay = line_delay_backup_;
    updateTrajectoryMotions(cameras);
    return;
  }
  for (std::size_t c = 0; c < motions_.size(); ++c) motions_[c] = motions_backup_[c];
}

BundleAdjustmentSummary BundleAdjuster::solve(std::span<BaCamera> cameras,
                                              std::span<const uint8_t> camera_fixed,
                                              std::span<Eigen::Vector3d> points,
                                              std::span<const uint8_t> points_fixed,
                                              std::span<const BaObservation> observations,
                                              BaIntrinsics& k,
                                              const BundleAdjustmentOptions& options) {
  // The global shutter: the rolling-shutter solve with no readout and no motions.
  return solve(cameras, camera_fixed, points, points_fixed, observations, k, options,
               RollingShutter{}, {});
}

BundleAdjustmentSummary BundleAdjuster::solve(
    std::span<BaCamera> cameras, std::span<const uint8_t> camera_fixed,
    std::span<Eigen::Vector3d> points, std::span<const uint8_t> points_fixed,
    std::span<const BaObservation> observations, BaIntrinsics& k,
    const BundleAdjustmentOptions& options, const RollingShutter& shutter,
    std::span<RollingShutterMotion> motions) {
  motions_ = {};
  if (shutter.line_delay != 0.0 && !motions.empty()) {
    if (capacity_ != BaCapacity::kRollingShutter || motions.size() != cameras.size() ||
        !std::isfinite(shutter.line_delay))
      return {};  // kInvalidInput
    for (const RollingShutterMotion& m : motions)
      if (!m.angular.allFinite() || !m.linear.allFinite()) return {};
    motions_ = motions;
    neighbours_ = {};
    shutter_ = shutter;
    velocity_prior_ = options.velocity_prior;
    motion_prior_mean_ = options.motion_prior_mean;
    if (!motion_prior_mean_.empty() && motion_prior_mean_.size() != motions.size()) return {};
    if (observations.size() <= row_.size())
      std::fill(row_.begin(), row_.begin() + static_cast<std::ptrdiff_t>(observations.size()),
                kNoRow);
  }
  BundleAdjustmentSummary summary =
      solveImpl(cameras, camera_fixed, points, points_fixed, observations, k, options);
  motions_ = {};
  return summary;
}

BundleAdjustmentSummary BundleAdjuster::solveTrajectory(
    std::span<BaCamera> cameras, std::span<const uint8_t> camera_fixed,
    std::span<Eigen::Vector3d> points, std::span<const uint8_t> points_fixed,
    std::span<const BaObservation> observations, BaIntrinsics& k,
    const BundleAdjustmentOptions& options, const RollingShutter& shutter,
    std::span<const BaTrajectoryNeighbours> neighbours, std::span<RollingShutterMotion> motions) {
  if (capacity_ == BaCapacity::kGlobalShutter || motions.size() != cameras.size() ||
      neighbours.size() != cameras.size() || !std::isfinite(shutter.line_delay) ||
      !std::isfinite(shutter.reference_row))
    return {};  // kInvalidInput
  const auto nc = static_cast<int>(cameras.size());
  for (const BaTrajectoryNeighbours& nb : neighbours)
    if (nb.previous < -1 || nb.previous >= nc || nb.next < -1 || nb.next >= nc) return {};
  motions_ = motions;
  neighbours_ = neighbours;
  shutter_ = shutter;
  velocity_prior_ = 0.0;  // no motion parameters
  motion_prior_mean_ = {};
  updateTrajectoryMotions(cameras);
  if (observations.size() <= row_.size())
    std::fill(row_.begin(), row_.begin() + static_cast<std::ptrdiff_t>(observations.size()),
              kNoRow);
  BundleAdjustmentSummary summary =
      solveImpl(cameras, camera_fixed, points, points_fixed, observations, k, options);
  summary.line_delay = shutter_.line_delay;
  motions_ = {};
  neighbours_ = {};
  return summary;
}

BundleAdjustmentSummary BundleAdjuster::solveImpl(std::span<BaCamera> cameras,
                                                  std::span<const uint8_t> camera_fixed,
                                                  std::span<Eigen::Vector3d> points,
                                                  std::span<const uint8_t> points_fixed,
                                                  std::span<const BaObservation> observations,
                                                  BaIntrinsics& k,
                                                  const BundleAdjustmentOptions& options) {
  using Status = BundleAdjustmentSummary::Status;
  BundleAdjustmentSummary summary;
  if (!validInput(cameras, camera_fixed, points, points_fixed, observations, options))
    return summary;
  const Layout L =
      buildLayout(camera_fixed, observations, static_cast<int>(points.size()), options);
  double rms = 0.0;
  double cost = evaluateCost(cameras, points, observations, k, options.huber_px, &rms);
  summary.initial_cost = cost;
  summary.initial_rms_px = rms;
  if (!std::isfinite(cost)) {
    summary.status = Status::kInvalidInput;
    return summary;
  }
  double lambda = options.initial_lambda;
  summary.status = Status::kMaxIterations;
  const auto converged = [&](double decrease, double step2) {
    double scale2 = 0.0;
    for (std::size_t p = 0; p < points.size(); ++p) scale2 += points[p].squaredNorm();
    for (const BaCamera& c : cameras) scale2 += c.t_cw.squaredNorm();
    return decrease < options.function_tolerance ||
           step2 <= options.step_tolerance * options.step_tolerance * (scale2 + 1e-300);
  };
  // A_ holds the Cholesky factor of the last full iteration's reduced system (chord steps).
  bool factor_ready = false;
  gradient_current_ = false;  // rhs_ and gp_ hold no trial's gradient yet
  for (int iter = 0; iter < options.max_iterations; ++iter) {
    summary.iterations = iter + 1;
    if (factor_ready) {
      const double before = cost;
      double step2 = 0.0;
      if (chordStep(cameras, points, points_fixed, observations, k, options, L, cost, rms, step2)) {
        ++summary.chord_steps;
        if (converged((before - cost) / std::max(before, 1e-300), step2)) {
          summary.status = Status::kConverged;
          break;
        }
        continue;
      }
      factor_ready = false;  // the frozen Hessian no longer leads down: a full iteration
    }
    gradient_current_ = false;  // this iteration's step moves away from the gradient's point
    if (L.traj)
      linearizeTrajectory(cameras, points, observations, k, options, L);
    else
      linearize(cameras, points, observations, k, options, L);
    const double grad_norm = rhs_.head(L.n).norm();
    // Damped solves until a step lowers the cost (Levenberg-Marquardt).
    bool accepted = false;
    bool stop = false;
    while (!accepted) {
      if (!solveReducedSystem(lambda, points_fixed, L)) {
        lambda *= 10.0;
        if (lambda > 1e12) {
          summary.status = Status::kNumericalFailure;
          stop = true;
          break;
        }
        continue;
      }
      const double step2 = backSubstitute(observations, points_fixed, L);
      applyStep(cameras, points, k, L);
      // With chord steps to follow, the trial's gradient comes with its cost (the first chord
      // step's); a rejected trial's replaced the linearization point's, recomputed below.
      const bool chords_follow = options.reuse_factorization && L.traj;
      double new_rms = 0.0;
      const double new_cost =
          chords_follow
              ? trajectoryCostAndGradient(cameras, points, observations, k, options, L, &new_rms)
              : evaluateCost(cameras, points, observations, k, options.huber_px, &new_rms);
      if (std::isfinite(new_cost) && new_cost < cost) {
        const double decrease = (cost - new_cost) / std::max(cost, 1e-300);
        cost = new_cost;
        rms = new_rms;
        lambda = std::max(lambda / 3.0, 1e-15);
        accepted = true;
        factor_ready = chords_follow;
        gradient_current_ = chords_follow;
        if (converged(decrease, step2)) {
          summary.status = Status::kConverged;
          stop = true;
        }
      } else {
        undoStep(cameras, points);
        k = k_backup_;
        if (chords_follow) trajectoryCostAndGradient(cameras, points, observations, k, options, L);
        lambda *= 4.0;
        if (lambda > 1e12 || grad_norm < 1e-14) {
          summary.status = Status::kConverged;  // no step improves: at a minimum
          stop = true;
          break;
        }
      }
    }
    if (stop) break;
  }
  summary.final_cost = cost;
  summary.final_rms_px = rms;
  if (L.traj && options.refine_readout)
    lineDelayStdErrors(cameras, points, points_fixed, observations, k, options, L, cost, summary);
  return summary;
}

void BundleAdjuster::lineDelayStdErrors(std::span<const BaCamera> cameras,
                                        std::span<const Eigen::Vector3d> points,
                                        std::span<const uint8_t> points_fixed,
                                        std::span<const BaObservation> observations,
                                        const BaIntrinsics& k,
                                        const BundleAdjustmentOptions& options, const Layout& L,
                                        double cost, BundleAdjustmentSummary& summary) {
  // var = sigma^2 e^T A^-1 e on the reduced system at the minimum (the points eliminated, which
  // is the marginal covariance), A = L L^T: |L^-1 e|^2. A tiny damping keeps the scale's gauge
  // direction (held by nothing else) from making A singular.
  linearizeTrajectory(cameras, points, observations, k, options, L);
  if (!solveReducedSystem(1e-8, points_fixed, L)) return;
  int index = -1;
  for (int j = 0; j < L.nk; ++j)
    if (L.kcol[j] == 3) index = L.k0 + j;
  if (index < 0) return;
  auto z = delta_.head(L.n);
  z.setZero();
  z(index) = 1.0;
  const auto Lfactor = A_.topLeftCorner(L.n, L.n).triangularView<Eigen::Lower>();
  Lfactor.solveInPlace(z);
  const double dof = std::max(1.0, 2.0 * L.no - L.n - 3.0 * L.np);
  const double sigma2 = 2.0 * cost / dof;
  const double independent_variance = sigma2 * z.squaredNorm();
  // That variance assumes every observation's error independent. A tracked feature's error is
  // not: its drift and its corner's bias persist along the track, and on tracked rendered clips
  // the readout scattered 5-7x that error between seeds (issue 27). The cluster-robust sandwich
  // (one cluster per point) measures the scatter of the points' pulls on the readout instead;
  // the larger of the two is reported.
  Lfactor.transpose().solveInPlace(z);  // u = A^-1 e
  const double cluster_variance =
      lineDelayClusterVariance(cameras, points, points_fixed, observations, k, options, L, z);
  summary.line_delay_std_error_independent = std::sqrt(independent_variance);
  summary.line_delay_std_error = std::sqrt(std::max(independent_variance, cluster_variance));
}

double BundleAdjuster::lineDelayClusterVariance(
    std::span<const BaCamera> cameras, std::span<const Eigen::Vector3d> points,
    std::span<const uint8_t> points_fixed, std::span<const BaObservation> observations,
    const BaIntrinsics& k, const BundleAdjustmentOptions& options, const Layout& L,
    const Eigen::Ref<const Eigen::VectorXd>& u) {
  // Point p's pull on the readout: u . h_p, h_p its reduced gradient (its observations' w J^T r
  // on the cameras and intrinsics, its own point eliminated: h_p = g_c,p - W_p V_p^-1 g_p). Along
  // u the observations move by J u and the point answers with dX = -V_p^-1 W_p^T u, so
  // u . h_p = sum w r^T J u - g_p^T V_p^-1 (sum w Jp^T J u).
  double sum = 0.0;
  int clusters = 0;
  for (int p = 0; p < L.np; ++p) {
    const auto pp = static_cast<std::size_t>(p);
    double pull = 0.0;
    Eigen::Vector3d point_response = Eigen::Vector3d::Zero();
    for (int a = point_obs_offset_[pp]; a < point_obs_offset_[pp + 1]; ++a) {
      const BaObservation& o =
          observations[static_cast<std::size_t>(point_obs_index_[static_cast<std::size_t>(a)])];
      TrajectoryObservationJacobian oj;
      if (!trajectoryObservationJacobian(cameras, points, o, k, options, L, oj)) continue;
      Eigen::Vector2d Ju = Eigen::Vector2d::Zero();
      for (int j = 0; j < L.nk; ++j) Ju += oj.Jk.col(j) * u(L.k0 + j);
      for (int c = 0; c < 3; ++c)
        if (oj.slot[c] >= 0) Ju += oj.J[c] * u.segment<6>(oj.slot[c]);
      pull += oj.w * oj.r.dot(Ju);
      point_response += oj.w * oj.Jp.transpose() * Ju;
    }
    if (!pointIsFixed(points_fixed, p)) pull -= gp_[pp].dot(Vinv_[pp] * point_response);
    sum += pull * pull;
    ++clusters;
  }
  return clusters > 1 ? sum * clusters / (clusters - 1.0) : 0.0;
}

namespace {
// The similarity's scaling about `anchor` (the gauge camera's centre), as a step of camera c's
// update (dtheta, dt): X -> anchor + (1 + e)(X - anchor) keeps every projection when
// t -> (1 + e) t + e R anchor, so dtheta = 0 and dt = R (anchor - C) per unit e.
Eigen::Vector3d scalingStep(const BaCamera& c, const Eigen::Vector3d& anchor) {
  return c.R_cw * anchor + c.t_cw;
}
}  // namespace

bool BundleAdjuster::holdScale(std::span<const BaCamera> cameras, const BaCamera& anchor_camera,
                               std::span<const double> undetermined, const Layout& L) {
  // Gauge: with one fixed camera the scale is held by the constraint s^T delta = 0 along the
  // scaling direction s, added as mu s s^T with mu the system's largest diagonal (the
  // covariance is then that of the cameras at a fixed overall scale). Two fixed cameras apart
  // hold the scale themselves.
  const Eigen::Vector3d anchor = -anchor_camera.R_cw.transpose() * anchor_camera.t_cw;
  auto s = b_.head(L.n);
  s.setZero();
  for (std::size_t c = 0; c < cameras.size(); ++c)
    if (camera_slot_[c] >= 0 && undetermined[c] >= 0.0)
      s.segment<3>(camera_slot_[c] + 3) = scalingStep(cameras[c], anchor);
  const double s_norm = s.norm();
  if (!(s_norm > 0.0)) return false;
  s /= s_norm;
  auto A = A_.topLeftCorner(L.n, L.n);
  A.selfadjointView<Eigen::Lower>().rankUpdate(s, A.diagonal().maxCoeff());
  return true;
}

bool BundleAdjuster::centreStandardDeviations(
    std::span<const BaCamera> cameras, std::span<const uint8_t> camera_fixed,
    std::span<const Eigen::Vector3d> points, std::span<const uint8_t> points_fixed,
    std::span<const BaObservation> observations, const BaIntrinsics& k,
    const BundleAdjustmentOptions& options, std::span<double> centre_sd) {
  if (centre_sd.size() != cameras.size() ||
      !validInput(cameras, camera_fixed, points, points_fixed, observations, options))
    return false;
  int anchor_camera = -1;
  int fixed_cameras = 0;
  for (std::size_t c = 0; c < camera_fixed.size(); ++c) {
    if (camera_fixed[c] == 0) continue;
    if (anchor_camera < 0) anchor_camera = static_cast<int>(c);
    ++fixed_cameras;
  }
  if (anchor_camera < 0) return false;
  motions_ = {};
  neighbours_ = {};
  const Layout L =
      buildLayout(camera_fixed, observations, static_cast<int>(points.size()), options);
  if (L.n == 0) return false;
  const double cost = evaluateCost(cameras, points, observations, k, options.huber_px, nullptr);
  linearize(cameras, points, observations, k, options, L);
  // The marginal covariance of the cameras and intrinsics is the inverse of the Schur
  // complement at the minimum (Triggs et al. 2000, §6; the points are eliminated, which
  // marginalises them). Undamped it can be singular to rounding (a point seen twice along
  // nearly one ray): the smallest of a few relative dampings that factors is used (each scales
  // the diagonal by 1 + lambda, so a determined centre's variance changes by about lambda).
  // A free camera without one observation in front of it has no information at all: its
  // centre is undetermined (centre_sd -1), and its rows are set to the identity so that the
  // others can still be measured.
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    const int slot = camera_slot_[c];
    centre_sd[c] = slot >= 0 && diag_.segment<6>(slot).maxCoeff() <= 0.0 ? -1.0 : 0.0;
  }
  bool factored = false;
  for (const double lambda : {1e-9, 1e-6, 1e-3}) {
    formReducedSystem(lambda, points_fixed, L);
    for (std::size_t c = 0; c < cameras.size(); ++c)
      if (centre_sd[c] < 0.0)
        A_.block<6, 6>(camera_slot_[c], camera_slot_[c]) = Eigen::Matrix<double, 6, 6>::Identity();
    if (fixed_cameras == 1 &&
        !holdScale(cameras, cameras[static_cast<std::size_t>(anchor_camera)], centre_sd, L))
      return false;
    auto A = A_.topLeftCorner(L.n, L.n);
    Eigen::Ref<Eigen::MatrixXd> A_ref(A);
    const Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Lower> llt(A_ref);
    factored = llt.info() == Eigen::Success;
    if (factored) break;
  }
  if (!factored) return false;
  const double dof = std::max(1.0, 2.0 * L.no - L.n - 3.0 * L.np);
  const double sigma2 = 2.0 * cost / dof;
  // Centre C = -R^T t; its derivative by the update (dtheta, dt) is [-R^T [t]x, -R^T]. Each
  // row's variance is |L^-1 J^T|^2; J^T is zero before the camera's slot, so the forward
  // substitution starts there.
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    const int slot = camera_slot_[c];
    if (slot < 0 || centre_sd[c] < 0.0) continue;
    const BaCamera& cam = cameras[c];
    Eigen::Matrix<double, 3, 6> J;
    J.leftCols<3>() = -cam.R_cw.transpose() * skewSymmetric(cam.t_cw);
    J.rightCols<3>() = -cam.R_cw.transpose();
    const int m = L.n - slot;
    double variance = 0.0;
    for (int r = 0; r < 3; ++r) {
      auto z = delta_.head(m);
      z.setZero();
      z.head<6>() = J.row(r).transpose();
      A_.block(slot, slot, m, m).triangularView<Eigen::Lower>().solveInPlace(z);
      variance += z.squaredNorm();
    }
    centre_sd[c] = std::sqrt(sigma2 * variance);
  }
  return std::isfinite(sigma2);
}

}  // namespace epitrack

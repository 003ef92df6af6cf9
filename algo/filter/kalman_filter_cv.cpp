#include "algo/filter/kalman_filter_cv.hpp"

#include <Eigen/Dense>

namespace epitrack {

void KalmanFilterCv::init(double x, double y) {
  state_ << x, y, 0.0, 0.0;
  const double r2 = options_.measurement_sigma * options_.measurement_sigma;
  const double v2 = options_.initial_velocity_sigma * options_.initial_velocity_sigma;
  P_.setZero();
  P_.diagonal() << r2, r2, v2, v2;
}

void KalmanFilterCv::predict(double dt) {
  // x' = F x, P' = F P F^T + Q with the discrete white-noise acceleration model
  // Q = q [dt^4/4 I, dt^3/2 I; dt^3/2 I, dt^2 I] (Bar-Shalom et al. 2001 §6.3.3).
  Covariance F = Covariance::Identity();
  F(0, 2) = dt;
  F(1, 3) = dt;
  state_ = F * state_;
  const double q = options_.process_accel_sigma * options_.process_accel_sigma;
  const double dt2 = dt * dt;
  Covariance Q = Covariance::Zero();
  Q(0, 0) = Q(1, 1) = q * dt2 * dt2 / 4.0;
  Q(0, 2) = Q(2, 0) = Q(1, 3) = Q(3, 1) = q * dt2 * dt / 2.0;
  Q(2, 2) = Q(3, 3) = q * dt2;
  P_ = F * P_ * F.transpose() + Q;
}

double KalmanFilterCv::mahalanobis2(double mx, double my) const {
  const double r2 = options_.measurement_sigma * options_.measurement_sigma;
  Eigen::Matrix2d S = P_.topLeftCorner<2, 2>();
  S(0, 0) += r2;
  S(1, 1) += r2;
  const Eigen::Vector2d nu(mx - state_(0), my - state_(1));
  return nu.dot(S.inverse() * nu);
}

void KalmanFilterCv::correct(double mx, double my) {
  const double r2 = options_.measurement_sigma * options_.measurement_sigma;
  Eigen::Matrix2d S = P_.topLeftCorner<2, 2>();
  S(0, 0) += r2;
  S(1, 1) += r2;
  // K = P H^T S^-1 with H = [I 0].
  const Eigen::Matrix<double, 4, 2> K = P_.leftCols<2>() * S.inverse();
  const Eigen::Vector2d nu(mx - state_(0), my - state_(1));
  state_ += K * nu;
  Eigen::Matrix<double, 4, 4> IKH = Covariance::Identity();
  IKH.leftCols<2>() -= K;
  Eigen::Matrix2d R = Eigen::Matrix2d::Identity() * r2;
  P_ = IKH * P_ * IKH.transpose() + K * R * K.transpose();
}

}  // namespace epitrack

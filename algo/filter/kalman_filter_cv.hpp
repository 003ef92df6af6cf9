#pragma once

#include <Eigen/Core>

namespace epitrack {

struct KalmanCvOptions {
  double process_accel_sigma = 0.3;     ///< white-noise acceleration, px / frame^2
  double measurement_sigma = 0.3;       ///< LK position noise, px
  double initial_velocity_sigma = 8.0;  ///< prior on the velocity of a new track, px / frame
  double gate_chi2 = 13.82;             ///< chi-square gate, 2 dof (13.82: 99.9 %)
};

/// Constant-velocity Kalman filter of one image feature (the paper §4.2): state (x, y, vx, vy),
/// transition x' = x + vx dt, position measurement. Gating: the squared Mahalanobis distance of a
/// measurement under the innovation covariance S = H P H^T + R, compared with a chi-square bound.
/// Fixed-size Eigen types only: no allocation.
class KalmanFilterCv {
 public:
  using State = Eigen::Matrix<double, 4, 1>;
  using Covariance = Eigen::Matrix<double, 4, 4>;

  KalmanFilterCv() = default;
  explicit KalmanFilterCv(const KalmanCvOptions& options) : options_(options) {}

  /// Starts at (x, y) with zero velocity and the prior covariance.
  void init(double x, double y);
  /// Time update by dt frames (F = [I dt I; 0 I], Q from the white-noise acceleration model).
  void predict(double dt = 1.0);
  /// Control input (B u): moves the position by (dx, dy) and the velocity by (dvx, dvy), known
  /// changes the filter did not predict (the image motion the camera caused, measured from the
  /// whole frame), leaving the covariance.
  void control(double dx, double dy, double dvx, double dvy) {
    state_(0) += dx;
    state_(1) += dy;
    state_(2) += dvx;
    state_(3) += dvy;
  }
  /// Squared Mahalanobis distance of the measurement (mx, my) from the predicted position.
  [[nodiscard]] double mahalanobis2(double mx, double my) const;
  /// True when the measurement lies inside the chi-square gate.
  [[nodiscard]] bool accepts(double mx, double my) const {
    return mahalanobis2(mx, my) <= options_.gate_chi2;
  }
  /// Measurement update (Joseph form keeps P symmetric positive semi-definite).
  void correct(double mx, double my);

  [[nodiscard]] double x() const { return state_(0); }
  [[nodiscard]] double y() const { return state_(1); }
  [[nodiscard]] double vx() const { return state_(2); }
  [[nodiscard]] double vy() const { return state_(3); }
  [[nodiscard]] const State& state() const { return state_; }
  [[nodiscard]] const Covariance& covariance() const { return P_; }
  [[nodiscard]] const KalmanCvOptions& options() const { return options_; }

 private:
  KalmanCvOptions options_;
  State state_ = State::Zero();
  Covariance P_ = Covariance::Identity();
};

}  // namespace epitrack

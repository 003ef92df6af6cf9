#include <catch2/catch.hpp>

#include <cmath>

#include "algo/filter/kalman_filter_cv.hpp"
#include "algo/math/random.hpp"
#include "tests/support/seeded_random.hpp"

// Unit tests of the per-feature constant-velocity Kalman filter (the paper §4.2) against the
// closed forms of one predict/update step, and of its chi-square gate against the statistics of
// measurements drawn from the filter's own model.

using epitrack::KalmanCvOptions;
using epitrack::KalmanFilterCv;

namespace {

KalmanCvOptions testOptions() {
  KalmanCvOptions o;
  o.process_accel_sigma = 0.5;
  o.measurement_sigma = 0.25;
  o.initial_velocity_sigma = 4.0;
  o.gate_chi2 = 13.82;
  return o;
}

}  // namespace

TEST_CASE("Kalman CV: init and one prediction match the closed form", "[algo][kalman]") {
  const KalmanCvOptions o = testOptions();
  KalmanFilterCv kf(o);
  kf.init(10.0, -3.0);
  const double r2 = o.measurement_sigma * o.measurement_sigma;
  const double v2 = o.initial_velocity_sigma * o.initial_velocity_sigma;
  const double q = o.process_accel_sigma * o.process_accel_sigma;
  CHECK(kf.x() == 10.0);
  CHECK(kf.y() == -3.0);
  CHECK(kf.vx() == 0.0);
  CHECK(kf.covariance()(0, 0) == Approx(r2));
  CHECK(kf.covariance()(2, 2) == Approx(v2));
  CHECK(kf.covariance()(0, 2) == 0.0);

  const double dt = 2.0;
  kf.predict(dt);
  // P' = F P F^T + Q with P = diag(r2, r2, v2, v2), F = [I dt I; 0 I] (per axis, independent).
  const double p00 = r2 + dt * dt * v2 + q * std::pow(dt, 4) / 4.0;
  const double p02 = dt * v2 + q * std::pow(dt, 3) / 2.0;
  const double p22 = v2 + q * dt * dt;
  const auto& P = kf.covariance();
  CHECK(P(0, 0) == Approx(p00).epsilon(1e-12));
  CHECK(P(1, 1) == Approx(p00).epsilon(1e-12));
  CHECK(P(0, 2) == Approx(p02).epsilon(1e-12));
  CHECK(P(2, 0) == Approx(p02).epsilon(1e-12));
  CHECK(P(2, 2) == Approx(p22).epsilon(1e-12));
  CHECK(P(0, 1) == 0.0);  // the axes stay uncorrelated
  CHECK(P(0, 3) == 0.0);
  CHECK(kf.x() == 10.0);  // zero initial velocity: the position does not move
}

TEST_CASE("Kalman CV: Mahalanobis distance, gate and update match the closed form",
          "[algo][kalman]") {
  const KalmanCvOptions o = testOptions();
  KalmanFilterCv kf(o);
  kf.init(0.0, 0.0);
  kf.predict(1.0);
  const double r2 = o.measurement_sigma * o.measurement_sigma;
  const double p00 = kf.covariance()(0, 0);
  const double p02 = kf.covariance()(0, 2);
  const double s = p00 + r2;  // innovation variance per axis
  const double nx = 1.5;
  const double ny = -0.5;
  CHECK(kf.mahalanobis2(nx, ny) == Approx((nx * nx + ny * ny) / s).epsilon(1e-12));
  // The gate's boundary: a measurement at distance sqrt(chi2 * s) along one axis.
  const double edge = std::sqrt(o.gate_chi2 * s);
  CHECK(kf.accepts(edge * 0.999, 0.0));
  CHECK_FALSE(kf.accepts(edge * 1.001, 0.0));

  kf.correct(nx, ny);
  // Scalar gains per axis: k_pos = p00 / s, k_vel = p02 / s; posterior p00 r2 / s.
  CHECK(kf.x() == Approx(nx * p00 / s).epsilon(1e-12));
  CHECK(kf.y() == Approx(ny * p00 / s).epsilon(1e-12));
  CHECK(kf.vx() == Approx(nx * p02 / s).epsilon(1e-12));
  CHECK(kf.vy() == Approx(ny * p02 / s).epsilon(1e-12));
  CHECK(kf.covariance()(0, 0) == Approx(p00 * r2 / s).epsilon(1e-12));
  // The Joseph form keeps P symmetric.
  const auto& P = kf.covariance();
  CHECK((P - P.transpose()).cwiseAbs().maxCoeff() < 1e-15);
}

TEST_CASE("Kalman CV: a constant-velocity track converges to its velocity", "[algo][kalman]") {
  KalmanFilterCv kf(testOptions());
  kf.init(100.0, 50.0);
  for (int t = 1; t <= 30; ++t) {
    kf.predict(1.0);
    const double mx = 100.0 + 2.5 * t;
    const double my = 50.0 - 1.25 * t;
    REQUIRE(kf.accepts(mx, my));
    kf.correct(mx, my);
  }
  CHECK(kf.vx() == Approx(2.5).margin(0.01));
  CHECK(kf.vy() == Approx(-1.25).margin(0.01));
  CHECK(kf.x() == Approx(175.0).margin(0.01));
  // The next prediction lands on the true position.
  kf.predict(1.0);
  CHECK(kf.x() == Approx(177.5).margin(0.02));
}

TEST_CASE("Kalman CV: the gate's chi-square statistics hold on the filter's own model",
          "[algo][kalman]") {
  // Tracks simulated from the filter's model (white-noise acceleration, Gaussian measurement
  // noise): the normalized innovation squared is chi-square with 2 dof, so its mean is 2 and
  // 0.1 % exceed 13.82. Seeded: the counts below are exact on every platform.
  const KalmanCvOptions o = testOptions();
  epitrack::SplitMix64 rng(2026);
  double sum_nis = 0.0;
  int samples = 0;
  int beyond_gate = 0;
  for (int track = 0; track < 400; ++track) {
    KalmanFilterCv kf(o);
    double x = 0.0, y = 0.0, vx = 3.0 * epitrack::test::standardNormal(rng), vy = 0.0;
    kf.init(x + o.measurement_sigma * epitrack::test::standardNormal(rng),
            y + o.measurement_sigma * epitrack::test::standardNormal(rng));
    for (int t = 1; t <= 60; ++t) {
      // Discrete white-noise acceleration, as the filter's Q assumes (dt = 1).
      const double ax = o.process_accel_sigma * epitrack::test::standardNormal(rng);
      const double ay = o.process_accel_sigma * epitrack::test::standardNormal(rng);
      x += vx + 0.5 * ax;
      y += vy + 0.5 * ay;
      vx += ax;
      vy += ay;
      const double mx = x + o.measurement_sigma * epitrack::test::standardNormal(rng);
      const double my = y + o.measurement_sigma * epitrack::test::standardNormal(rng);
      kf.predict(1.0);
      const double nis = kf.mahalanobis2(mx, my);
      if (t > 10) {  // past the prior's transient
        sum_nis += nis;
        ++samples;
        beyond_gate += nis > o.gate_chi2 ? 1 : 0;
      }
      kf.correct(mx, my);
    }
  }
  const double mean_nis = sum_nis / samples;
  const double rate = static_cast<double>(beyond_gate) / samples;
  INFO("mean NIS " << mean_nis << ", beyond the gate " << beyond_gate << " of " << samples);
  CHECK(mean_nis == Approx(2.0).margin(0.1));
  CHECK(rate < 0.003);  // 0.1 % expected; 20 000 samples
  // A measurement 5 sigma of the innovation away is rejected.
  KalmanFilterCv kf(o);
  kf.init(0.0, 0.0);
  kf.predict(1.0);
  const double s = kf.covariance()(0, 0) + o.measurement_sigma * o.measurement_sigma;
  CHECK_FALSE(kf.accepts(5.0 * std::sqrt(s), 0.0));
}

#include "algo/sfm/bundle_adjustment.hpp"

#include <catch2/catch.hpp>

#include <cmath>

#include <Eigen/Geometry>

#include "tools/synth/random.hpp"

using epitrack::BaCamera;
using epitrack::BaIntrinsics;
using epitrack::BaObservation;
using epitrack::BundleAdjuster;
using epitrack::BundleAdjustmentOptions;
using Status = epitrack::BundleAdjustmentSummary::Status;

namespace {

struct Problem {
  std::vector<BaCamera> cameras;
  std::vector<Eigen::Vector3d> points;
  std::vector<BaObservation> obs;
  BaIntrinsics k;
};

// Cameras on an arc looking at a cloud of points around the origin; exact observations plus noise.
Problem makeProblem(int n_cams, int n_points, double noise_px, uint64_t seed, double k1 = 0.0,
                    double k2 = 0.0, double spread = 2.0, double arc = 0.6) {
  epitrack::synth::SplitMix64 rng(seed);
  Problem pr;
  pr.k = BaIntrinsics{600.0, 1.0, 351.5, 287.5, k1, k2};
  // One draw per statement, in the order x86-64 evaluated the former one-expression form
  // (tests/support/seeded_random.hpp), so the problems are the same on aarch64.
  for (int i = 0; i < n_points; ++i) {
    const double z = rng.uniform(-1, 1);
    const double y = rng.uniform(-spread, spread);
    const double x = rng.uniform(-spread, spread);
    pr.points.emplace_back(x, y, z);
  }
  for (int c = 0; c < n_cams; ++c) {
    const double a = -arc + 2.0 * arc * c / std::max(1, n_cams - 1);
    const Eigen::Vector3d eye(8.0 * std::sin(a), 1.0 * std::cos(3 * a), -8.0 * std::cos(a));
    const Eigen::Vector3d f = (-eye).normalized();
    const Eigen::Vector3d r = Eigen::Vector3d::UnitY().cross(f).normalized();
    Eigen::Matrix3d R_wc;
    R_wc.col(0) = r;
    R_wc.col(1) = f.cross(r);
    R_wc.col(2) = f;
    BaCamera cam;
    cam.R_cw = R_wc.transpose();
    cam.t_cw = -cam.R_cw * eye;
    pr.cameras.push_back(cam);
  }
  for (int c = 0; c < n_cams; ++c) {
    for (int i = 0; i < n_points; ++i) {
      Eigen::Vector2d uv;
      if (!BundleAdjuster::project(pr.cameras[static_cast<std::size_t>(c)], pr.k,
                                   pr.points[static_cast<std::size_t>(i)], uv))
        continue;
      const double ny = rng.gaussian();
      const double nx = rng.gaussian();
      uv += noise_px * Eigen::Vector2d(nx, ny);
      pr.obs.push_back({c, i, uv});
    }
  }
  return pr;
}

double maxPointError(const Problem& a, const Problem& b) {
  double e = 0;
  for (std::size_t i = 0; i < a.points.size(); ++i)
    e = std::max(e, (a.points[i] - b.points[i]).norm());
  return e;
}

}  // namespace

TEST_CASE("Analytic BA Jacobians match central differences", "[sfm][ba]") {
  epitrack::synth::SplitMix64 rng(5);
  for (int trial = 0; trial < 50; ++trial) {
    BaCamera c;
    const double axis_y = rng.uniform(-1, 1);
    const double axis_x = rng.uniform(-1, 1);
    const double angle = rng.uniform(-1, 1);
    c.R_cw = Eigen::AngleAxisd(angle, Eigen::Vector3d(axis_x, axis_y, 1).normalized())
                 .toRotationMatrix();
    const double ty = rng.uniform(-1, 1);
    const double tx = rng.uniform(-1, 1);
    c.t_cw = Eigen::Vector3d(tx, ty, 5.0);
    const double z = rng.uniform(-1, 1);
    const double y = rng.uniform(-1, 1);
    const double x = rng.uniform(-1, 1);
    const Eigen::Vector3d X(x, y, z);
    // A braced list is evaluated left to right on every platform.
    BaIntrinsics k{rng.uniform(300, 900),  rng.uniform(0.95, 1.05), 320, 240,
                   rng.uniform(-0.3, 0.3), rng.uniform(-0.1, 0.1)};
    Eigen::Vector2d uv;
    Eigen::Matrix<double, 2, 6> Jc;
    Eigen::Matrix<double, 2, 3> Jp;
    Eigen::Matrix<double, 2, 3> Jk;
    REQUIRE(BundleAdjuster::projectWithJacobians(c, k, X, uv, Jc, Jp, Jk));
    const double h = 1e-6;
    for (int j = 0; j < 6; ++j) {
      BaCamera cp = c;
      BaCamera cm = c;
      Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
      d(j) = h;
      const auto apply = [](BaCamera& cam, const Eigen::Matrix<double, 6, 1>& dd) {
        const Eigen::Vector3d w = dd.head<3>();
        if (w.norm() > 0)
          cam.R_cw = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix() * cam.R_cw;
        cam.t_cw += dd.tail<3>();
      };
      apply(cp, d);
      apply(cm, -d);
      Eigen::Vector2d up;
      Eigen::Vector2d um;
      BundleAdjuster::project(cp, k, X, up);
      BundleAdjuster::project(cm, k, X, um);
      const Eigen::Vector2d num = (up - um) / (2 * h);
      REQUIRE((num - Jc.col(j)).norm() < 1e-5 * (1 + Jc.col(j).norm()));
    }
    for (int j = 0; j < 3; ++j) {
      Eigen::Vector3d d = Eigen::Vector3d::Zero();
      d(j) = h;
      Eigen::Vector2d up;
      Eigen::Vector2d um;
      BundleAdjuster::project(c, k, X + d, up);
      BundleAdjuster::project(c, k, X - d, um);
      REQUIRE(((up - um) / (2 * h) - Jp.col(j)).norm() < 1e-5 * (1 + Jp.col(j).norm()));
    }
    for (int j = 0; j < 3; ++j) {
      BaIntrinsics kp = k;
      BaIntrinsics km = k;
      double* fp = j == 0 ? &kp.f : (j == 1 ? &kp.k1 : &kp.k2);
      double* fm = j == 0 ? &km.f : (j == 1 ? &km.k1 : &km.k2);
      *fp += h;
      *fm -= h;
      Eigen::Vector2d up;
      Eigen::Vector2d um;
      BundleAdjuster::project(c, kp, X, up);
      BundleAdjuster::project(c, km, X, um);
      REQUIRE(((up - um) / (2 * h) - Jk.col(j)).norm() < 1e-5 * (1 + Jk.col(j).norm()));
    }
  }
}

TEST_CASE("BA recovers perturbed cameras and points exactly without noise", "[sfm][ba]") {
  const Problem truth = makeProblem(8, 120, 0.0, 11);
  Problem p = truth;
  epitrack::synth::SplitMix64 rng(3);
  for (std::size_t c = 1; c + 1 < p.cameras.size(); ++c) {
    p.cameras[c].R_cw =
        Eigen::AngleAxisd(0.02, Eigen::Vector3d(rng.uniform(-1, 1), 1, 0).normalized()) *
        p.cameras[c].R_cw;
    const double dz = rng.uniform(-0.1, 0.1);
    const double dy = rng.uniform(-0.1, 0.1);
    const double dx = rng.uniform(-0.1, 0.1);
    p.cameras[c].t_cw += Eigen::Vector3d(dx, dy, dz);
  }
  for (auto& X : p.points) {
    const double dz = rng.uniform(-0.05, 0.05);
    const double dy = rng.uniform(-0.05, 0.05);
    const double dx = rng.uniform(-0.05, 0.05);
    X += Eigen::Vector3d(dx, dy, dz);
  }
  std::vector<uint8_t> fixed(p.cameras.size(), 0);
  fixed.front() = 1;  // first and last fixed: the gauge (including scale) is determined
  fixed.back() = 1;
  BundleAdjuster ba(16, 200, 2000);
  BundleAdjustmentOptions o;
  o.max_iterations = 50;
  const auto s = ba.solve(p.cameras, fixed, p.points, {}, p.obs, p.k, o);
  INFO("rms " << s.initial_rms_px << " -> " << s.final_rms_px << " in " << s.iterations
              << " iterations");
  REQUIRE(s.status == Status::kConverged);
  REQUIRE(s.initial_rms_px > 5.0);
  REQUIRE(s.final_rms_px < 1e-6);
  REQUIRE(maxPointError(p, truth) < 1e-6);
  for (std::size_t c = 0; c < p.cameras.size(); ++c) {
    REQUIRE((p.cameras[c].R_cw - truth.cameras[c].R_cw).norm() < 1e-8);
    REQUIRE((p.cameras[c].t_cw - truth.cameras[c].t_cw).norm() < 1e-7);
  }
}

TEST_CASE("BA estimates the shared focal length and radial distortion", "[sfm][ba]") {
  // Points filling the field of view (normalized radius up to ~0.6), so k2 is observable too.
  const Problem truth = makeProblem(10, 300, 0.3, 21, -0.12, 0.03, 4.5);
  Problem p = truth;
  p.k.f *= 1.04;
  p.k.k1 = 0.0;
  p.k.k2 = 0.0;
  std::vector<uint8_t> fixed(p.cameras.size(), 0);
  fixed.front() = 1;
  fixed.back() = 1;
  BundleAdjuster ba(16, 300, 3000);
  BundleAdjustmentOptions o;
  o.max_iterations = 100;
  o.refine_focal = true;
  o.refine_distortion = 2;
  const auto s = ba.solve(p.cameras, fixed, p.points, {}, p.obs, p.k, o);
  INFO("f " << p.k.f << " k1 " << p.k.k1 << " k2 " << p.k.k2 << " rms " << s.final_rms_px);
  REQUIRE(s.final_rms_px < 0.3 * std::sqrt(2.0));  // at the noise level (0.3 px per axis)
  REQUIRE(p.k.f == Approx(600.0).epsilon(0.002));
  REQUIRE(p.k.k1 == Approx(-0.12).epsilon(0.05));
  REQUIRE(std::abs(p.k.k2 - 0.03) < 0.015);
}

TEST_CASE("Huber loss keeps gross outliers from dragging the solution", "[sfm][ba]") {
  const Problem truth = makeProblem(8, 150, 0.0, 31);
  Problem p = truth;
  epitrack::synth::SplitMix64 rng(8);
  for (std::size_t i = 0; i < p.obs.size(); i += 23) {
    const double dy = rng.uniform(-40, 40);
    const double dx = rng.uniform(20, 40);
    p.obs[i].xy += Eigen::Vector2d(dx, dy);
  }
  for (auto& X : p.points) X += Eigen::Vector3d(0.02, -0.02, 0.01);
  std::vector<uint8_t> fixed(p.cameras.size(), 0);
  fixed.front() = 1;
  fixed.back() = 1;
  BundleAdjuster ba(16, 200, 2000);
  BundleAdjustmentOptions robust;
  robust.max_iterations = 100;
  robust.huber_px = 1.0;
  Problem a = p;
  ba.solve(a.cameras, fixed, a.points, {}, a.obs, a.k, robust);
  BundleAdjustmentOptions plain = robust;
  plain.huber_px = 0.0;
  Problem b = p;
  ba.solve(b.cameras, fixed, b.points, {}, b.obs, b.k, plain);
  const double robust_err = maxPointError(a, truth);
  const double plain_err = maxPointError(b, truth);
  INFO("max point error: Huber " << robust_err << ", least squares " << plain_err);
  REQUIRE(robust_err < 0.5 * plain_err);
}

TEST_CASE("BA refuses invalid input instead of producing NaN", "[sfm][ba]") {
  Problem p = makeProblem(3, 10, 0.0, 1);
  std::vector<uint8_t> fixed(3, 0);
  fixed[0] = 1;
  BundleAdjuster ba(2, 100, 1000);  // too few cameras for the problem
  BundleAdjustmentOptions o;
  REQUIRE(ba.solve(p.cameras, fixed, p.points, {}, p.obs, p.k, o).status == Status::kInvalidInput);
  BundleAdjuster ok(8, 100, 1000);
  p.obs[0].point = 99;
  REQUIRE(ok.solve(p.cameras, fixed, p.points, {}, p.obs, p.k, o).status == Status::kInvalidInput);
  p.obs[0].point = 0;
  p.obs[1].xy.x() = std::nan("");
  REQUIRE(ok.solve(p.cameras, fixed, p.points, {}, p.obs, p.k, o).status == Status::kInvalidInput);
}

namespace {

// Camera c's centre, -R^T t.
Eigen::Vector3d centreOf(const BaCamera& c) { return -c.R_cw.transpose() * c.t_cw; }

// The RMS of the free centres' standard deviations in percent of the path (Solver's measure).
double centreSdPercent(const Problem& p, const std::vector<double>& sd) {
  double path = 0.0, sum = 0.0;
  int n = 0;
  for (std::size_t c = 0; c < p.cameras.size(); ++c) {
    if (c > 0) path += (centreOf(p.cameras[c]) - centreOf(p.cameras[c - 1])).norm();
    if (sd[c] > 0.0) {
      sum += sd[c] * sd[c];
      ++n;
    }
  }
  return 100.0 * std::sqrt(sum / n) / path;
}

}  // namespace

TEST_CASE("BA centre standard deviations match the scatter of repeated noisy solves", "[sfm][ba]") {
  // First and last cameras fixed (they hold the scale): the linearised marginal covariance of a
  // middle camera's centre against the RMS error of that centre over 40 noise draws.
  const Problem truth = makeProblem(8, 60, 0.0, 11);
  constexpr std::size_t kCamera = 4;
  constexpr int kTrials = 40;
  std::vector<uint8_t> fixed(truth.cameras.size(), 0);
  fixed.front() = fixed.back() = 1;
  BundleAdjuster ba(16, 200, 2000);
  BundleAdjustmentOptions o;
  o.huber_px = 0.0;
  o.max_iterations = 20;
  double sum_err2 = 0.0, sum_var = 0.0;
  for (int t = 0; t < kTrials; ++t) {
    Problem p = makeProblem(8, 60, 0.5, 100 + static_cast<uint64_t>(t));
    p.cameras = truth.cameras;
    p.points = truth.points;
    REQUIRE(ba.solve(p.cameras, fixed, p.points, {}, p.obs, p.k, o).status == Status::kConverged);
    std::vector<double> sd(p.cameras.size(), -1.0);
    REQUIRE(ba.centreStandardDeviations(p.cameras, fixed, p.points, {}, p.obs, p.k, o, sd));
    CHECK(sd.front() == 0.0);
    CHECK(sd.back() == 0.0);
    sum_err2 += (centreOf(p.cameras[kCamera]) - centreOf(truth.cameras[kCamera])).squaredNorm();
    sum_var += sd[kCamera] * sd[kCamera];
  }
  const double empirical = std::sqrt(sum_err2 / kTrials);
  const double predicted = std::sqrt(sum_var / kTrials);
  INFO("empirical " << empirical << " predicted " << predicted);
  CHECK(predicted > 0.0);
  CHECK(predicted == Approx(empirical).epsilon(0.25));
}

TEST_CASE("BA centre uncertainty relative to the path separates a wide arc from a short walk",
          "[sfm][ba]") {
  // One fixed camera (the solver's gauge; the scale held by the constraint). A wide arc (the
  // cameras travel 9.5 units around a cloud 8 units away) determines its centres to a small
  // fraction of the path; a short walk (0.16 units, the same rotation of view) does not, as in
  // a fast pan that travels little.
  BundleAdjuster ba(16, 200, 2000);
  BundleAdjustmentOptions o;
  const auto measure = [&](double arc) {
    Problem p = makeProblem(8, 120, 1.0, 7, 0.0, 0.0, 2.0, arc);
    std::vector<uint8_t> fixed(p.cameras.size(), 0);
    fixed.front() = 1;
    ba.solve(p.cameras, fixed, p.points, {}, p.obs, p.k, o);
    std::vector<double> sd(p.cameras.size(), 0.0);
    REQUIRE(ba.centreStandardDeviations(p.cameras, fixed, p.points, {}, p.obs, p.k, o, sd));
    return centreSdPercent(p, sd);
  };
  const double wide = measure(0.6);
  const double short_walk = measure(0.01);
  INFO("wide " << wide << " %, short walk " << short_walk << " %");
  CHECK(wide < 0.5);
  CHECK(short_walk > 10.0 * wide);
  CHECK(short_walk > 3.0);
}

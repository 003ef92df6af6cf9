// The smooth-trajectory rolling-shutter adjustment (BundleAdjuster::solveTrajectory, issue 27):
// the trajectory motion's derivative and the line delay's Jacobian against central differences,
// and the readout estimated as one parameter on a scene rendered row by row from a closed-form
// camera path (each row at its own pose, not the constant-velocity model the adjustment uses).
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <vector>

#include <Eigen/Geometry>

#include "algo/sfm/bundle_adjustment.hpp"
#include "tools/synth/random.hpp"

using epitrack::BaCamera;
using epitrack::BaIntrinsics;
using epitrack::BaObservation;
using epitrack::BaTrajectoryNeighbours;
using epitrack::BundleAdjuster;
using epitrack::BundleAdjustmentOptions;
using epitrack::RollingShutter;
using epitrack::RollingShutterMotion;
using Status = epitrack::BundleAdjustmentSummary::Status;

namespace {

constexpr int kRows = 480;
constexpr double kReferenceRow = 0.5 * (kRows - 1);

Eigen::Matrix3d rotationOf(const Eigen::Vector3d& w) {
  return w.norm() > 0 ? Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix()
                      : Eigen::Matrix3d::Identity();
}

// The camera at time t (frame intervals): on an arc around the origin at 1 deg per frame, with a
// vertical bob and a roll wobble, looking at a point that wanders; smooth in t.
BaCamera cameraAt(double t) {
  const double a = 0.0175 * t;
  const Eigen::Vector3d eye(8.0 * std::sin(a), 0.4 * std::sin(0.15 * t), -8.0 * std::cos(a));
  const Eigen::Vector3d target(0.3 * std::sin(0.11 * t), 0.2 * std::cos(0.07 * t), 0.0);
  const Eigen::Vector3d f = (target - eye).normalized();
  const Eigen::Vector3d r = Eigen::Vector3d::UnitY().cross(f).normalized();
  Eigen::Matrix3d R_wc;
  R_wc.col(0) = r;
  R_wc.col(1) = f.cross(r);
  R_wc.col(2) = f;
  R_wc = R_wc * rotationOf(Eigen::Vector3d(0, 0, 0.01 * std::sin(0.2 * t)));
  BaCamera cam;
  cam.R_cw = R_wc.transpose();
  cam.t_cw = -cam.R_cw * eye;
  return cam;
}

struct Scene {
  std::vector<BaCamera> cameras;
  std::vector<BaTrajectoryNeighbours> neighbours;
  std::vector<Eigen::Vector3d> points;
  std::vector<BaObservation> obs;
  BaIntrinsics k{500.0, 1.0, 319.5, kReferenceRow, 0.0, 0.0};
};

// `frames` consecutive frames, `readout` frame intervals from row 0 to the last; each point seen
// on the row whose exposure time's pose projects it there (iterated to 1e-10 px), plus noise:
// independent per observation (`noise_px`) and drifting along each track, a random walk of
// `drift_px` per frame (a tracker's error persists from frame to frame).
Scene renderScene(int frames, double readout, double noise_px, uint64_t seed,
                  double drift_px = 0.0) {
  epitrack::synth::SplitMix64 rng(seed);
  Scene s;
  for (int i = 0; i < 300; ++i) {
    const double z = rng.uniform(-3, 3);
    const double y = rng.uniform(-2, 2);
    const double x = rng.uniform(-3, 3);
    s.points.emplace_back(x, y, z);
  }
  const double line_delay = readout / (kRows - 1);
  std::vector<Eigen::Vector2d> drift(s.points.size(), Eigen::Vector2d::Zero());
  for (int f = 0; f < frames; ++f) {
    s.cameras.push_back(cameraAt(f));
    BaTrajectoryNeighbours nb;
    nb.previous = f > 0 ? f - 1 : -1;
    nb.next = f + 1 < frames ? f + 1 : -1;
    s.neighbours.push_back(nb);
    for (std::size_t i = 0; i < s.points.size(); ++i) {
      Eigen::Vector2d uv;
      if (!BundleAdjuster::project(s.cameras.back(), s.k, s.points[i], uv)) continue;
      bool settled = false;
      for (int step = 0; step < 50 && !settled; ++step) {
        Eigen::Vector2d next;
        if (!BundleAdjuster::project(cameraAt(f + line_delay * (uv.y() - kReferenceRow)), s.k,
                                     s.points[i], next))
          break;
        settled = std::fabs(next.y() - uv.y()) < 1e-10;
        uv = next;
      }
      if (!settled || uv.x() < 0 || uv.y() < 0 || uv.x() > 639 || uv.y() > kRows - 1) continue;
      const double ny = rng.gaussian();
      const double nx = rng.gaussian();
      const double dy = rng.gaussian();
      const double dx = rng.gaussian();
      drift[i] += drift_px * Eigen::Vector2d(dx, dy);
      s.obs.push_back({f, static_cast<int>(i), uv + drift[i] + noise_px * Eigen::Vector2d(nx, ny)});
    }
  }
  return s;
}

}  // namespace

TEST_CASE(
    "Smooth-trajectory BA: the motion's derivative and the line delay's Jacobian match "
    "central differences",
    "[sfm][ba][rs]") {
  epitrack::synth::SplitMix64 rng(5);
  for (int trial = 0; trial < 20; ++trial) {
    const double t0 = rng.uniform(0, 100);
    std::vector<BaCamera> cams = {cameraAt(t0 - 1.3), cameraAt(t0), cameraAt(t0 + 0.9)};
    // Shaky: each pose turned by up to 3 deg more.
    for (auto& c : cams) {
      const double z = rng.uniform(-0.05, 0.05);
      const double y = rng.uniform(-0.05, 0.05);
      const double x = rng.uniform(-0.05, 0.05);
      c.R_cw = rotationOf(Eigen::Vector3d(x, y, z)) * c.R_cw;
    }
    for (int shape = 0; shape < 3; ++shape) {  // both neighbours, the next only, the previous only
      BaTrajectoryNeighbours nb{shape == 1 ? -1 : 0, shape == 2 ? -1 : 2};
      Eigen::Matrix<double, 6, 18> D;
      BundleAdjuster::trajectoryMotion(cams, nb, 1, &D);
      const double h = 1e-6;
      for (int which = 0; which < 3; ++which) {
        for (int j = 0; j < 6; ++j) {
          const auto moved = [&](double d) {
            std::vector<BaCamera> m = cams;
            BaCamera& c = m[static_cast<std::size_t>(which)];
            if (j < 3)
              c.R_cw = rotationOf(Eigen::Vector3d::Unit(j) * d) * c.R_cw;
            else
              c.t_cw(j - 3) += d;
            const RollingShutterMotion r = BundleAdjuster::trajectoryMotion(m, nb, 1, nullptr);
            Eigen::Matrix<double, 6, 1> v;
            v << r.angular, r.linear;
            return v;
          };
          const Eigen::Matrix<double, 6, 1> numeric = (moved(h) - moved(-h)) / (2 * h);
          const Eigen::Matrix<double, 6, 1> analytic = D.col(6 * which + j);
          INFO("shape " << shape << " camera " << which << " column " << j);
          CHECK((numeric - analytic).norm() < 1e-6 * (1 + analytic.norm()));
        }
      }
    }
    // The line delay's column of the row-solved projection.
    const RollingShutterMotion m = BundleAdjuster::trajectoryMotion(cams, {0, 2}, 1, nullptr);
    const BaIntrinsics k{rng.uniform(400, 700), 1.0, 319.5, kReferenceRow, -0.1, 0.02};
    const RollingShutter rs = RollingShutter::fromReadout(0.9, kRows, kReferenceRow);
    const Eigen::Vector3d X(rng.uniform(-2, 2), rng.uniform(-1, 1), rng.uniform(-2, 2));
    Eigen::Vector2d uv, Jl;
    Eigen::Matrix<double, 2, 6> Jc, Jm;
    Eigen::Matrix<double, 2, 3> Jp, Jk;
    REQUIRE(BundleAdjuster::projectRollingShutterWithJacobians(cams[1], m, rs, k, X, uv, Jc, Jm, Jp,
                                                               Jk, &Jl));
    const double h = 1e-9;
    RollingShutter plus = rs, minus = rs;
    plus.line_delay += h;
    minus.line_delay -= h;
    Eigen::Vector2d up, um;
    double tau = 0.0;
    REQUIRE(BundleAdjuster::projectRollingShutter(cams[1], m, plus, k, X, up, tau));
    REQUIRE(BundleAdjuster::projectRollingShutter(cams[1], m, minus, k, X, um, tau));
    const Eigen::Vector2d numeric = (up - um) / (2 * h);
    CHECK((numeric - Jl).norm() < 1e-5 * (1 + Jl.norm()));
    // The reverse-mode gradient (the chord steps' linearization) is J^T v of these Jacobians.
    const Eigen::Vector2d v(rng.uniform(-2, 2), rng.uniform(-2, 2));
    REQUIRE(BundleAdjuster::projectRollingShutter(cams[1], m, rs, k, X, uv, tau));
    BundleAdjuster::RollingShutterGradient g;
    REQUIRE(BundleAdjuster::rollingShutterGradient(cams[1], m, rs, k, X, tau, v, g));
    const auto close = [](const auto& a, const auto& b) {
      return (a - b).norm() < 1e-9 * (1 + b.norm());
    };
    CHECK(close(g.camera, Jc.transpose() * v));
    CHECK(close(g.motion, Jm.transpose() * v));
    CHECK(close(g.point, Jp.transpose() * v));
    CHECK(close(g.intrinsics, Jk.transpose() * v));
    CHECK(std::fabs(g.line_delay - Jl.dot(v)) < 1e-9 * (1 + std::fabs(Jl.dot(v))));
  }
}

namespace {

struct ReadoutRun {
  double readout = 0.0;
  double std_error = 0.0;
  double std_error_independent = 0.0;
  double max_angle_deg = 0.0;
  double rms = 0.0;
};

// The truth perturbed (a global-shutter solve's error: ~0.2 deg, ~1 cm), the first two cameras
// kept (the gauge, scale included).
Scene perturbed(const Scene& truth) {
  Scene s = truth;
  epitrack::synth::SplitMix64 rng(8);
  for (std::size_t c = 2; c < s.cameras.size(); ++c) {
    const double rz = rng.uniform(-0.003, 0.003);
    const double ry = rng.uniform(-0.003, 0.003);
    const double rx = rng.uniform(-0.003, 0.003);
    s.cameras[c].R_cw = rotationOf(Eigen::Vector3d(rx, ry, rz)) * s.cameras[c].R_cw;
    const double tz = rng.uniform(-0.01, 0.01);
    const double ty = rng.uniform(-0.01, 0.01);
    const double tx = rng.uniform(-0.01, 0.01);
    s.cameras[c].t_cw += Eigen::Vector3d(tx, ty, tz);
  }
  return s;
}

ReadoutRun estimate(double true_readout, uint64_t seed = 17, double noise_px = 0.3,
                    double drift_px = 0.0) {
  const Scene truth = renderScene(60, true_readout, noise_px, seed, drift_px);
  // The first two cameras fixed; the readout starts at half a frame.
  Scene s = perturbed(truth);
  std::vector<uint8_t> fixed(s.cameras.size(), 0);
  fixed[0] = fixed[1] = 1;
  BundleAdjuster ba(static_cast<int>(s.cameras.size()), static_cast<int>(s.points.size()),
                    static_cast<int>(s.obs.size()), epitrack::BaCapacity::kSmoothTrajectory);
  BundleAdjustmentOptions o;
  o.huber_px = 0.0;
  o.refine_readout = true;
  std::vector<RollingShutterMotion> motions(s.cameras.size());
  const auto summary = ba.solveTrajectory(s.cameras, fixed, s.points, {}, s.obs, s.k, o,
                                          RollingShutter::fromReadout(0.5, kRows, kReferenceRow),
                                          s.neighbours, motions);
  REQUIRE(summary.status == Status::kConverged);
  ReadoutRun r;
  r.readout = summary.line_delay * (kRows - 1);
  r.std_error = summary.line_delay_std_error * (kRows - 1);
  r.std_error_independent = summary.line_delay_std_error_independent * (kRows - 1);
  r.rms = summary.final_rms_px;
  for (std::size_t c = 2; c < s.cameras.size(); ++c)
    r.max_angle_deg =
        std::max(r.max_angle_deg,
                 Eigen::AngleAxisd(s.cameras[c].R_cw * truth.cameras[c].R_cw.transpose()).angle() *
                     180 / M_PI);
  return r;
}

}  // namespace

// The chord steps (BundleAdjustmentOptions::reuse_factorization: the reduced system formed and
// factorized once, then reused with each new gradient) reach the minimum the full iterations
// reach, with fewer factorizations.
TEST_CASE("Smooth-trajectory BA: reusing the factorization reaches the same minimum",
          "[sfm][ba][rs]") {
  const Scene truth = renderScene(60, 0.9, 0.3, 23);
  const auto solve = [&](bool reuse, Scene& s) {
    std::vector<uint8_t> fixed(s.cameras.size(), 0);
    fixed[0] = fixed[1] = 1;
    BundleAdjuster ba(static_cast<int>(s.cameras.size()), static_cast<int>(s.points.size()),
                      static_cast<int>(s.obs.size()), epitrack::BaCapacity::kSmoothTrajectory);
    BundleAdjustmentOptions o;
    o.huber_px = 0.5;  // some residuals beyond it: the reweighting moves the Hessian
    o.refine_readout = true;
    o.reuse_factorization = reuse;
    o.function_tolerance = 1e-6;
    std::vector<RollingShutterMotion> motions(s.cameras.size());
    return ba.solveTrajectory(s.cameras, fixed, s.points, {}, s.obs, s.k, o,
                              RollingShutter::fromReadout(0.5, kRows, kReferenceRow), s.neighbours,
                              motions);
  };
  Scene full = perturbed(truth);
  Scene chord = perturbed(truth);
  const auto a = solve(false, full);
  const auto b = solve(true, chord);
  INFO("full: " << a.iterations << " iterations, cost " << a.final_cost << ", readout "
                << a.line_delay * (kRows - 1) << "; reused: " << b.iterations << " iterations ("
                << b.chord_steps << " chord steps), cost " << b.final_cost << ", readout "
                << b.line_delay * (kRows - 1));
  REQUIRE(a.status == Status::kConverged);
  REQUIRE(b.status == Status::kConverged);
  CHECK(a.chord_steps == 0);
  CHECK(b.chord_steps > 0);
  CHECK(b.iterations - b.chord_steps < a.iterations);  // fewer formed systems
  // The chord steps stop on the same relative decrease, a little short along the directions the
  // observations determine least (where the cost is flat): the same cost to 1e-5 (the cost's own
  // scatter is sqrt(2 N) / N, 1e-2 here), the readout to a twentieth of its standard error, and
  // the cameras as near the truth.
  CHECK(std::fabs(b.final_cost - a.final_cost) < 1e-5 * a.final_cost);
  CHECK(std::fabs(b.line_delay - a.line_delay) < 0.05 * a.line_delay_std_error);
  const auto errors = [&](const Scene& s) {
    double angle = 0.0, shift = 0.0;
    for (std::size_t c = 0; c < s.cameras.size(); ++c) {
      angle += Eigen::AngleAxisd(s.cameras[c].R_cw * truth.cameras[c].R_cw.transpose()).angle();
      shift += (s.cameras[c].R_cw.transpose() * s.cameras[c].t_cw -
                truth.cameras[c].R_cw.transpose() * truth.cameras[c].t_cw)
                   .norm();
    }
    return std::pair(angle, shift);
  };
  const auto [angle_full, shift_full] = errors(full);
  const auto [angle_chord, shift_chord] = errors(chord);
  INFO("mean rotation error " << angle_full * 180 / M_PI / 60 << " / "
                              << angle_chord * 180 / M_PI / 60 << " deg, centre error "
                              << shift_full / 60 << " / " << shift_chord / 60);
  CHECK(angle_chord < 1.05 * angle_full);
  CHECK(shift_chord < 1.05 * shift_full);
}

TEST_CASE("Smooth-trajectory BA estimates the readout, and zero on a global shutter",
          "[sfm][ba][rs]") {
  const ReadoutRun rolling = estimate(0.9);
  INFO("readout " << rolling.readout << " +- " << rolling.std_error << " frame (true 0.9), rms "
                  << rolling.rms << " px, rotation error " << rolling.max_angle_deg << " deg");
  CHECK(std::fabs(rolling.readout - 0.9) < 0.05 * 0.9);
  CHECK(rolling.std_error > 0.0);
  CHECK(rolling.std_error < 0.02);
  // Within four standard errors of the truth: the error is an honest one.
  CHECK(std::fabs(rolling.readout - 0.9) < 4.0 * rolling.std_error);
  CHECK(rolling.rms < 0.3 * std::sqrt(2.0));
  CHECK(rolling.max_angle_deg < 0.05);
  const ReadoutRun global = estimate(0.0);
  INFO("global shutter: readout " << global.readout << " +- " << global.std_error);
  CHECK(std::fabs(global.readout) < 4.0 * global.std_error);
  CHECK(std::fabs(global.readout) < 0.02);
  CHECK(global.max_angle_deg < 0.05);
}

// Tracks that drift (each observation's error the previous one's plus a step) are not 60
// independent measurements each: the error is correlated along the track, and a standard error
// that counts every observation once claims several times the precision the estimate has
// (issue 27: tracked fast orbits scattered by +-7 ms about a 30 ms readout, each estimate claiming
// +-1 ms). The cluster-robust error (one cluster per point) follows the scatter.
TEST_CASE("The readout's standard error is honest when the tracks' errors drift", "[sfm][ba][rs]") {
  double sum_sq_error = 0.0, sum_sq_claimed = 0.0, sum_sq_independent = 0.0;
  constexpr int kSeeds = 8;
  for (int seed = 1; seed <= kSeeds; ++seed) {
    const ReadoutRun r = estimate(0.9, 100 + static_cast<uint64_t>(seed), 0.05, 0.06);
    std::printf("seed %d: drifting tracks: readout %.4f frame +- %.4f (independent errors: %.4f)\n",
                seed, r.readout, r.std_error, r.std_error_independent);
    CHECK(std::fabs(r.readout - 0.9) < 3.0 * r.std_error);
    CHECK(r.std_error >= r.std_error_independent);
    sum_sq_error += (r.readout - 0.9) * (r.readout - 0.9);
    sum_sq_claimed += r.std_error * r.std_error;
    sum_sq_independent += r.std_error_independent * r.std_error_independent;
  }
  const double rms_error = std::sqrt(sum_sq_error / kSeeds);
  const double rms_claimed = std::sqrt(sum_sq_claimed / kSeeds);
  const double rms_independent = std::sqrt(sum_sq_independent / kSeeds);
  std::printf(
      "drifting tracks: rms error %.4f frame, rms standard error %.4f, taking the errors "
      "as independent %.4f\n",
      rms_error, rms_claimed, rms_independent);
  CHECK(rms_claimed > 0.5 * rms_error);
  CHECK(rms_claimed < 3.0 * rms_error);
  CHECK(rms_independent < 0.5 * rms_error);  // what the error claimed before it was robust
  // Independent noise: the two agree (the cluster-robust one is the independent one's estimate
  // from the points' scatter).
  const ReadoutRun independent = estimate(0.9, 101, 0.3, 0.0);
  std::printf("independent noise: readout %.4f frame +- %.4f (independent errors: %.4f)\n",
              independent.readout, independent.std_error, independent.std_error_independent);
  CHECK(independent.std_error < 1.5 * independent.std_error_independent);
}

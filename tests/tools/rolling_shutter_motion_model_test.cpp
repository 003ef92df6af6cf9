// Issue 27: how closely can a motion model within one readout follow the rows' true poses? The
// solve's rolling-shutter model turns each frame's pose by a constant angular velocity over the
// readout, taken from its neighbours' poses (the central difference; docs/rolling-shutter.md).
// Here the models are fed the exact poses of epitrack-synth's trajectories at the frame times, so
// what is left is the model's own error, in pixels at a focal of 600 px over a 0.9-frame readout
// (rows at +-0.45 and +-0.225 frame interval from the middle row).
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <initializer_list>

#include <Eigen/Geometry>

#include "tools/synth/trajectory.hpp"

namespace synth = epitrack::synth;

namespace {

Eigen::Vector3d logSo3(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

struct ModelErrors {
  double central = 0.0;        // constant velocity, central difference of the neighbours
  double true_velocity = 0.0;  // constant velocity, the trajectory's own at the frame time
  double quadratic = 0.0;      // velocity and acceleration through the poses of f-1, f, f+1
  double quartic = 0.0;        // interpolation through the poses of frames f-2 ... f+2
};

// RMS over frames 3 ... frames-4 of the rotation error at the rows, pixels at `focal`.
ModelErrors modelErrors(const synth::TrajectoryParams& p, double focal) {
  double sum_central = 0.0, sum_true = 0.0, sum_quadratic = 0.0, sum_quartic = 0.0;
  int n = 0;
  for (int f = 3; f + 3 < p.frames; ++f) {
    const Eigen::Matrix3d R_f = synth::trajectoryPose(p, f).R_wc;
    // The pose at time t as R_f Exp(rel(t)): every model predicts rel.
    const auto rel = [&](double t) {
      return logSo3(R_f.transpose() * synth::trajectoryPose(p, t).R_wc);
    };
    const Eigen::Vector3d central = 0.5 * (rel(f + 1) - rel(f - 1));
    const Eigen::Vector3d second = rel(f + 1) + rel(f - 1);  // the second difference; rel(f) = 0
    constexpr double h = 1e-4;
    const Eigen::Vector3d velocity = (rel(f + h) - rel(f - h)) / (2.0 * h);
    for (const double tau : {-0.45, -0.225, 0.225, 0.45}) {
      Eigen::Vector3d quartic = Eigen::Vector3d::Zero();  // Lagrange; rel(f) = 0
      for (int i = -2; i <= 2; ++i) {
        if (i == 0) continue;
        double weight = 1.0;
        for (int j = -2; j <= 2; ++j)
          if (j != i) weight *= (tau - j) / static_cast<double>(i - j);
        quartic += weight * rel(f + i);
      }
      const Eigen::Vector3d truth = rel(f + tau);
      const auto sq = [&](const Eigen::Vector3d& model) {
        return (model - truth).squaredNorm() * focal * focal;
      };
      sum_central += sq(central * tau);
      sum_true += sq(velocity * tau);
      sum_quadratic += sq(central * tau + 0.5 * second * tau * tau);
      sum_quartic += sq(quartic);
      ++n;
    }
  }
  return {std::sqrt(sum_central / n), std::sqrt(sum_true / n), std::sqrt(sum_quadratic / n),
          std::sqrt(sum_quartic / n)};
}

}  // namespace

TEST_CASE("Within a readout, hand shake outruns a constant velocity, a smooth orbit does not",
          "[tools][synth][rolling-shutter]") {
  synth::TrajectoryParams shake;
  shake.kind = synth::SceneKind::kShake;
  shake.frames = 200;
  const ModelErrors s = modelErrors(shake, 600.0);
  synth::TrajectoryParams orbit;
  orbit.kind = synth::SceneKind::kOrbit;
  orbit.frames = 200;
  orbit.orbit_speed_deg = 0.75;
  orbit.target_wander = 1.0;
  const ModelErrors o = modelErrors(orbit, 600.0);
  std::printf(
      "rows' rotation error of the within-readout motion models (0.9-frame readout, focal 600, "
      "RMS px): shake: central difference %.3f, true velocity %.3f, quadratic through 3 frames "
      "%.3f, quartic through 5 frames %.3f; fast orbit: %.4f, %.4f, %.4f, %.4f\n",
      s.central, s.true_velocity, s.quadratic, s.quartic, o.central, o.true_velocity, o.quadratic,
      o.quartic);
  // The shake's jitter (bands to 8 Hz at 30 fps) changes its velocity within a readout: even the
  // exact velocity leaves more than the tracks' noise, the central difference more still.
  CHECK(s.true_velocity > 0.5);
  CHECK(s.central > s.true_velocity);
  CHECK(s.quartic < 0.5 * s.true_velocity);  // a model through more poses follows it
  // An acceleration from the same three poses (the second difference) is not enough: the jitter's
  // acceleration changes within the readout too; the neighbours' neighbours are needed.
  CHECK(s.quadratic < s.central);
  CHECK(s.quadratic > 2.0 * s.quartic);
  // The hand-held walk (seed 23, the clips of rolling_shutter_handheld_test.cpp) shakes gently:
  // the central difference misses its rows by 0.037 px RMS, a systematic error that alone gives
  // its noiseless landmarks an ATE of 0.035 % of the path (docs/rolling-shutter.md); through five
  // poses 0.0026 px.
  synth::TrajectoryParams walk;
  walk.kind = synth::SceneKind::kHandheld;
  walk.frames = 100;
  walk.seed = 23;
  const ModelErrors h = modelErrors(walk, 600.0);
  std::printf(
      "hand-held walk: central difference %.4f, true velocity %.4f, quadratic %.4f, "
      "quartic %.4f\n",
      h.central, h.true_velocity, h.quadratic, h.quartic);
  CHECK(h.central > 0.02);
  CHECK(h.central < 0.06);
  CHECK(h.quadratic < 0.6 * h.central);
  CHECK(h.quartic < 0.1 * h.central);
  // The orbit turns smoothly: the constant velocity is exact to a hundredth of a pixel.
  CHECK(o.central < 0.05);
  CHECK(o.true_velocity < 0.05);
  CHECK(o.quadratic < 0.005);
}

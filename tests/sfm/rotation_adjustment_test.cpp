// The rotation-only adjustment of a tripod solve (RotationAdjuster): a camera that pans with a
// changing speed, scene directions seen row by row (each row at its own time on the closed-form
// path, not the constant-velocity model the adjustment uses), perturbed starts.
#include <catch2/catch.hpp>

#include <cmath>
#include <vector>

#include <Eigen/Geometry>

#include "algo/geometry/pose.hpp"
#include "algo/sfm/rotation_adjustment.hpp"
#include "tools/synth/random.hpp"

using epitrack::BaIntrinsics;
using epitrack::BaTrajectoryNeighbours;
using epitrack::RollingShutter;
using epitrack::RotationAdjuster;
using epitrack::RotationAdjustmentOptions;
using epitrack::RotationObservation;

namespace {

constexpr int kRows = 480;
constexpr int kFrames = 40;
constexpr double kReferenceRow = 0.5 * (kRows - 1);

// R_cw at time t (frame intervals): a pan whose speed swings between about 0.5 and 3.5 deg per
// frame, with a slow tilt and roll.
Eigen::Matrix3d rotationAt(double t) {
  const double yaw = 0.035 * t + 0.4 * std::sin(0.08 * t);
  const double pitch = 0.05 * std::sin(0.05 * t);
  const double roll = 0.02 * std::sin(0.11 * t);
  const Eigen::Matrix3d R_wc = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()) *
                                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()) *
                                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()))
                                   .toRotationMatrix();
  return R_wc.transpose();
}

struct Scene {
  std::vector<Eigen::Matrix3d> truth, rotations;
  std::vector<Eigen::Vector3d> true_directions, directions;
  std::vector<RotationObservation> obs;
  std::vector<BaTrajectoryNeighbours> neighbours;
  std::vector<uint8_t> fixed;
  BaIntrinsics k{600.0, 1.0, 319.5, kReferenceRow, 0.0, 0.0};
};

// Where direction d is seen in frame f: the fixed point of the row (each row exposed at
// f + line_delay (row - reference)); false when it leaves the image.
bool observe(const BaIntrinsics& k, double line_delay, int f, const Eigen::Vector3d& d,
             Eigen::Vector2d& px) {
  double row = kReferenceRow;
  for (int i = 0; i < 20; ++i) {
    const Eigen::Vector3d x = rotationAt(f + line_delay * (row - kReferenceRow)) * d;
    if (x.z() <= 0.1) return false;
    px = Eigen::Vector2d(k.f * x.x() / x.z() + k.cx, k.f * x.y() / x.z() + k.cy);
    if (std::abs(px.y() - row) < 1e-9) break;
    row = px.y();
  }
  return std::abs(px.y() - row) < 1e-9 && px.x() >= 0.0 && px.x() <= 639.0 && px.y() >= 0.0 &&
         px.y() <= kRows - 1.0;
}

Scene makeScene(double readout_frames, uint64_t seed) {
  Scene s;
  epitrack::synth::SplitMix64 rng(seed);
  const double line_delay = readout_frames / (kRows - 1);
  for (int f = 0; f < kFrames; ++f) {
    s.truth.push_back(rotationAt(f));
    s.neighbours.push_back({f - 1, f + 1 < kFrames ? f + 1 : -1});
    s.fixed.push_back(f == 0 ? 1 : 0);
  }
  for (int j = 0; j < 3000; ++j) {
    const Eigen::Vector3d d =
        Eigen::Vector3d(rng.uniform(-1.0, 1.0), rng.uniform(-0.5, 0.5), rng.uniform(-1.0, 1.0))
            .normalized();
    std::vector<RotationObservation> seen;
    for (int f = 0; f < kFrames; ++f) {
      Eigen::Vector2d px;
      if (!observe(s.k, line_delay, f, d, px)) continue;
      px += 0.2 * Eigen::Vector2d(rng.gaussian(), rng.gaussian());
      seen.push_back({f, static_cast<int>(s.true_directions.size()), px});
    }
    if (seen.size() < 2) continue;
    s.obs.insert(s.obs.end(), seen.begin(), seen.end());
    s.true_directions.push_back(d);
  }
  // Starts: rotations off by up to 0.5 deg, directions by ~0.3 deg, the focal by 3 %.
  for (int f = 0; f < kFrames; ++f) {
    const Eigen::Vector3d e(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
    s.rotations.push_back(f == 0 ? s.truth[0]
                                 : Eigen::Matrix3d(epitrack::expSo3(0.005 * e) * s.truth[f]));
  }
  for (const auto& d : s.true_directions)
    s.directions.push_back(
        (d + 0.005 * Eigen::Vector3d(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)))
            .normalized());
  s.k.f *= 1.03;
  return s;
}

double worstRotationErrorDeg(const Scene& s) {
  double worst = 0.0;
  for (int f = 0; f < kFrames; ++f)
    worst =
        std::max(worst, epitrack::rotationAngle(s.rotations[static_cast<std::size_t>(f)] *
                                                s.truth[static_cast<std::size_t>(f)].transpose()) *
                            180.0 / M_PI);
  return worst;
}

struct Result {
  double worst_deg, rms_px, focal;
  bool converged;
};

Result adjust(Scene s, double model_readout_frames, bool refine_focal = true) {
  if (!refine_focal) s.k.f = 600.0;
  RotationAdjuster adjuster(kFrames, static_cast<int>(s.directions.size()),
                            static_cast<int>(s.obs.size()));
  RotationAdjustmentOptions o;
  o.refine_focal = refine_focal;
  o.huber_px = 1.0;
  o.shutter = RollingShutter::fromReadout(model_readout_frames, kRows, kReferenceRow);
  const auto r = adjuster.solve(s.rotations, s.fixed, s.directions, s.obs, s.neighbours, s.k, o);
  return {worstRotationErrorDeg(s), r.final_rms_px, s.k.f, r.converged && !r.failed};
}

}  // namespace

TEST_CASE("Rotation-only adjustment recovers a global-shutter pan's rotations and focal",
          "[sfm][tripod]") {
  const Scene s = makeScene(0.0, 7);
  REQUIRE(s.obs.size() > 10000);
  const Result r = adjust(s, 0.0);
  INFO("worst " << r.worst_deg << " deg, rms " << r.rms_px << " px, focal " << r.focal);
  CHECK(r.converged);
  // From up to 0.5 deg off. The pan sweeps 90 deg, so the first and last frames share no
  // direction: their relative rotation is carried through the overlaps (measured 0.020 deg).
  CHECK(r.worst_deg < 0.05);
  CHECK(std::abs(r.focal / 600.0 - 1.0) < 1e-3);  // from +3 %; measured 0.026 %
  CHECK(r.rms_px < 0.2 * std::sqrt(2.0) * 1.1);   // the noise: 0.2 px per axis
  const Result given = adjust(s, 0.0, false);
  INFO("focal given: worst " << given.worst_deg << " deg");
  CHECK(given.worst_deg < 0.03);
}

TEST_CASE("Rotation-only adjustment with the rolling shutter solves a pan exposed row by row",
          "[sfm][tripod][rolling-shutter]") {
  const Scene s = makeScene(0.9, 11);  // 30 ms readout at 30 fps
  const Result with_model = adjust(s, 0.9);
  const Result global = adjust(s, 0.0);
  INFO("with the model: worst " << with_model.worst_deg << " deg, rms " << with_model.rms_px
                                << " px, focal " << with_model.focal);
  INFO("as a global shutter: worst " << global.worst_deg << " deg, rms " << global.rms_px
                                     << " px, focal " << global.focal);
  CHECK(with_model.converged);
  CHECK(with_model.worst_deg < 0.05);  // measured 0.017
  CHECK(std::abs(with_model.focal / 600.0 - 1.0) < 1e-3);
  CHECK(with_model.rms_px < 0.2 * std::sqrt(2.0) * 1.1);
  // The same observations solved as a global shutter do not fit: the shear is left in them.
  CHECK(global.rms_px > 2.0 * with_model.rms_px);
  CHECK(global.worst_deg > 5.0 * with_model.worst_deg);
  const Result given = adjust(s, 0.9, false);
  INFO("focal given: worst " << given.worst_deg << " deg");
  CHECK(given.worst_deg < 0.03);  // measured 0.013
}

TEST_CASE("Rotation-only adjustment rejects observations of directions out of range",
          "[sfm][tripod]") {
  Scene s = makeScene(0.0, 3);
  s.obs.push_back({0, static_cast<int>(s.directions.size()), Eigen::Vector2d(1, 1)});
  RotationAdjuster adjuster(kFrames, static_cast<int>(s.directions.size()),
                            static_cast<int>(s.obs.size()));
  RotationAdjustmentOptions o;
  const auto r = adjuster.solve(s.rotations, s.fixed, s.directions, s.obs, s.neighbours, s.k, o);
  CHECK(r.failed);
}

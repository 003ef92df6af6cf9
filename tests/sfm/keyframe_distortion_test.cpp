// Key frames through a strongly distorting lens (issue 22 item 3): rendered key-frame sets (a
// clip subsampled to large viewpoint steps) with k1 = -0.28, k2 = 0.07 (a wide-angle lens, the
// model of a drone's 752x480 camera), matched, verified and solved with the distortion given,
// against the same views rendered through a pinhole lens. Every view must register and the
// trajectory error must stay close to the pinhole copy's. The same sets with the lens given to
// nobody: SolverOptions::detect_distortion finds it while the views register.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <Eigen/Geometry>

#include "algo/geometry/undistort.hpp"
#include "algo/image/image.hpp"
#include "algo/matching/descriptor_tracker.hpp"
#include "algo/sfm/solver.hpp"
#include "tools/eval/trajectory_metrics.hpp"
#include "tools/synth/synthetic_sequence.hpp"

using namespace epitrack;

namespace {

constexpr double kK1 = -0.28, kK2 = 0.07;

struct KeyframeSet {
  synth::SceneKind kind = synth::SceneKind::kOrbit;
  int keyframes = 12;
  int spacing = 24;  // rendered frames between key frames
  double wander = 0.5;
  uint64_t seed = 3;
  const char* name = "";
};

struct SolveFigures {
  int solved = 0;
  int frames = 0;
  double ate = 1.0;  // of the path
  double rotation_deg = 180.0;
  int verified_pairs = 0;  // of the view graph
  int inliers = 0;         // verified matches over every pair
  DistortionTrial trial;   // SolverOptions::detect_distortion's
  double focal = 0.0, k1 = 0.0, k2 = 0.0;
};

// What the solve is told of the lens.
enum class LensKnowledge {
  kGiven,              // k1, k2 given to the matching and the solver
  kSolverOnly,         // given to the solver, left out of the matching
  kUnknown,            // given to nobody, nor the focal: detect_distortion finds it while the views
                       // register
  kUnknownFocalGiven,  // given to nobody, the focal given (and held)
};

// The key-frame sets of both tests: wide steps around and along the scene.
const KeyframeSet kSets[] = {
    {synth::SceneKind::kOrbit, 10, 40, 0.5, 3, "orbit seed 3, 10 deg steps"},
    {synth::SceneKind::kOrbit, 8, 56, 0.5, 7, "orbit seed 7, 14 deg steps"},
    {synth::SceneKind::kHandheld, 8, 80, 0.0, 2, "handheld seed 2, 0.4 m steps"},
};

// Renders the set through a lens with (k1, k2), tracks it by descriptors, solves it as key frames
// with what `lens` says of the distortion and scores it against the true poses.
SolveFigures solveSet(const KeyframeSet& set, double k1, double k2, LensKnowledge lens) {
  synth::SynthOptions so;
  so.kind = set.kind;
  so.frames = set.keyframes * set.spacing;
  so.width = 640;
  so.height = 480;
  so.focal = 500.0;
  so.k1 = k1;
  so.k2 = k2;
  so.target_wander = set.wander;
  so.seed = set.seed;
  const synth::SyntheticSequence seq(so);
  synth::FrameRenderer renderer(seq);
  DescriptorTrackerOptions o;
  o.focal_px = so.focal;
  o.cx = (so.width - 1) * 0.5;
  o.cy = (so.height - 1) * 0.5;
  o.window = DescriptorTrackerOptions::kAllPairs;  // a photo set: every pair
  if (lens == LensKnowledge::kGiven) {
    o.k1 = k1;
    o.k2 = k2;
  }
  DescriptorTracker tracker(o, so.width, so.height, set.keyframes);
  Image<uint8_t> frame;
  for (int k = 0; k < set.keyframes; ++k) {
    renderer.render(k * set.spacing, frame);
    REQUIRE(tracker.addFrame(frame.constView()) == DescriptorTracker::Status::kOk);
  }
  TrackTable tracks;
  tracker.buildTracks(tracks);
  const bool unknown = lens == LensKnowledge::kUnknown || lens == LensKnowledge::kUnknownFocalGiven;
  SolveFigures r;
  for (const FramePairMatches& p : tracker.pairs()) {
    r.verified_pairs += p.verified ? 1 : 0;
    r.inliers += p.verified ? p.inliers : 0;
  }
  SolverOptions options;
  options.focal_px = lens == LensKnowledge::kUnknown ? 0.0 : so.focal;
  options.k1 = unknown ? 0.0 : k1;
  options.k2 = unknown ? 0.0 : k2;
  options.detect_distortion = unknown;
  options.keyframe_collection = true;
  Solver solver(tracks, so.width, so.height, options);
  r.frames = set.keyframes;
  if (!solver.calibrate() || !solver.initialize() || !solver.registerFrames() || !solver.finalize())
    return r;
  r.solved = solver.solvedFrames();
  const SolverSummary summary = solver.summary();
  r.trial = summary.distortion_trial;
  r.focal = summary.focal_px;
  r.k1 = summary.k1;
  r.k2 = summary.k2;
  std::vector<hal::TrajectoryEntry> gt, est;
  for (int k = 0; k < set.keyframes; ++k) {
    const synth::Pose truth = seq.pose(k * set.spacing);
    gt.push_back({static_cast<double>(k), truth.t_wc, Eigen::Quaterniond(truth.R_wc)});
    const SolvedFrame& f = solver.frames()[static_cast<std::size_t>(k)];
    if (f.solved)
      est.push_back(
          {static_cast<double>(k), f.pose.centre(), Eigen::Quaterniond(f.pose.R_cw.transpose())});
  }
  eval::TrajectoryMetrics m;
  std::string error;
  if (est.size() >= 3 && eval::evaluateTrajectory(gt, est, 0.01, m, error)) {
    r.ate = m.ate_rmse_rel;
    r.rotation_deg = m.rot_err_deg_mean;
  }
  return r;
}

}  // namespace

TEST_CASE("undistortNormalized inverts the radial model up to the corners of a wide lens",
          "[sfm][distortion]") {
  // Round trip over the image of a 640x480, f = 500 px camera (radius up to 0.8 normalized),
  // where the fixed-point inversion diverges for k1 = -0.28.
  double worst = 0.0;
  for (double y = -0.48; y <= 0.48; y += 0.04) {
    for (double x = -0.64; x <= 0.64; x += 0.04) {
      const Eigen::Vector2d p(x, y);
      const double r2 = p.squaredNorm();
      const Eigen::Vector2d d = p * (1.0 + kK1 * r2 + kK2 * r2 * r2);
      worst = std::max(worst, (undistortNormalized(kK1, kK2, d) - p).norm());
    }
  }
  CHECK(worst < 1e-12);
  CHECK(undistortNormalized(0.0, 0.0, Eigen::Vector2d(0.3, -0.2)) == Eigen::Vector2d(0.3, -0.2));
  CHECK(undistortNormalized(kK1, kK2, Eigen::Vector2d::Zero()) == Eigen::Vector2d::Zero());
}

TEST_CASE("Key frames through a k1 = -0.28 lens register as well as their pinhole copy",
          "[sfm][distortion][keyframes][slow]") {
  for (const KeyframeSet& set : kSets) {
    const SolveFigures pinhole = solveSet(set, 0.0, 0.0, LensKnowledge::kGiven);
    const SolveFigures lens = solveSet(set, kK1, kK2, LensKnowledge::kGiven);
    // The same lens with its distortion left out of the matching (the solver still has it).
    const SolveFigures ignored = solveSet(set, kK1, kK2, LensKnowledge::kSolverOnly);
    const auto line = [&](const char* what, const SolveFigures& r) {
      std::printf("%s, %s: %d/%d, ATE %.5f, %.3f deg, %d verified pairs, %d inliers\n", set.name,
                  what, r.solved, r.frames, r.ate, r.rotation_deg, r.verified_pairs, r.inliers);
    };
    line("pinhole", pinhole);
    line("k1 -0.28 k2 0.07 given", lens);
    line("k1 -0.28 k2 0.07 not given to the matching", ignored);
    INFO(set.name);
    CHECK(pinhole.solved == pinhole.frames);
    CHECK(lens.solved == lens.frames);
    // The distorted images lose resolution at the edges (the lens squeezes them) and gain field
    // of view: close to the pinhole copy, not equal.
    CHECK(lens.ate <= std::max(2.0 * pinhole.ate, pinhole.ate + 5e-4));
    CHECK(lens.rotation_deg <= std::max(2.0 * pinhole.rotation_deg, pinhole.rotation_deg + 0.1));
    // Undistorted, the pairs verify more matches than on the image as taken (measured 2026-12-03:
    // 20486 / 11730 / 25671 against 19155 / 11161 / 23971, and the 14-degree orbit's ATE 0.00005
    // against 0.00029).
    CHECK(lens.verified_pairs >= ignored.verified_pairs);
    CHECK(lens.inliers > ignored.inliers);
  }
}

TEST_CASE("Key frames through a lens nobody named: found while the views register",
          "[sfm][distortion][keyframes][slow]") {
  // SolverOptions::detect_distortion in the key-frame mode: the trial runs with the initial
  // pair's adjustment and again at 4, 8, ... views, not only in the final adjustments, which come
  // after an unmodelled lens has misled every registration. Measured 2026-12-07 (focal
  // self-calibrated): found at the initial pair, rotations 0.020 / 0.014 / 0.009 deg, ATE
  // 0.004 / 0.020 / 0.007 %; tried in the final adjustments only (detect_distortion_min_views
  // beyond the set): 123 deg and 15 % (the lens not found) / 0.069 deg / 4.6 deg and 0.5 %.
  for (const KeyframeSet& set : kSets) {
    const SolveFigures given = solveSet(set, kK1, kK2, LensKnowledge::kGiven);
    const SolveFigures found = solveSet(set, kK1, kK2, LensKnowledge::kUnknown);
    const SolveFigures found_at_focal = solveSet(set, kK1, kK2, LensKnowledge::kUnknownFocalGiven);
    const auto line = [&](const char* what, const SolveFigures& r) {
      std::printf(
          "%s, %s: %d/%d, focal %.2f, k1 %.4f k2 %.4f (trial at %d views), ATE %.5f, %.3f deg\n",
          set.name, what, r.solved, r.frames, r.focal, r.k1, r.k2, r.trial.views, r.ate,
          r.rotation_deg);
    };
    line("lens given", given);
    line("lens found while registering", found);
    line("lens found while registering, focal given", found_at_focal);
    INFO(set.name);
    CHECK(found.solved == found.frames);
    CHECK(found.trial.detected);
    CHECK(found.trial.views < found.frames);  // found during the registration
    CHECK(found.k1 == Approx(kK1).margin(0.005));
    CHECK(found.k2 == Approx(kK2).margin(0.005));
    CHECK(found.ate <= std::max(2.0 * given.ate, given.ate + 5e-4));
    CHECK(found.rotation_deg <= std::max(2.0 * given.rotation_deg, given.rotation_deg + 0.03));
    // The focal given and held: the initial pair's relative pose, found through the unmodelled
    // lens, is left by registering the views again with the lens found
    // (SolverOptions::keyframe_lens_reregistration; without it the 14-degree orbit ends 164 deg
    // off).
    CHECK(found_at_focal.solved == found_at_focal.frames);
    CHECK(found_at_focal.trial.detected);
    CHECK(found_at_focal.k1 == Approx(kK1).margin(0.005));
    CHECK(found_at_focal.ate <= std::max(2.0 * given.ate, given.ate + 5e-4));
    CHECK(found_at_focal.rotation_deg <=
          std::max(2.0 * given.rotation_deg, given.rotation_deg + 0.03));
  }
}

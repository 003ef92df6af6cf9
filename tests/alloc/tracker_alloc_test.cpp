#include <catch2/catch.hpp>

#include <vector>

#include "algo/image/image.hpp"
#include "algo/tracking/feature_tracker.hpp"
#include "algo/tracking/global_motion.hpp"
#include "tests/alloc/counting_allocator.hpp"
#include "tools/synth/synthetic_sequence.hpp"

using epitrack::FeatureTracker;
using epitrack::FeatureTrackerOptions;
using epitrack::Image;
using epitrack::test::AllocationScope;

// The rule: no heap allocation per frame after the first two. A hand-held clip exercises
// every path: LK, the Kalman gate, re-detection, neighbour priors, the forward-backward check and
// template refreshes (the noise raises the residuals: the frame-median scaling and the checks run).
TEST_CASE("FeatureTracker allocates nothing per frame after the first two", "[alloc][tracker]") {
  epitrack::synth::SynthOptions o;
  o.kind = epitrack::synth::SceneKind::kHandheld;
  o.frames = 102;
  o.width = 320;
  o.height = 240;
  o.focal = 280.0;
  o.noise_sigma = 3.0;
  o.seed = 3;
  const epitrack::synth::SyntheticSequence seq(o);
  epitrack::synth::FrameRenderer renderer(seq);
  std::vector<Image<uint8_t>> frames(static_cast<std::size_t>(o.frames));
  for (int f = 0; f < o.frames; ++f) renderer.render(f, frames[static_cast<std::size_t>(f)]);

  FeatureTrackerOptions options;
  options.max_features = 150;
  // The whole-frame re-detection and the one by grid cells (redetect_cells).
  options.redetect_cells = GENERATE(0, 48);
  FeatureTracker tracker(options, o.width, o.height);
  REQUIRE(tracker.track(frames[0].constView()) == FeatureTracker::Status::kOk);
  REQUIRE(tracker.track(frames[1].constView()) == FeatureTracker::Status::kOk);
  AllocationScope scope;
  int detected = 0, checks = 0;
  for (std::size_t f = 2; f < frames.size(); ++f) {
    REQUIRE(tracker.track(frames[f].constView()) == FeatureTracker::Status::kOk);
    detected += tracker.lastStats().detected;
    checks += tracker.lastStats().forward_backward_checks;
  }
  const std::size_t allocations = scope.count();
  REQUIRE(allocations == 0);
  CHECK(detected > 0);  // the paths ran
  CHECK(checks > 0);
}

// The global motion estimator's buffers are sized at construction: filling and fitting never
// allocate.
TEST_CASE("GlobalMotionEstimator allocates nothing per fit", "[alloc][tracker]") {
  epitrack::GlobalMotionEstimator estimator;
  AllocationScope scope;
  epitrack::SimilarityMotion motion;
  int ok = 0;
  for (int frame = 0; frame < 10; ++frame) {
    estimator.clear();
    for (int i = 0; i < 64; ++i) {
      const double x = 11.0 * i, y = 7.0 * ((i * 5) % 64);
      estimator.add(x, y, x + frame, y - 2.0 + (i % 7 == 0 ? 25.0 : 0.0));
    }
    ok += estimator.estimate(motion) == epitrack::GlobalMotionEstimator::Status::kOk ? 1 : 0;
  }
  REQUIRE(scope.count() == 0);
  CHECK(ok == 10);
  CHECK(motion.tx == Approx(9.0).margin(1e-6));
}

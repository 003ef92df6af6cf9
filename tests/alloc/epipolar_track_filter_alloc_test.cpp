#include <catch2/catch.hpp>

#include <vector>

#include "algo/image/image.hpp"
#include "algo/tracking/epipolar_track_filter.hpp"
#include "algo/tracking/feature_tracker.hpp"
#include "tests/alloc/counting_allocator.hpp"
#include "tests/tracker/epipolar_scenes.hpp"
#include "tools/synth/synthetic_sequence.hpp"

using epitrack::EpipolarCheckSummary;
using epitrack::EpipolarFilterOptions;
using epitrack::EpipolarTrackFilter;
using epitrack::test::AllocationScope;
using epitrack::test::EpipolarSceneKind;

// Per-frame work of the epipolar check (history, reference choice, F and H RANSAC, GRIC,
// strikes) allocates nothing: an orbit exercises the F path, a pan the H path, sliding tracks
// the rejections.
TEST_CASE("EpipolarTrackFilter allocates nothing per frame", "[alloc][tracker][epipolar]") {
  for (const auto kind : {EpipolarSceneKind::kOrbit, EpipolarSceneKind::kPan}) {
    const auto scene = epitrack::test::makeEpipolarScene(kind, 10, 21);
    // Measurements made up front: the scene's helpers are not what is measured.
    epitrack::SplitMix64 rng(5);
    std::vector<Eigen::Vector2d> positions;
    for (int f = 0; f < scene.frames; ++f)
      for (int i = 0; i < scene.tracks; ++i) positions.push_back(scene.measure(i, f, rng));
    EpipolarTrackFilter filter(EpipolarFilterOptions{}, scene.tracks);
    std::vector<uint8_t> dropped(static_cast<std::size_t>(scene.tracks), 0);
    int checks = 0, rejected = 0;
    AllocationScope scope;
    for (int f = 0; f < scene.frames; ++f) {
      filter.beginFrame();
      for (int i = 0; i < scene.tracks; ++i) {
        if (dropped[static_cast<std::size_t>(i)] != 0) continue;
        const auto& p = positions[static_cast<std::size_t>(f * scene.tracks + i)];
        filter.observe(i, i, static_cast<float>(p.x()), static_cast<float>(p.y()));
      }
      rejected += filter.endFrame();
      checks += filter.lastCheck().model != EpipolarCheckSummary::Model::kNone ? 1 : 0;
      for (int i = 0; i < scene.tracks; ++i)
        if (filter.rejected(i)) dropped[static_cast<std::size_t>(i)] = 1;
    }
    REQUIRE(scope.count() == 0);
    CHECK(checks > 20);  // the paths ran (30 of the 60 frames are due)
    CHECK(rejected == 10);
  }
}

// The tracker with the check on: the hook (observe, endFrame, drops) allocates nothing either.
TEST_CASE("FeatureTracker with the epipolar check allocates nothing per frame",
          "[alloc][tracker][epipolar]") {
  epitrack::synth::SynthOptions o;
  o.kind = epitrack::synth::SceneKind::kOcclusion;
  o.frames = 60;
  o.width = 320;
  o.height = 240;
  o.focal = 280.0;
  o.noise_sigma = 1.0;
  o.seed = 3;
  const epitrack::synth::SyntheticSequence seq(o);
  epitrack::synth::FrameRenderer renderer(seq);
  std::vector<epitrack::Image<uint8_t>> frames(static_cast<std::size_t>(o.frames));
  for (int f = 0; f < o.frames; ++f) renderer.render(f, frames[static_cast<std::size_t>(f)]);
  epitrack::FeatureTrackerOptions options;
  options.max_features = 150;
  options.epipolar_check = true;
  epitrack::FeatureTracker tracker(options, o.width, o.height);
  REQUIRE(tracker.track(frames[0].constView()) == epitrack::FeatureTracker::Status::kOk);
  REQUIRE(tracker.track(frames[1].constView()) == epitrack::FeatureTracker::Status::kOk);
  AllocationScope scope;
  double epipolar_ms = 0.0;
  for (std::size_t f = 2; f < frames.size(); ++f) {
    REQUIRE(tracker.track(frames[f].constView()) == epitrack::FeatureTracker::Status::kOk);
    epipolar_ms += tracker.lastStats().epipolar_ms;
  }
  REQUIRE(scope.count() == 0);
  CHECK(epipolar_ms > 0.0);  // the check ran
}

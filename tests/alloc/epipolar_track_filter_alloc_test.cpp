#include <catch2/catch.hpp>

#include <vector>

#include "algo/tracking/epipolar_track_filter.hpp"
#include "tests/alloc/counting_allocator.hpp"
#include "tests/tracker/epipolar_scenes.hpp"

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
    CHECK(checks > 40);  // the paths ran
    CHECK(rejected == 10);
  }
}

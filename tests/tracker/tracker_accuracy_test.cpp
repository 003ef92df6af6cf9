#include <catch2/catch.hpp>

#include <cstdio>

#include "algo/tracking/feature_tracker.hpp"
#include "tests/tracker/clip_prefix.hpp"
#include "tests/tracker/orbit_clip.hpp"

using epitrack::FeatureTrackerOptions;
using epitrack::test::measureTracker;
using epitrack::test::orbitClip;

namespace {

void print(const char* name, const epitrack::test::TrackAccuracy& a) {
  std::printf(
      "%s: observations %d (tracks %d associated, %d not), median %.3f px, p95 %.3f px, "
      "beyond 3 px %.2f %% (occluded %d), drift@100 median %.3f px (n=%zu), survival %d/%d, "
      "%.2f ms/frame\n",
      name, a.observations, a.associated_tracks, a.unassociated_tracks, a.median, a.p95,
      100.0 * a.fraction_beyond_3px, a.occluded_observations, a.drift_median_100,
      a.drift_at_100.size(), a.survived_100, a.visible_100, a.mean_ms);
}

}  // namespace

TEST_CASE("Tracking the noise-free 704x576 orbit meets the accuracy targets",
          "[tracker][orbit][slow]") {
  const auto& clip = orbitClip();
  const FeatureTrackerOptions options;
  const auto a = measureTracker(clip, options);
  print("orbit sigma 0", a);
  REQUIRE(a.observations > 20000);
  CHECK(a.median <= 0.15);
  CHECK(a.p95 <= 1.0);
  CHECK(a.fraction_beyond_3px < 0.01);
  CHECK(a.drift_median_100 < 0.5);
  REQUIRE(a.visible_100 > 0);
  // Issue 3: at least 90 % of the features whose corner stays visible survive 100 frames (the
  // occlusion-aware defaults: 169/180 measured; 142/180 with the whole-window set).
  CHECK(static_cast<double>(a.survived_100) >= 0.9 * a.visible_100);
}

TEST_CASE("The whole-window option set (the device's) meets the accuracy targets too",
          "[tracker][orbit][slow]") {
  const auto& clip = orbitClip();
  FeatureTrackerOptions options;
  options.wholeWindow();
  const auto a = measureTracker(clip, options);
  print("orbit sigma 0, whole-window", a);
  REQUIRE(a.observations > 20000);
  CHECK(a.median <= 0.15);
  CHECK(a.p95 <= 1.0);
  CHECK(a.fraction_beyond_3px < 0.01);
  CHECK(a.drift_median_100 < 0.5);
  REQUIRE(a.visible_100 > 0);
  CHECK(static_cast<double>(a.survived_100) >= 0.75 * a.visible_100);
}

TEST_CASE("Tracking the orbit with noise sigma 5 keeps the median error under 0.3 px",
          "[tracker][orbit][noise][slow]") {
  // 150 frames are enough for the statistics (about 35000 observations).
  const auto& clip = epitrack::test::noisyOrbitPrefix(150, 5.0);
  FeatureTrackerOptions defaults;
  const auto a = measureTracker(clip, defaults);
  print("orbit sigma 5", a);
  REQUIRE(a.observations > 20000);
  CHECK(a.median <= 0.3);
  CHECK(a.p95 <= 1.0);
  CHECK(a.fraction_beyond_3px < 0.01);
  REQUIRE(a.visible_100 > 0);
  CHECK(static_cast<double>(a.survived_100) >= 0.75 * a.visible_100);
  const auto b = measureTracker(clip, FeatureTrackerOptions{}.wholeWindow());
  print("orbit sigma 5, whole-window", b);
  CHECK(b.median <= 0.3);
  CHECK(b.p95 <= 1.0);
  CHECK(b.fraction_beyond_3px < 0.01);
}

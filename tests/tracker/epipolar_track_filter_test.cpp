#include <catch2/catch.hpp>

#include <cstdio>
#include <vector>

#include "algo/tracking/epipolar_track_filter.hpp"
#include "tests/tracker/epipolar_scenes.hpp"

using epitrack::EpipolarCheckSummary;
using epitrack::EpipolarFilterOptions;
using epitrack::EpipolarTrackFilter;
using epitrack::SplitMix64;
using epitrack::test::EpipolarScene;
using epitrack::test::EpipolarSceneKind;
using epitrack::test::makeEpipolarScene;

namespace {

struct FilterRun {
  std::vector<int> rejected_at;  // per track: the frame it was rejected (-1: never)
  int checks_f = 0;
  int checks_h = 0;
  int checks_none = 0;
  std::vector<float> errors;  // every error of every check, in order (determinism)
};

/// Feeds the scene's tracks to a filter (track i in slot i, id i), one frame at a time; a
/// rejected track is no longer observed (the tracker drops it). `glitch`: track, frame and size
/// of a one-frame jump of a correct track.
FilterRun runFilter(const EpipolarScene& scene, const EpipolarFilterOptions& options,
                    uint64_t noise_seed, int glitch_track = -1, int glitch_frame = -1,
                    double glitch_px = 0.0) {
  FilterRun run;
  run.rejected_at.assign(static_cast<std::size_t>(scene.tracks), -1);
  EpipolarTrackFilter filter(options, scene.tracks);
  SplitMix64 rng(noise_seed);
  for (int f = 0; f < scene.frames; ++f) {
    filter.beginFrame();
    for (int i = 0; i < scene.tracks; ++i) {
      Eigen::Vector2d p = scene.measure(i, f, rng);
      if (i == glitch_track && f == glitch_frame) p.x() += glitch_px;
      if (run.rejected_at[static_cast<std::size_t>(i)] >= 0) continue;
      filter.observe(i, i, static_cast<float>(p.x()), static_cast<float>(p.y()));
    }
    filter.endFrame();
    const EpipolarCheckSummary& c = filter.lastCheck();
    switch (c.model) {
      case EpipolarCheckSummary::Model::kFundamental:
        ++run.checks_f;
        break;
      case EpipolarCheckSummary::Model::kHomography:
        ++run.checks_h;
        break;
      case EpipolarCheckSummary::Model::kNone:
        ++run.checks_none;
        break;
    }
    for (int i = 0; i < scene.tracks; ++i) {
      run.errors.push_back(filter.error(i));
      if (filter.rejected(i)) run.rejected_at[static_cast<std::size_t>(i)] = f;
    }
  }
  return run;
}

void requireOutliersFoundAndInliersKept(const EpipolarScene& scene, const FilterRun& run,
                                        int latest_frame) {
  int found = 0, sliding = 0, lost_correct = 0;
  for (int i = 0; i < scene.tracks; ++i) {
    const int at = run.rejected_at[static_cast<std::size_t>(i)];
    if (scene.sliding[static_cast<std::size_t>(i)] != 0) {
      ++sliding;
      if (at > scene.slide_start && at <= latest_frame) ++found;
    } else if (at >= 0) {
      ++lost_correct;
    }
  }
  CHECK(lost_correct == 0);
  CHECK(found == sliding);
}

}  // namespace

TEST_CASE("Epipolar filter: sliding tracks of an orbit are rejected with F, correct ones kept",
          "[tracker][epipolar]") {
  for (const uint64_t seed : {1ULL, 2ULL, 3ULL}) {
    const EpipolarScene scene = makeEpipolarScene(EpipolarSceneKind::kOrbit, 10, seed);
    const FilterRun run = runFilter(scene, EpipolarFilterOptions{}, seed + 100);
    INFO("seed " << seed << ": F checks " << run.checks_f << ", H checks " << run.checks_h);
    // A slide of 0.5 px/frame across the epipolar line is found within 10 frames.
    requireOutliersFoundAndInliersKept(scene, run, scene.slide_start + 10);
    CHECK(run.checks_f > 20);  // of 30 due (interval 2): a scene with depth, F
    CHECK(run.checks_h == 0);
  }
}

TEST_CASE("Epipolar filter: a pure rotation uses H and keeps every correct track",
          "[tracker][epipolar]") {
  for (const uint64_t seed : {1ULL, 2ULL, 3ULL}) {
    const EpipolarScene scene = makeEpipolarScene(EpipolarSceneKind::kPan, 10, seed);
    const FilterRun run = runFilter(scene, EpipolarFilterOptions{}, seed + 200);
    INFO("seed " << seed << ": F checks " << run.checks_f << ", H checks " << run.checks_h);
    requireOutliersFoundAndInliersKept(scene, run, scene.slide_start + 10);
    CHECK(run.checks_h > 20);  // of 30 due (interval 2)
    CHECK(run.checks_f == 0);
  }
}

TEST_CASE("Epipolar filter: a planar scene uses H and keeps every correct track",
          "[tracker][epipolar]") {
  for (const uint64_t seed : {1ULL, 2ULL, 3ULL}) {
    const EpipolarScene scene = makeEpipolarScene(EpipolarSceneKind::kPlanar, 10, seed);
    const FilterRun run = runFilter(scene, EpipolarFilterOptions{}, seed + 300);
    INFO("seed " << seed << ": F checks " << run.checks_f << ", H checks " << run.checks_h);
    requireOutliersFoundAndInliersKept(scene, run, scene.slide_start + 10);
    CHECK(run.checks_h > 20);  // of 30 due (interval 2)
  }
}

TEST_CASE("Epipolar filter: noisier tracks without outliers lose nothing", "[tracker][epipolar]") {
  for (const auto kind :
       {EpipolarSceneKind::kOrbit, EpipolarSceneKind::kPan, EpipolarSceneKind::kPlanar}) {
    EpipolarScene scene = makeEpipolarScene(kind, 0, 5);
    scene.noise_px = 0.3;  // beyond the LK noise of a clip with sensor noise sigma 5
    const FilterRun run = runFilter(scene, EpipolarFilterOptions{}, 9);
    int lost = 0;
    for (const int at : run.rejected_at) lost += at >= 0 ? 1 : 0;
    CHECK(lost == 0);
    CHECK(run.checks_none < 36);  // the checks ran (30 frames are not due)
  }
}

TEST_CASE("Epipolar filter: one glitch does not reject a track: two checks in a row do",
          "[tracker][epipolar]") {
  const EpipolarScene scene = makeEpipolarScene(EpipolarSceneKind::kOrbit, 0, 4);
  // A 4 px jump in one frame: beyond the threshold in one check only.
  const FilterRun once = runFilter(scene, EpipolarFilterOptions{}, 11, 7, 30, 4.0);
  CHECK(once.rejected_at[7] == -1);
  EpipolarFilterOptions strict;
  strict.consecutive = 1;
  const FilterRun strict_run = runFilter(scene, strict, 11, 7, 30, 4.0);
  CHECK(strict_run.rejected_at[7] == 30);
}

TEST_CASE(
    "Epipolar filter: no check without enough shared tracks: the oldest frame without "
    "displacement",
    "[tracker][epipolar]") {
  const EpipolarScene few = makeEpipolarScene(EpipolarSceneKind::kOrbit, 0, 6, 20, 30);
  const FilterRun sparse = runFilter(few, EpipolarFilterOptions{}, 3);  // min_tracks 24
  CHECK(sparse.checks_none == few.frames);
  // Never enough displacement: every check is against the oldest frame of the window, and
  // there is none while even that one has moved less than min_span_displacement_px.
  const EpipolarScene scene = makeEpipolarScene(EpipolarSceneKind::kOrbit, 0, 6, 150, 30);
  EpipolarFilterOptions options;
  options.min_displacement_px = 1000.0;
  EpipolarTrackFilter filter(options, scene.tracks);
  SplitMix64 rng(3);
  int checks = 0;
  for (int f = 0; f < scene.frames; ++f) {
    filter.beginFrame();
    for (int i = 0; i < scene.tracks; ++i) {
      const Eigen::Vector2d p = scene.measure(i, f, rng);
      filter.observe(i, i, static_cast<float>(p.x()), static_cast<float>(p.y()));
    }
    CHECK(filter.endFrame() == 0);
    const EpipolarCheckSummary& c = filter.lastCheck();
    if (c.model == EpipolarCheckSummary::Model::kNone) {
      CHECK(c.median_displacement_px < options.min_span_displacement_px);
      continue;
    }
    ++checks;
    CHECK(c.reference_age == std::min(f, options.window));
    CHECK(c.median_displacement_px >= options.min_span_displacement_px);
  }
  CHECK(checks >= 8);  // of 15 due
}

TEST_CASE("Epipolar filter: results are a pure function of the input", "[tracker][epipolar]") {
  const EpipolarScene scene = makeEpipolarScene(EpipolarSceneKind::kOrbit, 10, 8);
  const FilterRun a = runFilter(scene, EpipolarFilterOptions{}, 12);
  const FilterRun b = runFilter(scene, EpipolarFilterOptions{}, 12);
  CHECK(a.rejected_at == b.rejected_at);
  CHECK(a.errors == b.errors);
}

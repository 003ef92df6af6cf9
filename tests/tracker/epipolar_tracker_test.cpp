#include <catch2/catch.hpp>

#include <cstdio>
#include <cstdlib>
#include <map>
#include <set>
#include <string>

#include "algo/tracking/feature_tracker.hpp"
#include "tests/support/process.hpp"
#include "tests/support/test_support.hpp"
#include "tests/tracker/clip_prefix.hpp"
#include "tests/tracker/orbit_clip.hpp"

using epitrack::FeatureTracker;
using epitrack::FeatureTrackerOptions;
using epitrack::TrackLoss;

namespace {

// Every 10th track id from frame 20 on slides across the image (to the right and down, speeding
// up smoothly to 0.4 px/frame: a slide starts gently, and the Kalman gate lets a smooth path
// through): the measurement reported is the true alignment plus a growing offset, as for a
// corner carried along an occluding edge. LK itself still converges on the real point each frame.
struct Slide {
  static constexpr int kStart = 20;
  std::set<int32_t> touched;
  static void hook(void* context, int32_t id, int frame, float& x, float& y) {
    auto* self = static_cast<Slide*>(context);
    if (id % 10 != 3 || frame <= kStart || id >= 200) return;
    const float k = static_cast<float>(frame - kStart);
    const float offset = k <= 8.0f ? 0.025f * k * k : 1.6f + 0.4f * (k - 8.0f);
    x += offset;
    y += 0.5f * offset;
    self->touched.insert(id);
  }
};

}  // namespace

TEST_CASE("FeatureTracker drops sliding tracks with TrackLoss::kEpipolar and counts them",
          "[tracker][epipolar][slow]") {
  const auto& clip = epitrack::test::orbitPrefix(60);
  FeatureTrackerOptions options;
  options.epipolar_check = true;
  FeatureTracker tracker(options, clip.frames[0].width(), clip.frames[0].height());
  Slide slide;
  tracker.setMeasurementHook(&Slide::hook, &slide);
  std::map<int32_t, TrackLoss> lost;
  std::set<int32_t> seen;
  int counted = 0;
  for (const auto& frame : clip.frames) {
    REQUIRE(tracker.track(frame.constView()) == FeatureTracker::Status::kOk);
    for (const auto& l : tracker.lost()) lost[l.id] = l.reason;
    for (const auto& t : tracker.features()) seen.insert(t.id);
    counted += tracker.lastStats().lost_epipolar;
  }
  int epipolar_total = 0, slid_epipolar = 0, slid_other = 0;
  for (const auto& [id, reason] : lost) {
    if (reason == TrackLoss::kEpipolar) ++epipolar_total;
    if (slide.touched.count(id) == 0) continue;
    if (reason == TrackLoss::kEpipolar) {
      ++slid_epipolar;
    } else {
      ++slid_other;
    }
  }
  std::printf(
      "sliding tracks %zu: epipolar %d, other reasons %d; epipolar losses %d of %zu tracks\n",
      slide.touched.size(), slid_epipolar, slid_other, epipolar_total, seen.size());
  REQUIRE(slide.touched.size() >= 10);
  // Every sliding track is gone by the end (most by the check: the Kalman gate lets a constant
  // velocity through); the counts agree; few correct tracks are lost to it.
  CHECK(slid_epipolar + slid_other == static_cast<int>(slide.touched.size()));
  CHECK(slid_epipolar >= static_cast<int>(0.8 * static_cast<double>(slide.touched.size())));
  CHECK(counted == epipolar_total);
  CHECK(epipolar_total - slid_epipolar <=
        static_cast<int>(0.02 * static_cast<double>(seen.size())));
}

namespace {

void compareOnOff(const char* name, const epitrack::test::RenderedClip& clip, bool strict) {
  for (const bool whole_window : {false, true}) {
    FeatureTrackerOptions on;
    if (whole_window) on.wholeWindow();
    on.epipolar_check = true;
    FeatureTrackerOptions off = on;
    off.epipolar_check = false;
    const auto a = epitrack::test::measureTracker(clip, on);
    const auto b = epitrack::test::measureTracker(clip, off);
    for (const auto* r : {&a, &b}) {
      std::printf(
          "%s%s, epipolar %s: observations %d, median %.3f px, p95 %.3f px, beyond 3 px %.2f %%, "
          "survival %d/%d, %.2f ms/frame\n",
          name, whole_window ? " whole-window" : "", r == &a ? "on" : "off", r->observations,
          r->median, r->p95, 100.0 * r->fraction_beyond_3px, r->survived_100, r->visible_100,
          r->mean_ms);
    }
    REQUIRE(a.observations > 10000);
    if (!strict) continue;
    CHECK(a.median <= 0.15);
    CHECK(a.p95 <= 1.0);
    CHECK(a.fraction_beyond_3px <= 0.01);
    CHECK(a.survived_100 + 1 >= b.survived_100);
  }
}

}  // namespace

TEST_CASE("The epipolar check on the orbit and the occlusion clip with noise sigma 1",
          "[tracker][epipolar][orbit][noise][slow]") {
  compareOnOff("orbit sigma 1", epitrack::test::noisyOrbitPrefix(150, 1.0), true);
  epitrack::synth::SynthOptions o;
  o.kind = epitrack::synth::SceneKind::kOcclusion;
  o.frames = 150;
  o.width = 704;
  o.height = 576;
  o.focal = 600.0;
  o.seed = 1;
  const auto clip = epitrack::test::addNoise(epitrack::test::renderClip(o), 1.0, 7);
  compareOnOff("occlusion sigma 1", clip, false);
}

TEST_CASE("epitrack-track --frame-stats has the epipolar column: --epipolar turns the check on",
          "[tracker][epipolar][command]") {
  epitrack::test::TempDir dir("track-epipolar");
  const std::string synth = epitrack::test::binaryPath("tools/synth/epitrack-synth");
  const std::string track = epitrack::test::binaryPath("tools/track/epitrack-track");
  REQUIRE(epitrack::test::run(synth +
                              " --scene occlusion --frames 40 --size 320x240 --focal 280 --out " +
                              dir.path() + "/clip 2>/dev/null") == 0);
  const std::string base = track + " " + dir.path() + "/clip/frames --out " +
                           dir.file("tracks.csv") + " --features 150 --quiet --frame-stats";
  // The epipolar check's time: zero without the check, positive with it (summed over frames).
  auto epipolarMs = [](const std::string& err, int& lines) {
    double total = 0.0;
    lines = 0;
    std::size_t at = 0;
    while ((at = err.find(" epipolar ", at)) != std::string::npos) {
      at += 10;
      const std::size_t ms = err.find("lk ", at);
      if (ms == std::string::npos) break;
      const std::size_t e = err.find(" epipolar ", ms);
      if (e == std::string::npos) break;
      total += std::atof(err.c_str() + e + 10);
      ++lines;
      at = e + 10;
    }
    return total;
  };
  const auto off = epitrack::test::runCaptured(base, dir.file("off"));
  const auto on = epitrack::test::runCaptured(base + " --epipolar", dir.file("on"));
  REQUIRE(off.exit_code == 0);
  REQUIRE(on.exit_code == 0);
  int lines_off = 0, lines_on = 0;
  CHECK(epipolarMs(off.err, lines_off) == 0.0);
  CHECK(epipolarMs(on.err, lines_on) > 0.0);
  CHECK(lines_off == 40);
  CHECK(lines_on == 40);
}

// Repeated frames (a capture loop faster than its source, pulldown, a driver repeating its last
// buffer): framesNearlyEqual decides, and the tracker keeps such a frame out of its filters, so a
// clip with every frame twice is tracked exactly like the clip itself.
#include <catch2/catch.hpp>

#include <cstdio>
#include <cstdlib>
#include <vector>

#include "algo/image/frame_difference.hpp"
#include "algo/image/image.hpp"
#include "algo/math/random.hpp"
#include "algo/tracking/feature_tracker.hpp"
#include "tests/tracker/clip_prefix.hpp"

using epitrack::FeatureTracker;
using epitrack::FeatureTrackerOptions;
using epitrack::framesNearlyEqual;
using epitrack::Image;
using epitrack::TrackedFeature;
using epitrack::test::RenderedClip;

namespace {

Image<uint8_t> seededImage(int w, int h, uint64_t seed) {
  Image<uint8_t> img;
  img.allocate(w, h);
  epitrack::SplitMix64 rng(seed);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) img(x, y) = static_cast<uint8_t>(rng.next() & 0xff);
  return img;
}

// Every frame's live features (id and position, bit for bit) and its repeat flag.
struct Run {
  std::vector<std::vector<TrackedFeature>> features;
  std::vector<int> repeated;
  int lost = 0;
};

Run track(const std::vector<const Image<uint8_t>*>& frames, const FeatureTrackerOptions& options) {
  Run run;
  FeatureTracker tracker(options, frames[0]->width(), frames[0]->height());
  for (const Image<uint8_t>* f : frames) {
    REQUIRE(tracker.track(f->constView()) == FeatureTracker::Status::kOk);
    const auto feats = tracker.features();
    run.features.emplace_back(feats.begin(), feats.end());
    run.repeated.push_back(tracker.lastStats().repeated);
    const auto& s = tracker.lastStats();
    run.lost += s.lost_lk + s.lost_gate + s.lost_residual + s.lost_forward_backward;
  }
  return run;
}

bool sameFeatures(const std::vector<TrackedFeature>& a, const std::vector<TrackedFeature>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a[i].id != b[i].id || a[i].x != b[i].x || a[i].y != b[i].y) return false;
  }
  return true;
}

}  // namespace

TEST_CASE("framesNearlyEqual bounds the mean absolute difference in 1/256 grey levels",
          "[tracker][repeat]") {
  const Image<uint8_t> a = seededImage(64, 48, 1);
  Image<uint8_t> b = seededImage(64, 48, 1);
  CHECK(framesNearlyEqual(a.constView(), b.constView(), 0));
  // One pixel off by 255: mean 255 / 3072 = 0.083 grey levels = 21.25 / 256.
  b(10, 10) = static_cast<uint8_t>(b(10, 10) ^ 0xff);
  const int d = std::abs(static_cast<int>(a(10, 10)) - static_cast<int>(b(10, 10)));
  const uint32_t exact_q8 = static_cast<uint32_t>(d * 256 / (64 * 48));
  CHECK(framesNearlyEqual(a.constView(), b.constView(), exact_q8 + 1));
  CHECK_FALSE(framesNearlyEqual(a.constView(), b.constView(), exact_q8 - 1));
  // Every pixel one grey level brighter (or darker): mean exactly 1 = 256 / 256.
  Image<uint8_t> c = seededImage(64, 48, 1);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) c(x, y) = static_cast<uint8_t>(c(x, y) < 255 ? c(x, y) + 1 : 254);
  CHECK(framesNearlyEqual(a.constView(), c.constView(), 256));
  CHECK_FALSE(framesNearlyEqual(a.constView(), c.constView(), 255));
  CHECK_FALSE(framesNearlyEqual(a.constView(), seededImage(64, 48, 2).constView(), 64));
  CHECK_FALSE(framesNearlyEqual(a.constView(), seededImage(64, 40, 1).constView(), 1u << 16));
  CHECK_FALSE(framesNearlyEqual(a.constView(), Image<uint8_t>().constView(), 1u << 16));
}

TEST_CASE("A clip with every frame twice is tracked exactly like the clip", "[tracker][repeat]") {
  const RenderedClip& clip = epitrack::test::noisyOrbitPrefix(40, 1.0);
  std::vector<const Image<uint8_t>*> once, twice;
  for (const auto& f : clip.frames) {
    once.push_back(&f);
    twice.push_back(&f);
    twice.push_back(&f);
  }
  const FeatureTrackerOptions defaults;
  const Run a = track(once, defaults);
  const Run b = track(twice, defaults);
  REQUIRE(b.features.size() == 2 * a.features.size());
  int identical = 0, repeats = 0;
  for (std::size_t i = 0; i < a.features.size(); ++i) {
    identical += sameFeatures(a.features[i], b.features[2 * i]) ? 1 : 0;
    identical += sameFeatures(a.features[i], b.features[2 * i + 1]) ? 1 : 0;
    repeats += b.repeated[2 * i + 1];
    CHECK(b.repeated[2 * i] == 0);
  }
  CHECK(identical == static_cast<int>(b.features.size()));
  CHECK(repeats == static_cast<int>(a.features.size()));
  CHECK(a.lost == b.lost);
  // The noise of the clip (sigma 1, a fresh draw per frame) keeps consecutive frames of a moving
  // camera far apart: no frame of the clip itself is taken for a repeat.
  for (const int r : a.repeated) CHECK(r == 0);

  // Without the rule the repeats cost tracks (each one halves every track's filtered velocity).
  FeatureTrackerOptions off;
  off.repeat_max_mean_diff_q8 = 0;
  const Run c = track(twice, off);
  std::printf(
      "every frame twice: %d tracks lost with the repeat rule (as the clip itself), %d "
      "without\n",
      b.lost, c.lost);
  for (const int r : c.repeated) CHECK(r == 0);
  CHECK(c.lost > 2 * b.lost);  // measured 684 against 172 (2026-12-03)
}

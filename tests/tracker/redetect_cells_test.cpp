// Re-detection restricted to grid cells: the detector's region search and the tracker's policy.
#include <catch2/catch.hpp>

#include <cstring>
#include <vector>

#include "algo/features/shi_tomasi_detector.hpp"
#include "algo/tracking/feature_tracker.hpp"
#include "tests/tracker/orbit_clip.hpp"

using epitrack::Corner;
using epitrack::DetectionRegion;
using epitrack::FeatureTracker;
using epitrack::FeatureTrackerOptions;
using epitrack::Image;
using epitrack::PixelRect;
using epitrack::ShiTomasiDetector;
using epitrack::ShiTomasiOptions;

namespace {

/// One rendered 640x480 orbit frame (seed `seed`): textured everywhere.
Image<uint8_t> texturedFrame(uint64_t seed) {
  epitrack::synth::SynthOptions o;
  o.frames = 1;
  o.width = 640;
  o.height = 480;
  o.focal = 540.0;
  o.seed = seed;
  auto clip = epitrack::test::renderClip(o);
  return std::move(clip.frames[0]);
}

bool inside(const PixelRect& r, float x, float y) {
  return x >= static_cast<float>(r.x0) && x < static_cast<float>(r.x1) &&
         y >= static_cast<float>(r.y0) && y < static_cast<float>(r.y1);
}

}  // namespace

// The region search must give, inside its regions, exactly the corners the whole-frame search
// finds there (same responses, same sub-pixel refinement from the region's own gradients): the
// whole-frame search with a mask of the regions is the reference (no relative floor, so the two
// thresholds agree).
TEST_CASE("Shi-Tomasi in regions finds the whole-frame corners of those regions",
          "[tracker][detector][redetect]") {
  const Image<uint8_t> frame = texturedFrame(3);
  const PixelRect regions[] = {{40, 60, 200, 140}, {201, 60, 330, 140}, {400, 300, 620, 470}};
  Image<uint8_t> mask(640, 480);
  std::memset(mask.view().row(0), 0, static_cast<std::size_t>(mask.view().stride) * 480);
  for (const PixelRect& r : regions) {
    for (int y = r.y0; y < r.y1; ++y) std::memset(mask.view().row(y) + r.x0, 1, r.x1 - r.x0);
  }
  ShiTomasiOptions d;
  d.max_features = 400;
  d.min_quality = 0.0;
  d.border = 13;
  ShiTomasiDetector whole(d, 640, 480);
  ShiTomasiDetector part(d, 640, 480);
  std::vector<Corner> expected(400), got(400);
  int n_expected = 0, n_got = 0;
  REQUIRE(whole.detect(frame.constView(), {}, mask.constView(), 400, expected, n_expected) ==
          ShiTomasiDetector::Status::kOk);
  std::vector<DetectionRegion> search;
  for (const PixelRect& r : regions) search.push_back(DetectionRegion{r, -1});
  REQUIRE(part.detectInRegions(frame.constView(), {}, {}, search, 400, got, n_got) ==
          ShiTomasiDetector::Status::kOk);
  INFO("whole-frame corners in the regions " << n_expected << ", region search " << n_got);
  REQUIRE(n_expected > 40);
  REQUIRE(n_got == n_expected);
  for (int i = 0; i < n_got; ++i) {
    const auto k = static_cast<std::size_t>(i);
    CHECK(got[k].x == expected[k].x);
    CHECK(got[k].y == expected[k].y);
    CHECK(got[k].response == expected[k].response);
  }
  // A cap per region: at most `wanted` there, the strongest of the region.
  std::vector<DetectionRegion> capped{{regions[2], 5}};
  REQUIRE(part.detectInRegions(frame.constView(), {}, {}, capped, 400, got, n_got) ==
          ShiTomasiDetector::Status::kOk);
  REQUIRE(n_got == 5);
  for (int i = 0; i < n_got; ++i)
    CHECK(
        inside(regions[2], got[static_cast<std::size_t>(i)].x, got[static_cast<std::size_t>(i)].y));
}

// Frame 1 replaces the top-left quarter of frame 0 by another texture: the tracks there are lost
// and the tracker re-detects. With the cell policy every new corner lies in a cell that lost
// tracks (the quarter, widened by one cell of the grid for tracks on its edge); the whole-frame
// policy also adds corners elsewhere (what the cells save).
TEST_CASE("Re-detection by cells adds corners only where tracks were lost", "[tracker][redetect]") {
  const Image<uint8_t> frame0 = texturedFrame(3);
  const Image<uint8_t> other = texturedFrame(11);
  Image<uint8_t> frame1(640, 480);
  for (int y = 0; y < 480; ++y) {
    std::memcpy(frame1.view().row(y), frame0.constView().row(y), 640);
    if (y < 240) std::memcpy(frame1.view().row(y), other.constView().row(y), 320);
  }
  const PixelRect changed{0, 0, 320, 240};
  const PixelRect near_changed{0, 0, 320 + 80, 240 + 80};  // one 80x80 cell of 48 more
  for (const int cells : {48, 0}) {
    FeatureTrackerOptions o;
    o.max_features = 300;
    o.redetect_cells = cells;
    FeatureTracker tracker(o, 640, 480);
    REQUIRE(tracker.track(frame0.constView()) == FeatureTracker::Status::kOk);
    const int first_id = static_cast<int>(tracker.features().size());
    REQUIRE(tracker.track(frame1.constView()) == FeatureTracker::Status::kOk);
    int lost_in_changed = 0;
    for (const auto& l : tracker.lost()) lost_in_changed += inside(changed, l.x, l.y) ? 1 : 0;
    int fresh = 0, fresh_outside = 0;
    for (const auto& f : tracker.features()) {
      if (f.id < first_id) continue;
      ++fresh;
      fresh_outside += inside(near_changed, f.x, f.y) ? 0 : 1;
    }
    INFO("cells " << cells << ": lost " << tracker.lost().size() << " (" << lost_in_changed
                  << " in the changed quarter), new " << fresh << ", new outside "
                  << fresh_outside);
    REQUIRE(lost_in_changed > 30);
    REQUIRE(fresh > 20);
    if (cells > 0) {
      CHECK(fresh_outside == 0);
      CHECK(tracker.lastStats().detect_cells < 20);
    } else {
      CHECK(fresh_outside > 0);
    }
  }
}

// shiftTracksToReferenceRow: tracks exposed row by row moved to their frames' middle-row times.
#include <catch2/catch.hpp>

#include <cmath>

#include <Eigen/Core>

#include "algo/sfm/rolling_shutter_tracks.hpp"

using epitrack::RollingShutter;
using epitrack::TrackTable;

namespace {

constexpr int kRows = 480;

// A track's true image path over time (frame intervals): a fast sideways sweep that slows,
// reverses and bobs, 20-40 px per frame.
Eigen::Vector2d pathAt(double t, double phase) {
  return {320.0 + 200.0 * std::sin(0.15 * t + phase), 240.0 + 190.0 * std::sin(0.25 * t + phase)};
}

// Where the path is seen in frame f: at the time its row is exposed (fixed point of the row).
Eigen::Vector2d exposedAt(const RollingShutter& rs, int f, double phase) {
  Eigen::Vector2d p = pathAt(f, phase);
  for (int i = 0; i < 30; ++i) p = pathAt(f + rs.rowTime(p.y()), phase);
  return p;
}

}  // namespace

TEST_CASE("Rolling-shutter tracks are moved to the middle-row time of their frames",
          "[sfm][rolling-shutter]") {
  const RollingShutter rs = RollingShutter::fromReadout(0.9, kRows, 0.5 * (kRows - 1));
  TrackTable exposed;
  constexpr int kFrames = 30;
  for (int f = 0; f < kFrames; ++f) {
    for (int t = 0; t < 4; ++t) {
      if (t == 3 && f != 12) continue;  // track 3: one observation only
      const Eigen::Vector2d p = exposedAt(rs, f, 0.8 * t);
      exposed.add(f, 100 + t, p.x(), p.y());
    }
  }
  exposed.setFrameCount(kFrames);
  exposed.finalize();
  TrackTable shifted;
  shiftTracksToReferenceRow(exposed, rs, shifted);
  REQUIRE(shifted.trackCount() == exposed.trackCount());
  REQUIRE(shifted.observations().size() == exposed.observations().size());
  double worst_inner = 0.0, worst_end = 0.0, worst_before = 0.0;
  for (int t = 0; t < 3; ++t) {
    REQUIRE(shifted.trackId(t) == exposed.trackId(t));  // same dense indices
    for (int f = 0; f < kFrames; ++f) {
      const auto* o = shifted.find(t, f);
      const auto* e = exposed.find(t, f);
      REQUIRE(o != nullptr);
      REQUIRE(e != nullptr);
      const Eigen::Vector2d truth = pathAt(f, 0.8 * t);
      const double err = (Eigen::Vector2d(o->x, o->y) - truth).norm();
      (f >= 2 && f + 2 < kFrames ? worst_inner : worst_end) =
          std::max(f >= 2 && f + 2 < kFrames ? worst_inner : worst_end, err);
      worst_before = std::max(worst_before, (Eigen::Vector2d(e->x, e->y) - truth).norm());
    }
  }
  INFO("as exposed " << worst_before << " px, moved: inner frames " << worst_inner
                     << " px, the two at each end " << worst_end << " px");
  CHECK(worst_before > 5.0);  // the shear: up to ~40 px/frame x 0.45 frame
  CHECK(worst_inner < 0.02);  // quartic through five frames
  CHECK(worst_end < 0.5);     // fewer frames on one side
  // A track seen once cannot be moved: it stays as exposed.
  const auto* single = shifted.find(3, 12);
  const auto* single_exposed = exposed.find(3, 12);
  REQUIRE(single != nullptr);
  CHECK(single->x == single_exposed->x);
  CHECK(single->y == single_exposed->y);
}

TEST_CASE("Shifting tracks with a zero readout leaves them as they are", "[sfm][rolling-shutter]") {
  TrackTable exposed;
  for (int f = 0; f < 5; ++f) exposed.add(f, 7, 10.0 + 3.0 * f * f, 20.0 - f);
  exposed.setFrameCount(5);
  exposed.finalize();
  TrackTable shifted;
  shiftTracksToReferenceRow(exposed, RollingShutter{}, shifted);
  for (int f = 0; f < 5; ++f) {
    CHECK(shifted.find(0, f)->x == Approx(exposed.find(0, f)->x).margin(1e-9));
    CHECK(shifted.find(0, f)->y == Approx(exposed.find(0, f)->y).margin(1e-9));
  }
}

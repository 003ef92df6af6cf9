#include <catch2/catch.hpp>

#include <cstdint>

#include "algo/sfm/track_table.hpp"

// TrackTable, the solver's input: observations by frame and by track, original ids mapped to
// dense indices, frames without observations counted.

using epitrack::TrackTable;

TEST_CASE("TrackTable indexes observations by frame and by track", "[sfm][track_table]") {
  TrackTable table;
  table.reserve(6, 16);
  // Track ids as tracks.csv carries them (sparse, large); frame 3 has no observation.
  table.add(0, 1000, 1.0, 2.0);
  table.add(0, 7, 3.0, 4.0);
  table.add(1, 1000, 1.5, 2.5);
  table.add(1, 7, 3.5, 4.5);
  table.add(1, int64_t{1} << 40, 9.0, 9.0);
  table.add(2, 1000, 2.0, 3.0);
  table.add(4, int64_t{1} << 40, 8.0, 8.0);
  table.setFrameCount(6);
  table.finalize();

  CHECK(table.frameCount() == 6);
  CHECK(table.trackCount() == 3);
  // Dense indices in order of first appearance, original ids kept.
  CHECK(table.trackId(0) == 1000);
  CHECK(table.trackId(1) == 7);
  CHECK(table.trackId(2) == (int64_t{1} << 40));

  CHECK(table.frame(0).size() == 2);
  CHECK(table.frame(1).size() == 3);
  CHECK(table.frame(2).size() == 1);
  CHECK(table.frame(3).empty());
  CHECK(table.frame(5).empty());
  CHECK(table.frame(6).empty());  // past the end: empty, not out of bounds
  CHECK(table.frame(-1).empty());
  CHECK(table.frame(1)[2].track == 2);
  CHECK(table.frame(1)[2].x == 9.0);

  // Track 0 (id 1000) in frames 0, 1, 2, by frame.
  const auto t0 = table.track(0);
  REQUIRE(t0.size() == 3);
  for (std::size_t k = 0; k < t0.size(); ++k)
    CHECK(table.observations()[static_cast<std::size_t>(t0[k])].frame == static_cast<int>(k));
  CHECK(table.track(2).size() == 2);

  const auto* o = table.find(2, 4);
  REQUIRE(o != nullptr);
  CHECK(o->x == 8.0);
  CHECK(o->frame == 4);
  CHECK(table.find(2, 3) == nullptr);
  CHECK(table.find(1, 2) == nullptr);
  CHECK(table.find(0, 2)->y == 3.0);
}

TEST_CASE("TrackTable sorts observations added out of frame order", "[sfm][track_table]") {
  TrackTable table;
  table.add(2, 5, 2.0, 0.0);
  table.add(0, 5, 0.0, 0.0);
  table.add(1, 6, 1.0, 0.0);
  table.add(1, 5, 1.0, 1.0);
  table.finalize();
  CHECK(table.frameCount() == 3);
  for (int f = 0; f < 3; ++f)
    for (const auto& obs : table.frame(f)) CHECK(obs.frame == f);
  const auto t = table.track(0);  // id 5
  REQUIRE(t.size() == 3);
  CHECK(table.observations()[static_cast<std::size_t>(t[0])].frame == 0);
  CHECK(table.observations()[static_cast<std::size_t>(t[2])].frame == 2);
  CHECK(table.find(0, 1)->y == 1.0);
}

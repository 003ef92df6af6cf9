#include <catch2/catch.hpp>

#include <map>
#include <set>

#include "hal/io/tracks_csv.hpp"
#include "tests/support/test_support.hpp"

namespace hal = epitrack::hal;

TEST_CASE("tracks.csv round-trips and rejects malformed lines", "[tracker][tracks_csv]") {
  const std::vector<hal::TrackRow> rows = {
      {0, 0, 10.5, 20.25}, {0, 1, 3.125, 4.0}, {1, 0, 11.0, 20.5}};
  const std::string text = hal::formatTracksCsv(rows);
  REQUIRE(text.rfind("frame,track_id,x,y\n", 0) == 0);
  std::vector<hal::TrackRow> back;
  std::string error;
  REQUIRE(hal::parseTracksCsv(text, back, error));
  REQUIRE(back.size() == rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    CHECK(back[i].frame == rows[i].frame);
    CHECK(back[i].track_id == rows[i].track_id);
    CHECK(back[i].x == Approx(rows[i].x).margin(1e-9));
    CHECK(back[i].y == Approx(rows[i].y).margin(1e-9));
  }
  CHECK_FALSE(hal::parseTracksCsv("0,1,2,3\n", back, error));
  CHECK_FALSE(hal::parseTracksCsv("frame,track_id,x,y\n0,1,2\n", back, error));
  CHECK(error.find("line 2") != std::string::npos);
  CHECK_FALSE(hal::parseTracksCsv("frame,track_id,x,y\n0,1,2,3,4\n", back, error));
  CHECK_FALSE(hal::parseTracksCsv("frame,track_id,x,y\n0,1,nan,3\n", back, error));
  CHECK(hal::parseTracksCsv("frame,track_id,x,y\r\n\n0,1,2,3\r\n", back, error));
  CHECK(back.size() == 1);
}

TEST_CASE("epitrack-track tracks a synthetic clip into tracks.csv", "[tracker][command]") {
  epitrack::test::TempDir dir("track-cmd");
  const std::string synth = epitrack::test::binaryPath("tools/synth/epitrack-synth");
  const std::string track = epitrack::test::binaryPath("tools/track/epitrack-track");
  REQUIRE(epitrack::test::run(synth +
                              " --scene orbit --frames 30 --size 320x240 --focal 280 --out " +
                              dir.path() + "/clip 2>/dev/null") == 0);
  REQUIRE(epitrack::test::run(track + " " + dir.path() + "/clip/frames --out " +
                              dir.file("tracks.csv") + " --features 150 --quiet") == 0);
  std::vector<hal::TrackRow> rows;
  std::string error;
  REQUIRE(hal::readTracksCsv(dir.file("tracks.csv"), rows, error));
  std::set<int64_t> frames;
  std::map<int32_t, int> length;
  for (const auto& r : rows) {
    frames.insert(r.frame);
    ++length[r.track_id];
    CHECK(r.x >= 0.0);
    CHECK(r.x <= 319.0);
    CHECK(r.y >= 0.0);
    CHECK(r.y <= 239.0);
  }
  CHECK(frames.size() == 30);
  int full = 0;
  for (const auto& [id, n] : length) full += n == 30 ? 1 : 0;
  CHECK(full >= 50);  // most first-frame features survive a slow 30-frame orbit
  // Bad usage and a missing input: exit 2 (issue 9).
  CHECK(epitrack::test::run(track + " " + dir.path() + " 2>/dev/null") == 2);
  CHECK(epitrack::test::run(track + " " + dir.path() + "/nothing --out " + dir.file("x.csv") +
                            " 2>/dev/null") == 2);
  CHECK(epitrack::test::run(track + " --help >/dev/null 2>&1") == 0);
}

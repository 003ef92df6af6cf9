// libFuzzer harness: the text parsers of hal/io — trajectories (`t tx ty tz qx qy qz qw`),
// intrinsics.txt (`fx fy cx cy width height [k1 k2]`) and tracks.csv (`frame,track_id,x,y`); every
// input goes to all three. Invariants: what a parser accepts is valid (finite numbers, unit
// quaternions, positive focal lengths and sizes, track ids in range), and the matching writer
// round-trips it: format, parse again, same values within the printed precision.
#include <cmath>
#include <string>
#include <vector>

#include "hal/io/text_formats.hpp"
#include "hal/io/tracks_csv.hpp"
#include "tests/fuzz/fuzz_support.hpp"

namespace hal = epitrack::hal;

namespace {

bool near(double a, double b, double abs_tol, double rel_tol) {
  return std::abs(a - b) <= abs_tol + rel_tol * std::max(std::abs(a), std::abs(b));
}

void checkTrajectory(const std::string& text) {
  std::vector<hal::TrajectoryEntry> entries;
  std::string error;
  if (!hal::parseTrajectory(text, entries, error)) {
    FUZZ_CHECK(!error.empty());
    return;
  }
  for (const hal::TrajectoryEntry& e : entries) {
    FUZZ_CHECK(std::isfinite(e.t) && e.position.allFinite() && e.rotation.coeffs().allFinite());
    FUZZ_CHECK(std::abs(e.rotation.norm() - 1.0) < 1e-9);
  }
  const std::string written = hal::formatTrajectory(entries, "round trip");
  std::vector<hal::TrajectoryEntry> again;
  FUZZ_CHECK(hal::parseTrajectory(written, again, error));
  FUZZ_CHECK(again.size() == entries.size());
  for (std::size_t i = 0; i < entries.size(); ++i) {
    FUZZ_CHECK(near(again[i].t, entries[i].t, 1e-6, 1e-15));
    for (int k = 0; k < 3; ++k) {
      FUZZ_CHECK(near(again[i].position[k], entries[i].position[k], 1e-9, 1e-15));
    }
    for (int k = 0; k < 4; ++k) {
      FUZZ_CHECK(near(again[i].rotation.coeffs()[k], entries[i].rotation.coeffs()[k], 1e-8, 0.0));
    }
  }
}

void checkIntrinsics(const std::string& text) {
  epitrack::CameraIntrinsics k;
  std::string error;
  if (!hal::parseIntrinsics(text, k, error)) {
    FUZZ_CHECK(!error.empty());
    return;
  }
  FUZZ_CHECK(k.fx > 0.0 && k.fy > 0.0 && std::isfinite(k.fx) && std::isfinite(k.fy));
  FUZZ_CHECK(std::isfinite(k.cx) && std::isfinite(k.cy) && std::isfinite(k.k1) &&
             std::isfinite(k.k2));
  FUZZ_CHECK(k.width >= 1 && k.height >= 1 && k.width <= 65536 && k.height <= 65536);
  const std::string written = hal::formatIntrinsics(k, "round trip");
  epitrack::CameraIntrinsics again;
  FUZZ_CHECK(hal::parseIntrinsics(written, again, error));
  FUZZ_CHECK(again.width == k.width && again.height == k.height);
  const double printed = 1e-9;  // %.10g (and subnormals, which hold fewer digits)
  FUZZ_CHECK(near(again.fx, k.fx, 1e-300, printed) && near(again.fy, k.fy, 1e-300, printed));
  FUZZ_CHECK(near(again.cx, k.cx, 1e-300, printed) && near(again.cy, k.cy, 1e-300, printed));
  FUZZ_CHECK(near(again.k1, k.k1, 1e-300, printed) && near(again.k2, k.k2, 1e-300, printed));
}

void checkTracksCsv(const std::string& text) {
  std::vector<hal::TrackRow> rows;
  std::string error;
  if (!hal::parseTracksCsv(text, rows, error)) {
    FUZZ_CHECK(!error.empty());
    return;
  }
  for (const hal::TrackRow& r : rows) {
    FUZZ_CHECK(r.frame >= 0 && std::isfinite(r.x) && std::isfinite(r.y));
  }
  const std::string written = hal::formatTracksCsv(rows);
  std::vector<hal::TrackRow> again;
  FUZZ_CHECK(hal::parseTracksCsv(written, again, error));
  FUZZ_CHECK(again.size() == rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    FUZZ_CHECK(again[i].frame == rows[i].frame && again[i].track_id == rows[i].track_id);
    FUZZ_CHECK(near(again[i].x, rows[i].x, 5e-4, 1e-15) &&
               near(again[i].y, rows[i].y, 5e-4, 1e-15));
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  checkTrajectory(text);
  checkIntrinsics(text);
  checkTracksCsv(text);
  return 0;
}

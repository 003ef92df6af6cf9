#include <catch2/catch.hpp>

#include <cstdio>
#include <sstream>
#include <string>

#include "tests/support/test_support.hpp"
#include "tests/tools/trajectory_score.hpp"

// epitrack-solve end to end on rendered synthetic clips: tracking, solve, exports, rendering.
// The orbit, handheld and --tracks cases run the default 600 features; --refine-focal and the dolly
// test an option and a motion, at the live tracker's budget (liveFeatureBudgetOption) and 480x360
// (under ASan the rendering of a 704x576 clip and the 600-feature solve take minutes).

using epitrack::test::binaryPath;
using epitrack::test::jsonNumber;
using epitrack::test::liveFeatureBudgetOption;
using epitrack::test::readWholeFile;
using epitrack::test::run;
using epitrack::test::TempDir;

namespace {

bool exists(const std::string& path) { return ::access(path.c_str(), R_OK) == 0; }

epitrack::eval::TrajectoryMetrics evaluate(const std::string& gt, const std::string& est) {
  return epitrack::test::scoreTrajectoryFiles(gt, est);
}

}  // namespace

TEST_CASE("epitrack-solve solves a rendered orbit and writes every output", "[solve][cli]") {
  // 80 frames: under ASan epitrack-synth's rendering is two thirds of this test's time.
  TempDir dir("solve");
  const std::string clip = dir.file("orbit");
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") +
              " --scene orbit --frames 80 --target-wander 0.5 --out " + clip + " 2>/dev/null") ==
          0);
  const std::string out = dir.file("out");
  REQUIRE(run(binaryPath("tools/solve/epitrack-solve") + " " + clip + "/frames --out " + out +
              " --intrinsics " + clip + "/intrinsics.txt --render towers --quiet") == 0);
  for (const char* f :
       {"cameras.tum", "intrinsics.txt", "points.ply", "summary.json", "colmap/cameras.txt",
        "colmap/images.txt", "colmap/points3D.txt", "blender_camera.py", "camera.chan",
        "augmented/000000.jpg", "augmented/000079.jpg", "augmented.avi"})
    CHECK(exists(out + "/" + f));
  const std::string summary = readWholeFile(out + "/summary.json");
  CHECK(summary.find("\"status\": \"ok\"") != std::string::npos);
  CHECK(jsonNumber(summary, "solved_frames") == 80);
  CHECK(jsonNumber(summary, "focal_px") == Approx(600.0));
  CHECK(jsonNumber(summary, "mean_reproj_px") < 0.5);
  const auto m = evaluate(clip + "/groundtruth.txt", out + "/cameras.tum");
  INFO("ate_rmse_rel " << m.ate_rmse_rel * 100 << " % rot " << m.rot_err_deg_mean << " deg");
  CHECK(m.matched_frames == 80);
  CHECK(m.ate_rmse_rel < 1e-3);
  CHECK(m.rot_err_deg_mean < 1.0);
}

TEST_CASE("epitrack-solve self-calibrates a handheld clip", "[solve][cli][slow]") {
  TempDir dir("solve-hh");
  const std::string clip = dir.file("hh");
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") + " --scene handheld --frames 150 --out " +
              clip + " 2>/dev/null") == 0);
  const std::string out = dir.file("out");
  REQUIRE(run(binaryPath("tools/solve/epitrack-solve") + " " + clip + "/frames --out " + out +
              " --quiet") == 0);
  const std::string summary = readWholeFile(out + "/summary.json");
  CHECK(summary.find("\"focal_source\": \"self-calibrated\"") != std::string::npos);
  INFO(summary.substr(0, 600));
  CHECK(std::abs(jsonNumber(summary, "focal_px") / 600.0 - 1.0) < 0.01);
  const auto m = evaluate(clip + "/groundtruth.txt", out + "/cameras.tum");
  INFO("ate_rmse_rel " << m.ate_rmse_rel * 100 << " %");
  CHECK(m.matched_frames == 150);
  CHECK(m.ate_rmse_rel < 1e-3);
}

TEST_CASE("epitrack-solve --refine-focal starts from a given focal 3 % off and refines it",
          "[solve][cli][slow]") {
  TempDir dir("solve-refine");
  const std::string clip = dir.file("orbit");
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") +
              " --scene orbit --frames 120 --size 480x360 --focal 420 --out " + clip +
              " 2>/dev/null") == 0);
  const std::string exe = binaryPath("tools/solve/epitrack-solve");
  // Without a focal to start from the flag is a usage error.
  CHECK(run(exe + " " + clip + "/frames --out " + dir.file("bad") +
            " --refine-focal --quiet 2>/dev/null") == 2);
  const std::string out = dir.file("out");
  REQUIRE(run(exe + " " + clip + "/frames --out " + out + " --focal 433 --refine-focal" +
              liveFeatureBudgetOption() + " --quiet") == 0);
  const std::string summary = readWholeFile(out + "/summary.json");
  INFO(summary.substr(0, 600));
  CHECK(summary.find("\"focal_source\": \"given\"") != std::string::npos);
  CHECK(summary.find("\"focal_refined\": true") != std::string::npos);
  CHECK(jsonNumber(summary, "focal_given_px") == 433.0);
  CHECK(std::abs(jsonNumber(summary, "focal_px") / 420.0 - 1.0) < 0.002);
  const auto m = evaluate(clip + "/groundtruth.txt", out + "/cameras.tum");
  INFO("ate_rmse_rel " << m.ate_rmse_rel * 100 << " %");
  CHECK(m.matched_frames == 120);
  CHECK(m.ate_rmse_rel < 2e-4);
}

TEST_CASE("epitrack-solve solves a short forward dolly", "[solve][cli][slow]") {
  // Forward motion: central tracks barely move and the pairs look like homographies; the widest
  // baseline must still initialise (a regression: this clip once ended in "planar-scene").
  TempDir dir("solve-dolly");
  const std::string clip = dir.file("dolly");
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") +
              " --scene dolly --frames 120 --size 480x360 --focal 420 --out " + clip +
              " 2>/dev/null") == 0);
  const std::string out = dir.file("out");
  REQUIRE(run(binaryPath("tools/solve/epitrack-solve") + " " + clip + "/frames --out " + out +
              " --focal 420" + liveFeatureBudgetOption() + " --quiet") == 0);
  const auto m = evaluate(clip + "/groundtruth.txt", out + "/cameras.tum");
  INFO("ate_rmse_rel " << m.ate_rmse_rel * 100 << " % rot " << m.rot_err_deg_mean << " deg");
  CHECK(m.matched_frames == 120);
  CHECK(m.ate_rmse_rel < 2e-3);
  CHECK(m.rot_err_deg_mean < 0.5);
}

TEST_CASE("epitrack-solve reports bad input clearly", "[solve][cli]") {
  TempDir dir("solve-bad");
  const std::string exe = binaryPath("tools/solve/epitrack-solve");
  CHECK(run(exe + " " + dir.file("missing") + " --out " + dir.file("o") + " 2>/dev/null") == 2);
  CHECK(run(exe + " " + dir.path() + " --out " + dir.file("o") + " --bogus 2>/dev/null") == 2);
  CHECK(run(exe + " " + dir.path() + " 2>/dev/null") == 2);  // --out missing
  CHECK(run(exe + " " + dir.path() + " --out " + dir.file("o") +
            " --focal 500 --intrinsics x 2>/dev/null") == 2);
  CHECK(run(exe + " --help >/dev/null") == 0);
}

namespace {

// landmarks.txt (`frame id x y`, the true projections) as a tracks.csv; `frames` frames at most.
// Every `stride`-th landmark: the orbit's frames see about 1 800 texture corners each, and with
// all of them this test took 105 s under ASan; 1 in 8 still leaves about 230 a frame.
std::string landmarksAsTracksCsv(const std::string& landmarks, int frames, int stride) {
  std::string csv = "frame,track_id,x,y\n";
  std::istringstream in(readWholeFile(landmarks));
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    int frame = 0, id = 0;
    double x = 0, y = 0;
    fields >> frame >> id >> x >> y;
    if (frame >= frames || id % stride != 0) continue;
    char row[96];
    std::snprintf(row, sizeof(row), "%d,%d,%.3f,%.3f\n", frame, id, x, y);
    csv += row;
  }
  return csv;
}

void writeText(const std::string& path, const std::string& text) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  REQUIRE(f != nullptr);
  REQUIRE(std::fwrite(text.data(), 1, text.size(), f) == text.size());
  std::fclose(f);
}

}  // namespace

TEST_CASE("epitrack-solve --tracks solves given 2D tracks instead of tracking", "[solve][cli]") {
  TempDir dir("solve-tracks");
  const std::string clip = dir.file("orbit");
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") +
              " --scene orbit --frames 40 --target-wander 0.5 --out " + clip + " 2>/dev/null") ==
          0);
  const std::string exe = binaryPath("tools/solve/epitrack-solve");
  const std::string tracks = dir.file("tracks.csv");
  writeText(tracks, landmarksAsTracksCsv(clip + "/landmarks.txt", 40, 8));

  // One clip for every check (Catch2 would render it again for each SECTION).
  {  // the true projections give the true cameras and focal
    const std::string out = dir.file("out");
    REQUIRE(run(exe + " " + clip + "/frames --out " + out + " --tracks " + tracks + " --quiet") ==
            0);
    const std::string summary = readWholeFile(out + "/summary.json");
    INFO(summary.substr(0, 800));
    CHECK(summary.find("\"matcher\": \"given\"") != std::string::npos);
    CHECK(summary.find("\"focal_source\": \"self-calibrated\"") != std::string::npos);
    // Coordinates rounded to 1/1000 px: the focal within 0.01 %, the path within 1e-6.
    CHECK(std::abs(jsonNumber(summary, "focal_px") / 600.0 - 1.0) < 1e-4);
    CHECK(jsonNumber(summary, "mean_reproj_px") < 0.01);
    const auto m = evaluate(clip + "/groundtruth.txt", out + "/cameras.tum");
    INFO("ate_rmse_rel " << m.ate_rmse_rel * 100 << " % rot " << m.rot_err_deg_mean << " deg");
    CHECK(m.matched_frames == 40);
    CHECK(m.ate_rmse_rel < 1e-6);
    CHECK(m.rot_err_deg_mean < 1e-3);
  }
  {  // epitrack-track's tracks solve as the solve's own tracking does
    const std::string own = dir.file("own"), given = dir.file("given");
    const std::string csv = dir.file("lk.csv");
    REQUIRE(run(binaryPath("tools/track/epitrack-track") + " " + clip + "/frames --out " + csv +
                " --features 600 --matcher lk 2>/dev/null") == 0);
    REQUIRE(run(exe + " " + clip + "/frames --out " + own +
                " --focal 600 --features 600 --matcher lk --quiet") == 0);
    REQUIRE(run(exe + " " + clip + "/frames --out " + given + " --focal 600 --tracks " + csv +
                " --quiet") == 0);
    const auto a = evaluate(clip + "/groundtruth.txt", own + "/cameras.tum");
    const auto b = evaluate(clip + "/groundtruth.txt", given + "/cameras.tum");
    INFO("own " << a.ate_rmse_rel * 100 << " %, given " << b.ate_rmse_rel * 100 << " %");
    CHECK(b.matched_frames == 40);
    CHECK(b.ate_rmse_rel < 2e-4);
    // tracks.csv keeps 1/1000 px: the same solve to within that rounding.
    CHECK(std::abs(a.ate_rmse_rel - b.ate_rmse_rel) < 0.1 * a.ate_rmse_rel + 1e-6);
  }
  {  // unusable tracks are refused before anything is written
    const std::string bad = dir.file("bad.csv");
    writeText(bad, "frame,track_id,x,y\n0,1,10.0,20.0\n40,1,11.0,21.0\n");  // clip: frames 0-39
    CHECK(run(exe + " " + clip + "/frames --out " + dir.file("o1") + " --tracks " + bad +
              " --quiet 2>/dev/null") == 2);
    CHECK(!exists(dir.file("o1")));
    writeText(bad, "frame,track,x\n0,1,10\n");  // not a tracks.csv
    CHECK(run(exe + " " + clip + "/frames --out " + dir.file("o2") + " --tracks " + bad +
              " --quiet 2>/dev/null") == 2);
    CHECK(!exists(dir.file("o2")));
    writeText(bad, "frame,track_id,x,y\n0,1,nan,20.0\n");
    CHECK(run(exe + " " + clip + "/frames --out " + dir.file("o3") + " --tracks " + bad +
              " --quiet 2>/dev/null") == 2);
    CHECK(run(exe + " " + clip + "/frames --out " + dir.file("o4") + " --tracks " +
              dir.file("missing.csv") + " --quiet 2>/dev/null") == 2);
    CHECK(run(exe + " " + clip + "/frames --out " + dir.file("o5") + " --tracks " + tracks +
              " --mask " + clip + "/frames/000000.pgm --quiet 2>/dev/null") == 2);
  }
}

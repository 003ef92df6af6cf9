#include <catch2/catch.hpp>

#include <cstdio>
#include <string>

#include "tests/support/test_support.hpp"
#include "tests/tools/trajectory_score.hpp"

// epitrack-solve end to end on rendered synthetic clips: tracking, solve, exports, rendering.

using epitrack::test::binaryPath;
using epitrack::test::jsonNumber;
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
  TempDir dir("solve");
  const std::string clip = dir.file("orbit");
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") +
              " --scene orbit --frames 120 --target-wander 0.5 --out " + clip + " 2>/dev/null") ==
          0);
  const std::string out = dir.file("out");
  REQUIRE(run(binaryPath("tools/solve/epitrack-solve") + " " + clip + "/frames --out " + out +
              " --intrinsics " + clip + "/intrinsics.txt --render towers --quiet") == 0);
  for (const char* f :
       {"cameras.tum", "intrinsics.txt", "points.ply", "summary.json", "colmap/cameras.txt",
        "colmap/images.txt", "colmap/points3D.txt", "blender_camera.py", "camera.chan",
        "augmented/000000.jpg", "augmented/000119.jpg", "augmented.avi"})
    CHECK(exists(out + "/" + f));
  const std::string summary = readWholeFile(out + "/summary.json");
  CHECK(summary.find("\"status\": \"ok\"") != std::string::npos);
  CHECK(jsonNumber(summary, "solved_frames") == 120);
  CHECK(jsonNumber(summary, "focal_px") == Approx(600.0));
  CHECK(jsonNumber(summary, "mean_reproj_px") < 0.5);
  const auto m = evaluate(clip + "/groundtruth.txt", out + "/cameras.tum");
  INFO("ate_rmse_rel " << m.ate_rmse_rel * 100 << " % rot " << m.rot_err_deg_mean << " deg");
  CHECK(m.matched_frames == 120);
  CHECK(m.ate_rmse_rel < 1e-3);
  CHECK(m.rot_err_deg_mean < 1.0);
}

TEST_CASE("epitrack-solve self-calibrates a handheld clip", "[solve][cli]") {
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
          "[solve][cli]") {
  TempDir dir("solve-refine");
  const std::string clip = dir.file("orbit");
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") + " --scene orbit --frames 120 --out " +
              clip + " 2>/dev/null") == 0);
  const std::string exe = binaryPath("tools/solve/epitrack-solve");
  // Without a focal to start from the flag is a usage error.
  CHECK(run(exe + " " + clip + "/frames --out " + dir.file("bad") +
            " --refine-focal --quiet 2>/dev/null") == 2);
  const std::string out = dir.file("out");
  REQUIRE(run(exe + " " + clip + "/frames --out " + out + " --focal 618 --refine-focal --quiet") ==
          0);
  const std::string summary = readWholeFile(out + "/summary.json");
  INFO(summary.substr(0, 600));
  CHECK(summary.find("\"focal_source\": \"given\"") != std::string::npos);
  CHECK(summary.find("\"focal_refined\": true") != std::string::npos);
  CHECK(jsonNumber(summary, "focal_given_px") == 618.0);
  CHECK(std::abs(jsonNumber(summary, "focal_px") / 600.0 - 1.0) < 0.002);
  const auto m = evaluate(clip + "/groundtruth.txt", out + "/cameras.tum");
  INFO("ate_rmse_rel " << m.ate_rmse_rel * 100 << " %");
  CHECK(m.matched_frames == 120);
  CHECK(m.ate_rmse_rel < 2e-4);
}

TEST_CASE("epitrack-solve solves a short forward dolly", "[solve][cli]") {
  // Forward motion: central tracks barely move and the pairs look like homographies; the widest
  // baseline must still initialise (a regression: this clip once ended in "planar-scene").
  TempDir dir("solve-dolly");
  const std::string clip = dir.file("dolly");
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") +
              " --scene dolly --frames 120 --size 480x360 --focal 420 --out " + clip +
              " 2>/dev/null") == 0);
  const std::string out = dir.file("out");
  REQUIRE(run(binaryPath("tools/solve/epitrack-solve") + " " + clip + "/frames --out " + out +
              " --focal 420 --quiet") == 0);
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

// epitrack-solve --distortion auto (the default): a lens nobody told the solve about is found and
// modelled; a pinhole clip is solved exactly as with --distortion none. Without the trial an
// unmodelled k1 = -0.2 at 640x480 bends into the focal (+42 %) and the path (ATE 0.6 %), and the
// solve still said ok.
#include <catch2/catch.hpp>

#include <string>

#include "tests/support/test_support.hpp"
#include "tests/tools/trajectory_score.hpp"

using epitrack::test::binaryPath;
using epitrack::test::jsonNumber;
using epitrack::test::readWholeFile;
using epitrack::test::run;
using epitrack::test::TempDir;

namespace {

std::string solve(const std::string& clip, const std::string& out, const std::string& options) {
  REQUIRE(run(binaryPath("tools/solve/epitrack-solve") + " " + clip + "/frames --out " + out +
              " --force --quiet " + options + " 2>/dev/null") == 0);
  return readWholeFile(out + "/summary.json");
}

// Renders an epitrack-synth clip into dir/clip.
std::string synthClip(const TempDir& dir, const std::string& arguments) {
  const std::string clip = dir.file("clip");
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") + " " + arguments + " --out " + clip +
              " 2>/dev/null") == 0);
  return clip;
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

}  // namespace

TEST_CASE("epitrack-solve --distortion auto leaves a pinhole clip's solve as it was, bit for bit",
          "[solve][cli][distortion]") {
  TempDir dir("distortion-pinhole");
  const std::string clip = synthClip(
      dir, "--scene orbit --frames 60 --size 480x360 --noise 1 --target-wander 0.5 --seed 53");
  const std::string automatic = solve(clip, dir.file("auto"), "");
  const std::string pinhole = solve(clip, dir.file("none"), "--distortion none");
  INFO(automatic);
  CHECK(contains(automatic, "\"status\": \"ok\""));
  CHECK(contains(automatic, "\"source\": \"none\""));
  CHECK(contains(automatic, "\"tried\": true"));
  CHECK(contains(pinhole, "\"tried\": false"));
  CHECK(jsonNumber(automatic, "trial_views") == 60);  // a video's trial: the final adjustments
  // The trial's lens is nothing: well under the 2 px it would need, no lower error.
  CHECK(jsonNumber(automatic, "trial_max_displacement_px") < 1.0);
  CHECK(jsonNumber(automatic, "trial_median_after_px") >
        0.9 * jsonNumber(automatic, "trial_median_before_px"));
  CHECK(readWholeFile(dir.file("auto") + "/cameras.tum") ==
        readWholeFile(dir.file("none") + "/cameras.tum"));
  CHECK(readWholeFile(dir.file("auto") + "/intrinsics.txt") ==
        readWholeFile(dir.file("none") + "/intrinsics.txt"));
}

TEST_CASE(
    "epitrack-solve --distortion auto finds a k1 = -0.2 lens that --distortion none bends into the "
    "focal",
    "[solve][cli][distortion][slow]") {
  // Measured 2026-12-07 (seed 51, 120 frames 640x480, noise 2): auto k1 -0.2003, k2 0.0506,
  // focal 600.2 (+0.03 %), ATE 0.0047 %; none: focal 853.7 (+42 %), ATE 0.61 %, rotation 2.6 deg.
  TempDir dir("distortion-lens");
  const std::string clip = synthClip(dir,
                                     "--scene orbit --frames 120 --size 640x480 --noise 2 "
                                     "--target-wander 0.5 --distortion -0.2,0.05 --seed 51");
  const std::string automatic = solve(clip, dir.file("auto"), "");
  const std::string pinhole = solve(clip, dir.file("none"), "--distortion none");
  const auto m_auto =
      epitrack::test::scoreTrajectoryFiles(clip + "/groundtruth.txt", dir.file("auto/cameras.tum"));
  const auto m_none =
      epitrack::test::scoreTrajectoryFiles(clip + "/groundtruth.txt", dir.file("none/cameras.tum"));
  INFO(automatic);
  INFO("ATE auto " << 100 * m_auto.ate_rmse_rel << " %, none " << 100 * m_none.ate_rmse_rel
                   << " %");
  CHECK(contains(automatic, "\"status\": \"ok\""));
  CHECK(contains(automatic, "\"source\": \"detected\""));
  CHECK(jsonNumber(automatic, "k1") == Approx(-0.2).margin(0.01));
  CHECK(jsonNumber(automatic, "k2") == Approx(0.05).margin(0.02));
  CHECK(jsonNumber(automatic, "focal_px") == Approx(600.0).epsilon(0.005));
  CHECK(jsonNumber(automatic, "trial_max_displacement_px") > 10.0);
  CHECK(m_auto.matched_frames == 120);
  CHECK(m_auto.ate_rmse_rel < 2e-4);
  CHECK(m_auto.rot_err_deg_mean < 0.1);
  // What the trial prevents: the pinhole solve's focal and path.
  CHECK(jsonNumber(pinhole, "focal_px") > 660.0);
  CHECK(m_none.ate_rmse_rel > 10.0 * m_auto.ate_rmse_rel);
}

TEST_CASE(
    "A pan through a lens: the focal said to be in doubt, and solved as a tripod once the "
    "lens is given",
    "[solve][cli][distortion]") {
  // Measured 2026-12-07 (this clip): without the lens, solved as a walking camera,
  // trajectory-uncertain, focal 755.2 px (+26 %), the trial's k1 -0.053 (3.1 px) lowering no
  // error; with --intrinsics (k1 -0.1, k2 0.02), rotation-only, rotations within 0.0015 deg.
  // Before the calibration pairs were undistorted, the given lens was refused as a plane.
  TempDir dir("distortion-pan");
  const std::string clip = synthClip(
      dir, "--scene pan --frames 60 --size 480x360 --noise 2 --distortion -0.1,0.02 --seed 63");
  // Exit 4: trajectory-uncertain, with the focal not called solved: the lens the trial saw is
  // named.
  CHECK(run(binaryPath("tools/solve/epitrack-solve") + " " + clip + "/frames --out " +
            dir.file("unknown") + " --force --quiet 2>/dev/null") == 4);
  const std::string unknown = readWholeFile(dir.file("unknown") + "/summary.json");
  INFO(unknown);
  CHECK(contains(unknown, "\"status\": \"trajectory-uncertain\""));
  CHECK(contains(unknown, "the focal only if the lens does not distort"));
  CHECK_FALSE(contains(unknown, "the rotations and the focal are solved"));
  const std::string given =
      solve(clip, dir.file("given"), "--intrinsics " + clip + "/intrinsics.txt");
  INFO(given);
  CHECK(contains(given, "\"status\": \"rotation-only\""));
  const auto m = epitrack::test::scoreTrajectoryFiles(clip + "/groundtruth.txt",
                                                      dir.file("given/cameras.tum"));
  CHECK(m.matched_frames == 60);
  CHECK(m.rot_err_deg_mean < 0.01);
}

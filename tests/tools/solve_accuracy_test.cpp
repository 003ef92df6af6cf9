#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <string>

#include "hal/io/text_formats.hpp"
#include "tests/support/test_support.hpp"
#include "tests/tools/trajectory_score.hpp"

// Issue 6's accuracy targets for the whole chain (rendered frames -> 2D tracker -> solver ->
// cameras.tum), scored by epitrack-eval's metrics against the rendered ground truth. The solver
// tests (tests/sfm) feed it ideal tracks with Gaussian noise; these feed it the tracker's real
// tracks, with their occlusion corners and edge-sliding features. Names start with "Solve
// accuracy" so the slow CI stages can leave them to the native suite (.ci/slow_tests.sh).

using epitrack::test::binaryPath;
using epitrack::test::jsonNumber;
using epitrack::test::jsonString;
using epitrack::test::readWholeFile;
using epitrack::test::run;
using epitrack::test::TempDir;

namespace {

struct Solved {
  std::string summary;
  epitrack::eval::TrajectoryMetrics m;
  double focal = 0.0;
};

std::string synth(const TempDir& dir, const std::string& name, const std::string& args) {
  const std::string clip = dir.file(name);
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") + " " + args + " --quiet --out " + clip) ==
          0);
  return clip;
}

Solved solve(const TempDir& dir, const std::string& clip, const std::string& name,
             const std::string& args) {
  const std::string out = dir.file(name);
  REQUIRE(run(binaryPath("tools/solve/epitrack-solve") + " " + clip + "/frames --out " + out +
              " --quiet " + args) == 0);
  Solved s;
  s.summary = readWholeFile(out + "/summary.json");
  s.focal = jsonNumber(s.summary, "focal_px");
  s.m = epitrack::test::scoreTrajectoryFiles(clip + "/groundtruth.txt", out + "/cameras.tum");
  return s;
}

}  // namespace

TEST_CASE("Solve accuracy: the rendered 340-frame orbit, known and self-calibrated focal",
          "[solve][accuracy][slow]") {
  // Issue 6: every frame, ATE <= 0.01 %, rotation <= 0.03 deg, reprojection <= 0.2 px with K
  // known; the focal within 0.1 % and ATE <= 0.01 % with it unknown. Measured (stop 15): known K
  // 0.0040 % / 0.0126 deg / 0.079 px; self-calibrated focal 0.005 % off, ATE 0.0045 %.
  TempDir dir("acc-orbit");
  const std::string clip = synth(dir, "orbit", "--scene orbit --frames 340 --target-wander 0.5");
  const Solved k = solve(dir, clip, "known", "--intrinsics " + clip + "/intrinsics.txt");
  INFO("known K: ate " << k.m.ate_rmse_rel * 100 << " % rot " << k.m.rot_err_deg_mean
                       << " deg reproj " << jsonNumber(k.summary, "mean_reproj_px"));
  CHECK(jsonNumber(k.summary, "solved_frames") == 340);
  CHECK(k.m.matched_frames == 340);
  CHECK(k.m.ate_rmse_rel <= 1e-4);
  CHECK(k.m.rot_err_deg_mean <= 0.03);
  CHECK(jsonNumber(k.summary, "mean_reproj_px") <= 0.2);
  const Solved u = solve(dir, clip, "self", "");
  INFO("self-calibrated: focal " << u.focal << " ate " << u.m.ate_rmse_rel * 100 << " % rot "
                                 << u.m.rot_err_deg_mean << " deg");
  CHECK(jsonString(u.summary, "focal_source") == "self-calibrated");
  CHECK(std::abs(u.focal / 600.0 - 1.0) <= 1e-3);
  CHECK(u.m.matched_frames == 340);
  CHECK(u.m.ate_rmse_rel <= 1e-4);
}

TEST_CASE("Solve accuracy: handheld with the focal unknown", "[solve][accuracy][slow]") {
  // Issue 6: focal within 0.5 %, ATE <= 0.05 %. Measured (stop 15, 200 frames): focal 0.009 %
  // off, ATE 0.024 %.
  TempDir dir("acc-hh");
  const std::string clip = synth(dir, "hh", "--scene handheld --frames 200");
  const Solved u = solve(dir, clip, "self", "");
  INFO("focal " << u.focal << " ate " << u.m.ate_rmse_rel * 100 << " % rot " << u.m.rot_err_deg_mean
                << " deg");
  CHECK(u.m.matched_frames == 200);
  CHECK(std::abs(u.focal / 600.0 - 1.0) <= 5e-3);
  CHECK(u.m.ate_rmse_rel <= 5e-4);
}

TEST_CASE("Solve accuracy: noise sigma 2 with motion blur, and radial distortion",
          "[solve][accuracy][slow]") {
  // Issue 6: noise 2 + blur with K known: ATE <= 0.1 %, rotation <= 0.1 deg. Measured (stop 15,
  // blur 0.5): 0.0041 % / 0.020 deg. Distortion -0.12, 0.03 solved with --distortion k1k2: k1
  // within 5 % and the undistorted figures; measured k1 -0.1198 (0.15 %), 0.0051 % / 0.004 deg.
  TempDir dir("acc-noise");
  const std::string noisy =
      synth(dir, "noisy", "--scene orbit --frames 200 --target-wander 0.5 --noise 2 --blur 0.5");
  const Solved n = solve(dir, noisy, "noisy-out", "--intrinsics " + noisy + "/intrinsics.txt");
  INFO("noisy: ate " << n.m.ate_rmse_rel * 100 << " % rot " << n.m.rot_err_deg_mean << " deg");
  CHECK(n.m.matched_frames == 200);
  CHECK(n.m.ate_rmse_rel <= 1e-3);
  CHECK(n.m.rot_err_deg_mean <= 0.1);
  const std::string lens =
      synth(dir, "lens", "--scene orbit --frames 200 --target-wander 0.5 --distortion -0.12,0.03");
  const Solved d = solve(dir, lens, "lens-out", "--focal 600 --distortion k1k2");
  epitrack::CameraIntrinsics k;
  std::string error;
  REQUIRE(epitrack::hal::readIntrinsicsFile(dir.file("lens-out") + "/intrinsics.txt", k, error));
  const double k1 = k.k1, k2 = k.k2;
  INFO("distortion: k1 " << k1 << " k2 " << k2 << " ate " << d.m.ate_rmse_rel * 100 << " % rot "
                         << d.m.rot_err_deg_mean << " deg");
  CHECK(std::abs(k1 / -0.12 - 1.0) <= 0.05);
  CHECK(d.m.matched_frames == 200);
  CHECK(d.m.ate_rmse_rel <= 1e-4);
  CHECK(d.m.rot_err_deg_mean <= 0.03);
}

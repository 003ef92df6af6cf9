// epitrack-solve on the real key-frame sequences of ../shared/data (skipped visibly without it):
// the TUM RGB-D fr3/cabinet key frames (issue 6: at least 90 % of the frames solved) and the
// Middlebury templeRing views 12-30, against their ground truth through epitrack-eval.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <unistd.h>

#include "tests/support/process.hpp"
#include "tests/support/test_support.hpp"

using epitrack::test::binaryPath;
using epitrack::test::jsonNumber;
using epitrack::test::jsonString;
using epitrack::test::readWholeFile;
using epitrack::test::run;
using epitrack::test::sharedDataDir;
using epitrack::test::TempDir;

namespace {

struct SolveResult {
  int exit_code = -1;
  std::string summary, eval;
};

SolveResult solveAndEvaluate(const TempDir& dir, const std::string& frames,
                             const std::string& intrinsics, const std::string& gt,
                             const std::string& extra) {
  SolveResult r;
  const std::string out = dir.file("out");
  r.exit_code =
      run(binaryPath("tools/solve/epitrack-solve") + " " + frames + " --out " + out +
          (intrinsics.empty() ? "" : " --intrinsics " + intrinsics) + " --quiet " + extra);
  r.summary = readWholeFile(out + "/summary.json");
  const std::string eval = dir.file("eval.json");
  run(binaryPath("tools/eval/epitrack-eval") + " --gt " + gt + " --est " + out + "/cameras.tum > " +
      eval);
  r.eval = readWholeFile(eval);
  return r;
}

// Sum of the "frames" of the ranges in summary.json's array `key` ("solved_ranges" or
// "unsolved_ranges"); -1 when the array is absent.
int framesInRanges(const std::string& summary, const std::string& key) {
  const auto begin = summary.find("\"" + key + "\": [");
  if (begin == std::string::npos) return -1;
  const auto end = summary.find(']', begin);
  int total = 0;
  const std::string field = "\"frames\": ";
  for (auto at = summary.find(field, begin); at != std::string::npos && at < end;
       at = summary.find(field, at + 1))
    total += std::atoi(summary.c_str() + at + field.size());
  return total;
}

}  // namespace

TEST_CASE(
    "TUM fr3/cabinet key frames: descriptor tracks, no view far off called ok, the rest named",
    "[matching][real][slow]") {
  const std::string name = "tum_fr3_cabinet_keyframes";
  if (!epitrack::test::haveSharedSequence(name)) return;
  const std::string seq = sharedDataDir() + "/" + name;
  // The default seed and seed 2, whose solve registered 55 of 58 views under "ok" with views
  // 51-57 and 3-4 16-27 degrees off (PnP chains on the cabinet's plain side; measured
  // 2026-12-06).
  for (const int seed : {1, 2}) {
    TempDir dir("tum-kf-" + std::to_string(seed));
    // Default options: auto must pick the descriptor matcher for these key frames.
    const SolveResult r =
        solveAndEvaluate(dir, seq + "/frames", seq + "/intrinsics.txt", seq + "/groundtruth.txt",
                         seed == 1 ? "" : "--seed " + std::to_string(seed));
    INFO("seed " << seed << ": " << r.summary.substr(0, 700));
    INFO(r.eval);
    CHECK(jsonString(r.summary, "matcher") == "descriptors");
    const double frames = jsonNumber(r.summary, "frames");
    const double solved = jsonNumber(r.summary, "solved_frames");
    const std::string status = jsonString(r.summary, "status");
    const double rot_max = jsonNumber(r.eval, "rot_err_deg_max");
    std::printf(
        "TUM cabinet key frames, seed %d: %.0f/%.0f solved (%s, exit %d), ATE %.4f of the path, "
        "rotation %.2f deg mean, %.2f deg max; %.0f view pairs checked\n",
        seed, solved, frames, status.c_str(), r.exit_code, jsonNumber(r.eval, "ate_rmse_rel"),
        jsonNumber(r.eval, "rot_err_deg_mean"), rot_max, jsonNumber(r.summary, "pairs_checked"));
    CHECK(frames == 58);
    CHECK(jsonNumber(r.eval, "matched_frames") == solved);
    CHECK(frames - solved == std::max(0, framesInRanges(r.summary, "unsolved_ranges")));
    CHECK(jsonNumber(r.summary, "pairs_checked") >= 50);
    // The status says what was solved: partial (exit 3) below 90 % of the views, with the rest
    // named; above it ok (exit 0), or inconsistent (exit 5) when pairs of registered views
    // contradict the solve (Solver::checkViewPairs).
    if (solved < 0.9 * frames) {
      CHECK(status == "partial");
      CHECK(r.exit_code == 3);
    } else {
      CHECK((status == "ok" || status == "inconsistent"));
      CHECK(r.exit_code == (status == "ok" ? 0 : 5));
    }
    // Never a silent wrong answer: a view more than 15 degrees off is never under "ok".
    CHECK((rot_max <= 15.0 || status != "ok"));
    if (seed == 1) {
      // Measured 2026-12-06: 52/58, partial, ATE 0.0125, rotation 3.7 deg mean, 10.2 deg max.
      // Before the relative pose had to be determined by its matches
      // (SolverOptions::keyframe_max_rotation_spread_deg): 58/58 and ok, but frames 3-6 rotated
      // by 14-42 deg (ATE 0.0244): registered from an E that its matches did not determine.
      CHECK(solved >= 50);
      CHECK(rot_max < 15.0);
      CHECK(jsonNumber(r.eval, "ate_rmse_rel") < 0.02);
      CHECK(jsonNumber(r.eval, "rot_err_deg_mean") < 5.0);
    }
  }
}

TEST_CASE("templeRing views 12-30: descriptor tracks, rotations better than LK",
          "[matching][real][slow]") {
  const std::string name = "middlebury_templeRing";
  if (!epitrack::test::haveSharedSequence(name)) return;
  const std::string seq = sharedDataDir() + "/" + name;
  TempDir dir("temple-kf");
  // The longest continuous run of the ring (7.66 degrees between views): views 12-30 as frames
  // 0-18, the ground truth re-indexed the same way.
  const std::string frames = dir.file("frames");
  REQUIRE(run("mkdir -p " + frames) == 0);
  for (int v = 12; v <= 30; ++v) {
    char src[64], dst[64];
    std::snprintf(src, sizeof(src), "/frames/%06d.png", v);
    std::snprintf(dst, sizeof(dst), "/%06d.png", v - 12);
    REQUIRE(::symlink((seq + src).c_str(), (frames + dst).c_str()) == 0);
  }
  const std::string gt = dir.file("groundtruth.txt");
  REQUIRE(run("awk '/^#/ {next} $1 >= 12 && $1 <= 30 {$1 = $1 - 12; print}' " + seq +
              "/groundtruth.txt > " + gt) == 0);
  const SolveResult r =
      solveAndEvaluate(dir, frames, seq + "/intrinsics.txt", gt, "--matcher descriptors");
  INFO(r.summary.substr(0, 700));
  INFO(r.eval);
  REQUIRE(r.exit_code == 0);
  std::printf(
      "templeRing 12-30, descriptors: %.0f/19 solved, ATE %.4f of the path, rotation "
      "%.2f deg mean (LK: ATE 0.0017, 0.62 deg)\n",
      jsonNumber(r.summary, "solved_frames"), jsonNumber(r.eval, "ate_rmse_rel"),
      jsonNumber(r.eval, "rot_err_deg_mean"));
  CHECK(jsonNumber(r.summary, "solved_frames") == 19);
  // With the solver's robust statistics (stop 15): ATE 0.00175, rotation 0.37 deg; LK 0.0017 and
  // 0.62 deg (before them: 0.0028 / 0.57 deg against LK's 0.0033 / 1.09 deg).
  CHECK(jsonNumber(r.eval, "ate_rmse_rel") < 0.0025);
  CHECK(jsonNumber(r.eval, "rot_err_deg_mean") < 0.5);
}

TEST_CASE("templeRing, all 47 views: ok only when 90 % register, else partial with views named",
          "[matching][real][slow]") {
  // Issue 22: the 47 views in folder order (a ring, but not in ring order everywhere) registered
  // 6 of 47 and the solve said "ok", exit 0.
  const std::string name = "middlebury_templeRing";
  if (!epitrack::test::haveSharedSequence(name)) return;
  const std::string seq = sharedDataDir() + "/" + name;
  // The default matcher (auto: descriptors, for the cut in the file order after view 4 or 11),
  // with the intrinsics given and with the focal self-calibrated.
  for (const bool given : {true, false}) {
    const std::string focal = given ? "given" : "self-calibrated";
    TempDir dir("temple-47-" + focal);
    const SolveResult r =
        solveAndEvaluate(dir, seq + "/frames", given ? seq + "/intrinsics.txt" : std::string(),
                         seq + "/groundtruth.txt", "");
    INFO("focal " << focal << ": " << r.summary.substr(0, 1500));
    INFO(r.eval);
    const double frames = jsonNumber(r.summary, "frames");
    const double solved = jsonNumber(r.summary, "solved_frames");
    std::printf("templeRing, 47 views, focal %s: %.0f/%.0f registered, status %s, exit %d\n",
                focal.c_str(), solved, frames, jsonString(r.summary, "status").c_str(),
                r.exit_code);
    if (!given) {
      // Issue 22: the focal within 0.5 % of the calibration's fx (1520.4 px). F does not observe
      // it (the axes meet near one point) and the held profile is flat; the refined solves from
      // 320-1907 px converge (solver.md). Measured 2026-12-05: 1521.44 px (+0.068 %; 2026-12-04,
      // before the matcher's merge rule, 1520.75 px), before the convergence rule the flat
      // profile's guess 1534.2 px (+0.91 %).
      CHECK(std::abs(jsonNumber(r.summary, "focal_px") / 1520.4 - 1.0) <= 0.005);
      CHECK(jsonString(r.summary, "focal_fallback") == "converged");
    }
    CHECK(frames == 47);
    // Every view is in exactly one range: registered, or unregistered with a cause.
    CHECK(framesInRanges(r.summary, "solved_ranges") == solved);
    CHECK(framesInRanges(r.summary, "unsolved_ranges") == frames - solved);
    CHECK(jsonString(r.summary, "matcher") == "descriptors");
    {
      // The view graph (every pair matched, --match-window auto = all for 47 views): every view
      // registers. Measured 2026-12-05: 47/47, ATE 0.00039 of the path (self-calibrated
      // 0.00034; before the matcher's merge rule 0.00042 / 0.00048). The rotation error is not
      // checked: views 31-46 come out 180 degrees about their optical axis from groundtruth.txt
      // (0.42 deg mean over views 0-30, 179.8 over 31-46, each part aligned alone), which no
      // solve of these images can match: the README's rotation of those images or their ground
      // truth is off by a half turn.
      CHECK(solved == frames);
      CHECK(jsonNumber(r.eval, "ate_rmse_rel") < 0.001);
    }
    // The view-pair check finds nothing against this right solve (measured 2026-12-06: 428
    // pairs checked, none contradicted), so the status can be ok.
    CHECK(jsonNumber(r.summary, "pairs_checked") >= 100);
    if (solved >= 0.9 * frames) {
      CHECK(jsonString(r.summary, "status") == "ok");
      CHECK(r.exit_code == 0);
    } else {
      CHECK(jsonString(r.summary, "status") == "partial");
      CHECK(r.exit_code == 3);
      CHECK(r.summary.find("\"cause\": \"") != std::string::npos);
      CHECK(jsonString(r.summary, "message").find("; unsolved: ") != std::string::npos);
    }
  }
}

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "hal/io/text_formats.hpp"
#include "tests/device/device_output.hpp"
#include "tests/support/test_support.hpp"
#include "tools/eval/trajectory_metrics.hpp"

// Live accuracy (issue 8): replayed synthetic clips with the given intrinsics. After the map is
// initialised every frame must be tracking, and the live poses, similarity-aligned to the ground
// truth, must be within 2x the offline solver's ATE (epitrack-solve --intrinsics on the same clip).

using epitrack::test::binaryPath;
using epitrack::test::readWholeFile;
using epitrack::test::run;
using epitrack::test::TempDir;

namespace {

epitrack::eval::TrajectoryMetrics evaluate(const std::vector<epitrack::hal::TrajectoryEntry>& gt,
                                           const std::vector<epitrack::hal::TrajectoryEntry>& est) {
  epitrack::eval::TrajectoryMetrics m;
  std::string error;
  INFO(error);
  REQUIRE(epitrack::eval::evaluateTrajectory(gt, est, 0.01, m, error));
  return m;
}

// epitrack-device on a clip (SEQ/frames with SEQ/intrinsics.txt): its per-frame lines.
std::vector<epitrack::test::DeviceLine> runDevice(const std::string& seq, const TempDir& dir,
                                                  std::string& summary) {
  const std::string poses = dir.file("poses.jsonl");
  REQUIRE(run(binaryPath("firmware_like/epitrack-device") + " --source " + seq +
              "/frames --intrinsics " + seq + "/intrinsics.txt --poses " + poses +
              " 2>/dev/null") == 0);
  std::vector<epitrack::test::DeviceLine> lines;
  epitrack::test::parseDeviceOutput(readWholeFile(poses), lines, summary);
  return lines;
}

void checkLiveAgainstOffline(const std::string& synth_args, std::size_t max_init_frame,
                             double max_ratio, bool self_calibrate, const std::string& tag) {
  TempDir dir(tag);
  const std::string clip = dir.file("clip");
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") + " " + synth_args + " --out " + clip +
              " 2>/dev/null") == 0);
  std::vector<epitrack::hal::TrajectoryEntry> gt;
  std::string error;
  REQUIRE(epitrack::hal::readTrajectoryFile(clip + "/groundtruth.txt", gt, error));

  // Live.
  std::string summary;
  std::vector<epitrack::test::DeviceLine> lines = runDevice(clip, dir, summary);
  REQUIRE(lines.size() == gt.size());
  REQUIRE_FALSE(summary.empty());
  std::size_t first_tracking = lines.size();
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (lines[i].status == "tracking") {
      first_tracking = i;
      break;
    }
    CHECK(lines[i].status == "initializing");
  }
  INFO("initialised at frame " << first_tracking);
  REQUIRE(first_tracking <= max_init_frame);
  int not_tracking = 0;
  for (std::size_t i = first_tracking; i < lines.size(); ++i)
    not_tracking += lines[i].status == "tracking" ? 0 : 1;
  CHECK(not_tracking == 0);
  const auto live = evaluate(gt, epitrack::test::trackingTrajectory(lines));

  // Offline, at the device's feature budget (300, FeatureTrackerOptions): the comparison is of
  // the live map against the offline solver on the same 2D tracks' budget. epitrack-solve's own
  // default tracks twice as many (tools::kSolveFeatures); the README gives both ratios.
  const std::string out = dir.file("solve");
  REQUIRE(run(binaryPath("tools/solve/epitrack-solve") + " " + clip + "/frames --out " + out +
              " --intrinsics " + clip + "/intrinsics.txt" +
              epitrack::test::liveFeatureBudgetOption() + " --render none --quiet") == 0);
  std::vector<epitrack::hal::TrajectoryEntry> offline_est;
  REQUIRE(epitrack::hal::readTrajectoryFile(out + "/cameras.tum", offline_est, error));
  const auto offline = evaluate(gt, offline_est);

  std::printf(
      "%s: live ate_rmse_rel %.5f (%d frames, rot %.3f deg), offline %.5f (%d frames, "
      "rot %.3f deg), ratio %.2f, %s\n",
      tag.c_str(), live.ate_rmse_rel, live.matched_frames, live.rot_err_deg_mean,
      offline.ate_rmse_rel, offline.matched_frames, offline.rot_err_deg_mean,
      live.ate_rmse_rel / offline.ate_rmse_rel, summary.c_str());
  INFO("live " << live.ate_rmse_rel << " offline " << offline.ate_rmse_rel);
  // Issue 8 asks for 2x (max_ratio).
  CHECK(live.ate_rmse_rel <= max_ratio * offline.ate_rmse_rel);
  // Absolute bound as well:
  CHECK(live.ate_rmse_rel < 6e-4);
  CHECK(live.rot_err_deg_mean < 1.0);

  if (!self_calibrate) return;
  // Without intrinsics: the focal is self-calibrated over the first seconds, then the same loop.
  const std::string sc_poses = dir.file("poses-selfcal.jsonl");
  REQUIRE(run(binaryPath("firmware_like/epitrack-device") + " --source " + clip +
              "/frames --poses " + sc_poses + " 2>/dev/null") == 0);
  lines.clear();
  epitrack::test::parseDeviceOutput(readWholeFile(sc_poses), lines, summary);
  REQUIRE(lines.size() == gt.size());
  CHECK(summary.find("\"focal_source\": \"self-calibrated\"") != std::string::npos);
  epitrack::CameraIntrinsics K;
  REQUIRE(epitrack::hal::readIntrinsicsFile(clip + "/intrinsics.txt", K, error));
  const double focal = epitrack::test::jsonNumber(summary, "focal_px", -1);
  CHECK(std::abs(focal - K.fx) < 0.02 * K.fx);
  std::size_t sc_first = lines.size();
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (lines[i].status == "tracking") {
      sc_first = i;
      break;
    }
  }
  REQUIRE(sc_first < lines.size() / 2);
  int sc_not_tracking = 0;
  for (std::size_t i = sc_first; i < lines.size(); ++i)
    sc_not_tracking += lines[i].status == "tracking" ? 0 : 1;
  CHECK(sc_not_tracking == 0);
  const auto sc = evaluate(gt, epitrack::test::trackingTrajectory(lines));
  std::printf(
      "%s self-calibrated: focal %.1f (true %.1f), tracking from frame %zu, ate_rmse_rel %.5f\n",
      tag.c_str(), focal, K.fx, sc_first, sc.ate_rmse_rel);
  // The item-3 bound is for given intrinsics; a focal 1 % off bends the trajectory a little
  // (measured: 0.0007, i.e. 0.7 mm per metre of path).
  CHECK(sc.ate_rmse_rel < 0.0015);
}

}  // namespace

TEST_CASE("Live poses on a replayed orbit stay near the offline solver, and self-calibrated",
          "[device][accuracy][slow]") {
  // Measured (Release, x86-64): live 0.00015, offline 0.00013 (ratio 1.14), initialised at frame
  // 10. With 6 Levenberg-Marquardt iterations per windowed adjustment (before) the live orbit
  // bent slowly (0.34 deg of rotation drift over 120 frames; live 0.00032, ratio 2.40); 2
  // iterations per window and 8 dense keyframes at the start keep the ratio at 1.05-1.88 over
  // orbit seeds 1-5 (see LiveMapOptions::ba_iterations).
  checkLiveAgainstOffline(
      "--scene orbit --frames 150 --size 480x360 --focal 420 --target-wander 0.5 --quiet", 30, 2.0,
      true, "device-orbit");
}

TEST_CASE("Live poses on a replayed handheld clip are within 2x the offline solver",
          "[device][accuracy][slow]") {
  // The handheld walk is slow (5 mm a frame, 7 m from the scene): the offline solver needs about
  // 300 frames to find parallax, and the live map initialises at frame 80 (0.4 m of baseline).
  // Measured (Release, x86-64): live 0.00024, offline 0.00016 (ratio 1.52): the 2x holds.
  checkLiveAgainstOffline("--scene handheld --frames 300 --size 480x360 --focal 420 --quiet", 100,
                          2.0, false, "device-handheld");
}

namespace {

// Car-mounted, 10 Hz, forward motion (1.2 m a frame), given intrinsics. Measured (Release,
// x86-64): seq06 49 of 51 frames tracking, ATE 0.11 % of the path; highway 33 of 51, 0.60 %
// (the offline solver: 0.22 % and 1.40 %). The rotation is not checked: on a straight path a
// position-fitted similarity leaves the roll about it free (a constant 4-6 degrees on seq06).
void checkLiveOnKitti(const char* name, int min_tracking, double max_ate_rel) {
  const std::string seq = epitrack::test::sharedDataDir() + "/" + name;
  TempDir dir("device-real");
  std::string summary;
  const std::vector<epitrack::test::DeviceLine> lines = runDevice(seq, dir, summary);
  REQUIRE(lines.size() == 51);
  int tracking = 0, lost = 0;
  for (const auto& l : lines) {
    tracking += l.status == "tracking" ? 1 : 0;
    lost += l.status == "lost" ? 1 : 0;
  }
  std::vector<epitrack::hal::TrajectoryEntry> gt;
  std::string error;
  REQUIRE(epitrack::hal::readTrajectoryFile(seq + "/groundtruth.txt", gt, error));
  const auto live = evaluate(gt, epitrack::test::trackingTrajectory(lines));
  std::printf("device on %s: %d of 51 frames tracking, %d lost, ATE %.4f %% of the path\n", name,
              tracking, lost, 100.0 * live.ate_rmse_rel);
  CHECK(tracking >= min_tracking);
  CHECK(lost == 0);
  CHECK(live.ate_rmse_rel < max_ate_rel);
}

}  // namespace

// One test case per sequence: a missing sequence skips only its own case.
TEST_CASE("Live poses on the real KITTI seq06 excerpt follow the GPS/INS ground truth",
          "[device][accuracy][real]") {
  if (!epitrack::test::haveSharedSequence("kitti_seq06_excerpt")) return;
  checkLiveOnKitti("kitti_seq06_excerpt", 45, 0.003);
}

TEST_CASE("Live poses on the real KITTI highway excerpt follow the GPS/INS ground truth",
          "[device][accuracy][real]") {
  if (!epitrack::test::haveSharedSequence("kitti_highway_excerpt")) return;
  checkLiveOnKitti("kitti_highway_excerpt", 30, 0.012);
}

// Every frame twice (a capture loop faster than its source, pulldown, a driver repeating its last
// buffer; tools/vm's live KITTI check): the repeats must change nothing. Before the tracker kept
// repeated frames out of its filters (FeatureTrackerOptions::repeat_max_mean_diff_q8), each
// repeat halved every track's velocity, the next frame's prediction missed, and on seq06 the live
// map never initialised (0 of 102 frames tracking). Measured (Release, x86-64, 2026-12-03):
// 98 of 102 lines tracking, ATE 0.090 % of the path over the last line of each clip frame
// (each frame once: 49 of 51, 0.117 %).
TEST_CASE("Live poses on the real KITTI seq06 excerpt with every frame twice",
          "[device][accuracy][real]") {
  if (!epitrack::test::haveSharedSequence("kitti_seq06_excerpt")) return;
  namespace fs = std::filesystem;
  const std::string seq = epitrack::test::sharedDataDir() + "/kitti_seq06_excerpt";
  TempDir dir("device-repeated");
  const fs::path doubled = dir.file("seq");
  fs::create_directories(doubled / "frames");
  fs::copy_file(seq + "/intrinsics.txt", doubled / "intrinsics.txt");
  std::vector<fs::path> frames;
  for (const auto& e : fs::directory_iterator(seq + "/frames")) frames.push_back(e.path());
  std::sort(frames.begin(), frames.end());
  REQUIRE(frames.size() == 51);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    for (std::size_t r = 0; r < 2; ++r) {
      char name[32];
      std::snprintf(name, sizeof name, "%06zu.png", 2 * i + r);
      fs::copy_file(frames[i], doubled / "frames" / name);
    }
  }
  std::string summary;
  const std::vector<epitrack::test::DeviceLine> lines = runDevice(doubled.string(), dir, summary);
  REQUIRE(lines.size() == 102);
  int tracking = 0, lost = 0;
  std::vector<epitrack::test::DeviceLine> last_of_frame;  // the second line of each clip frame
  for (const auto& l : lines) {
    tracking += l.status == "tracking" ? 1 : 0;
    lost += l.status == "lost" ? 1 : 0;
    if (l.frame % 2 == 1) {
      last_of_frame.push_back(l);
      last_of_frame.back().frame = l.frame / 2;
    }
  }
  std::vector<epitrack::hal::TrajectoryEntry> gt;
  std::string error;
  REQUIRE(epitrack::hal::readTrajectoryFile(seq + "/groundtruth.txt", gt, error));
  const auto live = evaluate(gt, epitrack::test::trackingTrajectory(last_of_frame));
  std::printf(
      "device on kitti_seq06_excerpt, every frame twice: %d of 102 lines tracking, %d lost, "
      "ATE %.4f %% of the path over %d frames\n",
      tracking, lost, 100.0 * live.ate_rmse_rel, live.matched_frames);
  CHECK(tracking >= 90);
  CHECK(lost == 0);
  CHECK(live.matched_frames >= 45);
  CHECK(live.ate_rmse_rel < 0.003);
}

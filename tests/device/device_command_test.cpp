#include <catch2/catch.hpp>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <string>
#include <vector>

#include <sys/wait.h>
#include <unistd.h>

#include "firmware_like/device_config.hpp"
#include "hal/io/text_formats.hpp"
#include "tests/device/device_output.hpp"
#include "tests/support/test_support.hpp"

// epitrack-device as a command: configuration (read once, strict), the pose stream, the final
// statistics line, pacing with drops, and a clean stop on SIGINT/SIGTERM.

using epitrack::device::applyConfigText;
using epitrack::device::applyConfigValue;
using epitrack::device::DeviceConfig;
using epitrack::device::validateConfig;
using epitrack::test::binaryPath;
using epitrack::test::readWholeFile;
using epitrack::test::run;
using epitrack::test::TempDir;

namespace {

void writeText(const std::string& path, const std::string& text) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  REQUIRE(f != nullptr);
  std::fputs(text.c_str(), f);
  std::fclose(f);
}

/// A small rendered orbit shared by the command tests.
const std::string& smallClip() {
  static TempDir dir("device-cmd");
  static const std::string clip = [] {
    const std::string c = dir.file("clip");
    REQUIRE(run(binaryPath("tools/synth/epitrack-synth") +
                " --scene orbit --frames 60 --size 320x240 --focal 280 --target-wander 0.5 "
                "--out " +
                c + " 2>/dev/null") == 0);
    return c;
  }();
  return clip;
}

std::string device() { return binaryPath("firmware_like/epitrack-device"); }

}  // namespace

TEST_CASE("Device configuration: keys, values, files, cross checks", "[device][config]") {
  DeviceConfig c;
  std::string error;
  CHECK(applyConfigValue(c, "features", "200", error));
  CHECK(c.tracker.max_features == 200);
  CHECK(c.map.max_features == 200);
  CHECK(applyConfigValue(c, "realtime", "yes", error));
  CHECK(c.realtime);
  CHECK_FALSE(applyConfigValue(c, "no_such_key", "1", error));
  CHECK(error.find("unknown configuration key 'no_such_key'") != std::string::npos);
  CHECK_FALSE(applyConfigValue(c, "features", "lots", error));
  CHECK(error.find("features") != std::string::npos);
  CHECK_FALSE(applyConfigValue(c, "features", "5", error));  // below the range
  CHECK_FALSE(applyConfigValue(c, "window", "20", error));   // even
  CHECK_FALSE(applyConfigValue(c, "realtime", "maybe", error));
  CHECK_FALSE(applyConfigValue(c, "keyframe_parallax_deg", "nan", error));

  DeviceConfig f;
  CHECK(applyConfigText(f,
                        "# device\nsource = /dev/null\n  max_points = 5000  # more\n\n"
                        "ba_window=4\n",
                        "dev.conf", error));
  CHECK(f.source == "/dev/null");
  CHECK(f.map.max_points == 5000);
  CHECK(f.map.ba_window == 4);
  CHECK_FALSE(applyConfigText(f, "source /dev/null\n", "dev.conf", error));
  CHECK(error == "dev.conf:1: expected 'key = value'");
  CHECK_FALSE(applyConfigText(f, "\nfeaturez = 3\n", "dev.conf", error));
  CHECK(error.find("dev.conf:2: unknown configuration key 'featurez'") == 0);

  DeviceConfig v;
  CHECK_FALSE(validateConfig(v, error));  // no source
  v.source = "x";
  CHECK(validateConfig(v, error));
  v.map.ba_window = v.map.max_keyframes;  // window + fixed cameras exceed the keyframe ring
  CHECK_FALSE(validateConfig(v, error));
  v.map.ba_window = 5;
  v.map.max_points = 100;  // fewer than the features of one frame
  CHECK_FALSE(validateConfig(v, error));
  CHECK(error.find("max_points") != std::string::npos);
}

TEST_CASE("epitrack-device rejects bad usage with exit 2", "[device][cli]") {
  TempDir dir("device-usage");
  CHECK(run(device() + " --help > /dev/null") == 0);
  CHECK(run(device() + " 2>/dev/null") == 2);  // no source
  CHECK(run(device() + " --source x --bogus 1 2>/dev/null") == 2);
  CHECK(run(device() + " --source x --features many 2>/dev/null") == 2);
  CHECK(run(device() + " --source x --set nope=1 2>/dev/null") == 2);
  CHECK(run(device() + " --source x --record 2>/dev/null") == 2);  // no value
  writeText(dir.file("bad.conf"), "features = 300\nunknown_key = 1\n");
  CHECK(run(device() + " --source x --config " + dir.file("bad.conf") + " 2>/dev/null") == 2);
  writeText(dir.file("bad2.conf"), "max_points = -4\n");
  CHECK(run(device() + " --source x --config " + dir.file("bad2.conf") + " 2>/dev/null") == 2);
  CHECK(run(device() + " --source " + dir.file("missing") + " 2>/dev/null >/dev/null") == 2);
}

TEST_CASE("epitrack-device prints one pose line per frame and a final statistics line",
          "[device][cli]") {
  const std::string& clip = smallClip();
  TempDir dir("device-out");
  writeText(dir.file("dev.conf"), "# a device configuration\nsource = " + clip +
                                      "/frames\nintrinsics = " + clip +
                                      "/intrinsics.txt\nfeatures = 200\n");
  const std::string poses = dir.file("poses.jsonl");
  REQUIRE(run(device() + " --config " + dir.file("dev.conf") + " --max-frames 50 --poses " + poses +
              " 2>/dev/null") == 0);
  std::vector<epitrack::test::DeviceLine> lines;
  std::string summary;
  epitrack::test::parseDeviceOutput(readWholeFile(poses), lines, summary);
  REQUIRE(lines.size() == 50);
  int tracking = 0;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    CHECK(lines[i].frame == static_cast<long>(i));
    CHECK(lines[i].features > 0);
    CHECK(lines[i].features <= 200);
    CHECK(lines[i].ms > 0.0);
    if (lines[i].status == "tracking") {
      ++tracking;
      const double qn = lines[i].q[0] * lines[i].q[0] + lines[i].q[1] * lines[i].q[1] +
                        lines[i].q[2] * lines[i].q[2] + lines[i].q[3] * lines[i].q[3];
      CHECK(qn == Approx(1.0).epsilon(1e-6));
    }
  }
  CHECK(tracking > 30);
  // Each initializing line says why the map does not exist yet and how far it got (issue 20):
  // the first frame is the reference, the next ones wait for enough motion.
  REQUIRE(lines[0].status == "initializing");
  CHECK(lines[0].init_reason == "new-reference");
  int waiting_for_motion = 0;
  for (const auto& l : lines) {
    if (l.status != "initializing") {
      CHECK(l.init_reason.empty());
      continue;
    }
    CHECK(l.init_tracks == l.features);
    CHECK((l.init_reason == "new-reference" || l.init_reason == "too-few-tracks" ||
           l.init_reason == "too-little-motion" || l.init_reason == "no-two-view-geometry" ||
           l.init_reason == "too-few-points" || l.init_reason == "too-little-parallax"));
    if (l.init_reason == "too-little-motion") {
      ++waiting_for_motion;
      CHECK(l.init_common > 0);
      CHECK(l.init_common <= l.init_tracks);
      CHECK(l.init_displacement_px >= 0.0);
    }
    if (l.init_reason == "too-little-parallax") CHECK(l.init_parallax_deg > 0.0);
  }
  CHECK(waiting_for_motion > 0);
  CHECK(epitrack::test::jsonNumber(summary, "frames", -1) == 50);
  CHECK(epitrack::test::jsonNumber(summary, "tracked", -1) == tracking);
  CHECK(epitrack::test::jsonNumber(summary, "lost", -1) == 0);
  CHECK(epitrack::test::jsonNumber(summary, "dropped", -1) == 0);
  CHECK(epitrack::test::jsonNumber(summary, "ms_median", -1) > 0.0);
  CHECK(summary.find("\"stopped_by\": \"end\"") != std::string::npos);
  // Standard output is the default pose stream.
  const std::string stdout_file = dir.file("stdout.jsonl");
  REQUIRE(run(device() + " --source " + clip + "/frames --intrinsics " + clip +
              "/intrinsics.txt --max-frames 5 > " + stdout_file + " 2>/dev/null") == 0);
  lines.clear();
  epitrack::test::parseDeviceOutput(readWholeFile(stdout_file), lines, summary);
  CHECK(lines.size() == 5);
}

TEST_CASE("epitrack-device --realtime drops frames it cannot keep up with", "[device][cli]") {
  const std::string& clip = smallClip();
  TempDir dir("device-rt");
  const std::string poses = dir.file("poses.jsonl");
  // 2000 fps is far beyond the loop's rate: most frames arrive while the previous is processed.
  REQUIRE(run(device() + " --source " + clip + "/frames --intrinsics " + clip +
              "/intrinsics.txt --realtime --set fps=2000 --poses " + poses + " 2>/dev/null") == 0);
  std::vector<epitrack::test::DeviceLine> lines;
  std::string summary;
  epitrack::test::parseDeviceOutput(readWholeFile(poses), lines, summary);
  const double dropped = epitrack::test::jsonNumber(summary, "dropped", -1);
  CHECK(dropped > 0);
  CHECK(static_cast<double>(lines.size()) + dropped == 60);
  // At a pace the loop keeps up with (4 fps: 250 ms a frame, even on a loaded machine) nothing
  // is dropped.
  REQUIRE(run(device() + " --source " + clip + "/frames --intrinsics " + clip +
              "/intrinsics.txt --realtime --set fps=4 --max-frames 8 --poses " + poses +
              " 2>/dev/null") == 0);
  lines.clear();
  epitrack::test::parseDeviceOutput(readWholeFile(poses), lines, summary);
  CHECK(lines.size() == 8);
  CHECK(epitrack::test::jsonNumber(summary, "dropped", -1) == 0);
}

TEST_CASE("epitrack-device stops cleanly on SIGINT and SIGTERM", "[device][cli]") {
  const std::string& clip = smallClip();
  TempDir dir("device-sig");
  for (const int sig : {SIGINT, SIGTERM}) {
    const std::string poses = dir.file("poses" + std::to_string(sig) + ".jsonl");
    const std::string bin = std::string(EPITRACK_BINARY_DIR) + "/firmware_like/epitrack-device";
    const std::string source = clip + "/frames";
    const std::string intr = clip + "/intrinsics.txt";
    const pid_t pid = ::fork();
    REQUIRE(pid >= 0);
    if (pid == 0) {
      // Paced replay at 30 fps: 60 frames take two seconds, the signal comes first.
      ::execl(bin.c_str(), bin.c_str(), "--source", source.c_str(), "--intrinsics", intr.c_str(),
              "--realtime", "--poses", poses.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    // Signal once a few pose lines are out (the handlers are installed before the first frame),
    // however slow a loaded machine makes the start.
    for (int waited_ms = 0; waited_ms < 20000; waited_ms += 20) {
      const std::string so_far = readWholeFile(poses);
      if (std::count(so_far.begin(), so_far.end(), '\n') >= 4) break;
      ::usleep(20 * 1000);
    }
    ::kill(pid, sig);
    int status = 0;
    REQUIRE(::waitpid(pid, &status, 0) == pid);
    REQUIRE(WIFEXITED(status));
    CHECK(WEXITSTATUS(status) == 0);
    std::vector<epitrack::test::DeviceLine> lines;
    std::string summary;
    epitrack::test::parseDeviceOutput(readWholeFile(poses), lines, summary);
    CHECK(lines.size() > 3);
    CHECK(lines.size() < 60);
    CHECK(epitrack::test::jsonNumber(summary, "frames", -1) == static_cast<double>(lines.size()));
    CHECK(summary.find(sig == SIGINT ? "\"stopped_by\": \"SIGINT\""
                                     : "\"stopped_by\": \"SIGTERM\"") != std::string::npos);
  }
}

TEST_CASE("epitrack-device --record writes the frames: replaying them gives the same poses",
          "[device][cli]") {
  const std::string& clip = smallClip();
  TempDir dir("device-rec");
  const std::string args = " --intrinsics " + clip + "/intrinsics.txt --max-frames 40";
  const std::string live = dir.file("live.jsonl");
  const std::string replay = dir.file("replay.jsonl");
  // A directory recording is lossless (PGM): the replay must reproduce every pose exactly.
  REQUIRE(run(device() + " --source " + clip + "/frames" + args + " --record " + dir.file("rec") +
              " --poses " + live + " 2>/dev/null") == 0);
  REQUIRE(run(device() + " --source " + dir.file("rec") + args + " --poses " + replay +
              " 2>/dev/null") == 0);
  std::vector<epitrack::test::DeviceLine> a, b;
  std::string summary_a, summary_b;
  epitrack::test::parseDeviceOutput(readWholeFile(live), a, summary_a);
  epitrack::test::parseDeviceOutput(readWholeFile(replay), b, summary_b);
  REQUIRE(a.size() == 40);
  REQUIRE(b.size() == a.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    CHECK(a[i].status == b[i].status);
    CHECK(a[i].features == b[i].features);
    for (int k = 0; k < 3; ++k) CHECK(a[i].p[k] == b[i].p[k]);
    for (int k = 0; k < 4; ++k) CHECK(a[i].q[k] == b[i].q[k]);
  }
  // An .mjpeg recording (re-encoded JPEG) replays as many frames and still tracks.
  const std::string mjpeg = dir.file("rec.mjpeg");
  REQUIRE(run(device() + " --source " + clip + "/frames" + args + " --record " + mjpeg +
              " --poses " + live + " 2>/dev/null") == 0);
  REQUIRE(run(device() + " --source " + mjpeg + args + " --poses " + replay + " 2>/dev/null") == 0);
  b.clear();
  epitrack::test::parseDeviceOutput(readWholeFile(replay), b, summary_b);
  CHECK(b.size() == 40);
  CHECK(epitrack::test::jsonNumber(summary_b, "tracked", -1) > 20);
  // An unwritable recording target named on the command line is refused before the first frame
  // (exit 2, issue 9: unusable paths given on the command line are usage errors).
  CHECK(run(device() + " --source " + clip + "/frames" + args + " --record /proc/nope.mjpeg" +
            " --poses " + live + " 2>/dev/null") == 2);
}

TEST_CASE("epitrack-device readout_ms: a rolling-shutter clip tracked with its readout",
          "[device][cli][rolling-shutter][slow]") {
  // A fast orbit (0.75 deg per frame) read out over 30 ms of its 33 ms frames (issue 27 item 5).
  TempDir dir("device-rs");
  const std::string clip = dir.file("clip");
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") +
              " --scene orbit --orbit-speed 0.75 --target-wander 1 --frames 60 --size 320x240 "
              "--focal 280 --rolling-shutter 30ms --out " +
              clip + " 2>/dev/null") == 0);
  const std::string source =
      " --source " + clip + "/frames --intrinsics " + clip + "/intrinsics.txt";
  // A readout longer than a frame interval (30 fps: 33.3 ms) is refused.
  CHECK(run(device() + source + " --set readout_ms=40 > /dev/null 2> " + dir.file("err.txt")) == 2);
  CHECK(readWholeFile(dir.file("err.txt")).find("longer than a frame interval") !=
        std::string::npos);
  // The live track with and without the readout, scored against the truth (middle-row poses).
  double ate[2] = {0.0, 0.0};
  int tracked[2] = {0, 0};
  for (const int readout_ms : {0, 30}) {
    const int i = readout_ms > 0 ? 1 : 0;
    const std::string poses = dir.file("poses_" + std::to_string(readout_ms) + ".jsonl");
    REQUIRE(run(device() + source + " --set readout_ms=" + std::to_string(readout_ms) +
                " --poses " + poses + " 2>/dev/null") == 0);
    std::vector<epitrack::test::DeviceLine> lines;
    std::string summary;
    epitrack::test::parseDeviceOutput(readWholeFile(poses), lines, summary);
    std::string tum;
    for (const auto& l : lines) {
      if (l.status != "tracking") continue;
      char row[256];
      std::snprintf(row, sizeof(row), "%ld %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", l.frame, l.p[0],
                    l.p[1], l.p[2], l.q[0], l.q[1], l.q[2], l.q[3]);
      tum += row;
      ++tracked[i];
    }
    const std::string tum_path = dir.file("live_" + std::to_string(readout_ms) + ".tum");
    writeText(tum_path, tum);
    const std::string eval = dir.file("eval_" + std::to_string(readout_ms) + ".json");
    REQUIRE(run(binaryPath("tools/eval/epitrack-eval") + " --gt " + clip +
                "/groundtruth.txt --est " + tum_path + " > " + eval) == 0);
    ate[i] = epitrack::test::jsonNumber(readWholeFile(eval), "ate_rmse_rel", -1.0);
  }
  std::printf(
      "device, rolling-shutter fast orbit 320x240: live ATE %.5f %% (%d frames tracking) "
      "without the readout, %.5f %% (%d) with readout_ms=30\n",
      100.0 * ate[0], tracked[0], 100.0 * ate[1], tracked[1]);
  CHECK(tracked[1] >= 55);
  CHECK(tracked[1] >= tracked[0]);
  CHECK(ate[1] > 0.0);
  // Measured 0.118 % -> 0.057 % here (2026-12-03); on a longer, larger clip of the same motion
  // the gain vanishes (docs/device.md, rolling shutter).
  CHECK(ate[1] < 0.8 * ate[0]);
}

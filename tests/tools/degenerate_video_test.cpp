#include <catch2/catch.hpp>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "algo/image/image.hpp"
#include "algo/math/random.hpp"
#include "hal/io/file_util.hpp"
#include "hal/io/image_codec.hpp"
#include "hal/io/text_formats.hpp"
#include "tests/support/test_support.hpp"

// Degenerate and damaged video through epitrack-solve (issue 9): each gives a defined result (a
// solve, a tripod solve or a clear status in summary.json), never a crash, a hang or a NaN.

using epitrack::Image;
using epitrack::test::binaryPath;
using epitrack::test::jsonNumber;
using epitrack::test::jsonString;
using epitrack::test::readWholeFile;
using epitrack::test::run;
using epitrack::test::TempDir;

namespace {

std::string synth(const TempDir& dir, const std::string& name, const std::string& args) {
  const std::string clip = dir.file(name);
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") + " " + args +
              " --size 320x240 --focal 280 --out " + clip + " 2>/dev/null") == 0);
  return clip;
}

std::string frameName(const std::string& dir, int i) {
  char name[32];
  std::snprintf(name, sizeof(name), "/%06d.pgm", i);
  return dir + name;
}

struct Outcome {
  int exit_code = -1;
  std::string summary;
  std::string status;
};

// Runs epitrack-solve and checks what every outcome must satisfy: a summary.json without NaN
// whenever the clip could be read, and no NaN in the camera track.
Outcome solve(const TempDir& dir, const std::string& input, const std::string& args = "") {
  static int counter = 0;
  const std::string out = dir.file("out" + std::to_string(counter++));
  Outcome o;
  o.exit_code = run(binaryPath("tools/solve/epitrack-solve") + " " + input + " --out " + out +
                    " --quiet " + args + " 2>" + out + ".err");
  o.summary = readWholeFile(out + "/summary.json");
  o.status = jsonString(o.summary, "status");
  INFO("stderr: " << readWholeFile(out + ".err") << "\nsummary: " << o.summary.substr(0, 400));
  for (const char* bad : {": nan", ": -nan", ": inf", ": -inf", ": NaN"})
    CHECK(o.summary.find(bad) == std::string::npos);
  const std::string cams = readWholeFile(out + "/cameras.tum");
  CHECK(cams.find("nan") == std::string::npos);
  CHECK(o.exit_code >= 0);
  CHECK(o.exit_code <= 2);
  return o;
}

}  // namespace

TEST_CASE("A blank clip ends with too-few-features, pure noise solves nothing",
          "[solve][degenerate]") {
  TempDir dir("degenerate");
  const std::string blank = dir.file("blank"), noise = dir.file("noise");
  std::string error;
  REQUIRE(epitrack::hal::makeDirectories(blank, error));
  REQUIRE(epitrack::hal::makeDirectories(noise, error));
  Image<uint8_t> img(320, 240);
  epitrack::SplitMix64 rng(7);
  for (int i = 0; i < 20; ++i) {
    for (int y = 0; y < 240; ++y)
      for (int x = 0; x < 320; ++x) img.view()(x, y) = 128;
    REQUIRE(epitrack::hal::writePgm(frameName(blank, i), img.view(), error));
    for (int y = 0; y < 240; ++y)
      for (int x = 0; x < 320; ++x) img.view()(x, y) = static_cast<uint8_t>(rng.next() >> 56);
    REQUIRE(epitrack::hal::writePgm(frameName(noise, i), img.view(), error));
  }
  const Outcome b = solve(dir, blank);
  CHECK(b.exit_code == 1);
  CHECK(b.status == "too-few-features");
  CHECK(jsonNumber(b.summary, "solved_frames") == 0);
  // Noise: whatever the tracker makes of it, no geometry may come out of it.
  const Outcome n = solve(dir, noise);
  CHECK(n.exit_code == 1);
  CHECK((n.status == "too-few-features" || n.status == "no-motion" ||
         n.status == "initialization-failed"));
  CHECK(jsonNumber(n.summary, "solved_frames") == 0);
}

TEST_CASE("A static camera and a two-frame clip end with no-motion", "[solve][degenerate]") {
  TempDir dir("degenerate");
  const std::string clip = synth(dir, "hh", "--scene handheld --frames 2");
  const std::string still = dir.file("still");
  std::string error;
  REQUIRE(epitrack::hal::makeDirectories(still, error));
  std::vector<uint8_t> bytes;
  REQUIRE(epitrack::hal::readFileInto(frameName(clip + "/frames", 0), bytes, error));
  for (int i = 0; i < 25; ++i)
    REQUIRE(epitrack::hal::writeFileAtomic(frameName(still, i), bytes.data(), bytes.size(), error));
  for (const auto& input : {still, clip + "/frames"}) {
    const Outcome o = solve(dir, input);
    CHECK(o.exit_code == 1);
    CHECK(o.status == "no-motion");
  }
}

TEST_CASE("Pure rotation gives a tripod solve and a single plane asks for the focal",
          "[solve][degenerate]") {
  TempDir dir("degenerate");
  const std::string pan = synth(dir, "pan", "--scene pan --frames 60");
  const Outcome rot = solve(dir, pan + "/frames");
  CHECK(rot.exit_code == 0);
  CHECK(rot.status == "rotation-only");
  CHECK(std::abs(jsonNumber(rot.summary, "focal_px") / 280.0 - 1.0) < 0.03);
  CHECK(jsonNumber(rot.summary, "solved_frames") == 60);

  const std::string plane = synth(dir, "plane", "--scene planar --frames 60");
  const Outcome unknown_focal = solve(dir, plane + "/frames");
  CHECK(unknown_focal.exit_code == 1);
  CHECK(unknown_focal.status == "planar-scene");
  const Outcome given_focal = solve(dir, plane + "/frames", "--focal 280");
  CHECK(given_focal.exit_code == 0);
  CHECK(given_focal.status == "ok");
  CHECK(jsonNumber(given_focal.summary, "solved_frames") == 60);
}

TEST_CASE("Extreme motion blur gives a defined status", "[solve][degenerate][slow]") {
  TempDir dir("degenerate");
  const std::string clip = synth(dir, "blur", "--scene handheld --frames 40 --blur 6");
  const Outcome o = solve(dir, clip + "/frames");
  // Either solved or refused with a status: never a crash or NaN (checked in solve()).
  CHECK((o.status == "ok" || o.status == "no-motion" || o.status == "too-few-features" ||
         o.status == "initialization-failed"));
  CHECK(o.exit_code == (o.status == "ok" ? 0 : 1));
}

TEST_CASE("Corrupt JPEG frames in an MJPEG clip are skipped and counted, the rest solved",
          "[solve][degenerate]") {
  TempDir dir("degenerate");
  const std::string clip = synth(dir, "orbit", "--scene orbit --target-wander 0.5 --frames 80");
  std::vector<uint8_t> mjpeg, jpeg;
  std::string error;
  epitrack::hal::GrayImageDecoder decoder;
  Image<uint8_t> frame;
  for (int i = 0; i < 80; ++i) {
    REQUIRE(decoder.decodeFile(frameName(clip + "/frames", i), frame, error));
    const std::string tmp = dir.file("f.jpg");
    REQUIRE(epitrack::hal::writeJpegGray(tmp, frame.view(), 95, error));
    REQUIRE(epitrack::hal::readFileInto(tmp, jpeg, error));
    if (i >= 30 && i < 35) {
      // A run of damaged frames: a valid start of image, then garbage instead of the scan.
      for (std::size_t k = 200; k < jpeg.size() - 2; ++k)
        jpeg[k] = static_cast<uint8_t>((k * 37) & 0x7f);
    }
    mjpeg.insert(mjpeg.end(), jpeg.begin(), jpeg.end());
  }
  const std::string path = dir.file("clip.mjpeg");
  REQUIRE(epitrack::hal::writeFileAtomic(path, mjpeg.data(), mjpeg.size(), error));
  // The frames' handling is tested here, not the solve (as in the size-change test below).
  const Outcome o = solve(dir, path, "--focal 280" + epitrack::test::liveFeatureBudgetOption());
  CHECK(o.exit_code == 0);
  CHECK(o.status == "ok");
  CHECK(jsonNumber(o.summary, "frames") == 75);
  CHECK(jsonNumber(o.summary, "skipped_frames") == 5);
  CHECK(jsonNumber(o.summary, "solved_frames") >= 70);
}

TEST_CASE("A size change mid-stream solves the frames before it and says why it stopped",
          "[solve][degenerate]") {
  TempDir dir("degenerate");
  const std::string clip = synth(dir, "hh", "--scene handheld --frames 60");
  const std::string other = dir.file("other");
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") +
              " --scene handheld --frames 1 --size 330x240 --out " + other + " 2>/dev/null") == 0);
  std::vector<uint8_t> bytes;
  std::string error;
  REQUIRE(epitrack::hal::readFileInto(frameName(other + "/frames", 0), bytes, error));
  REQUIRE(epitrack::hal::writeFileAtomic(frameName(clip + "/frames", 60), bytes.data(),
                                         bytes.size(), error));
  const Outcome o =
      solve(dir, clip + "/frames", "--focal 280" + epitrack::test::liveFeatureBudgetOption());
  CHECK(o.exit_code == 1);
  CHECK(o.status == "ok");
  CHECK(jsonNumber(o.summary, "frames") == 60);
  CHECK(o.summary.find("330x240") != std::string::npos);
}

TEST_CASE("A frame size beyond the memory limit is refused up front", "[solve][degenerate]") {
  TempDir dir("degenerate");
  const std::string path = dir.file("big.y4m");
  std::string y4m = "YUV4MPEG2 W4000 H3000 F30:1 Cmono\nFRAME\n";
  y4m.append(static_cast<std::size_t>(4000) * 3000, '\x80');
  std::string error;
  REQUIRE(epitrack::hal::writeFileAtomic(path, y4m.data(), y4m.size(), error));
  const std::string out = dir.file("big");
  const std::string err = dir.file("big.err");
  CHECK(run(binaryPath("tools/solve/epitrack-solve") + " " + path + " --out " + out +
            " --quiet --max-memory 64 2>" + err) == 1);
  CHECK(readWholeFile(err).find("above the limit of 64 MiB") != std::string::npos);
}

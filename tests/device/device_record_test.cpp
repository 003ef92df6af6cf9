#include <catch2/catch.hpp>

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include <unistd.h>

#include "firmware_like/pose_output.hpp"
#include "hal/replay/jpeg_stream.hpp"
#include "tests/device/device_output.hpp"
#include "tests/support/test_support.hpp"

// epitrack-device --record and the pose lines' `record_frame`: a pose line names its frame's
// number in the recording, so the frames the live loop processed can be picked out of a
// recording that also holds the frames it dropped, and replayed alone to the same poses.

using epitrack::test::binaryPath;
using epitrack::test::DeviceLine;
using epitrack::test::jsonNumber;
using epitrack::test::readWholeFile;
using epitrack::test::run;
using epitrack::test::TempDir;

namespace {

std::string device() { return binaryPath("firmware_like/epitrack-device"); }

void writeBytes(const std::string& path, const std::string& bytes) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  REQUIRE(f != nullptr);
  REQUIRE(std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size());
  REQUIRE(std::fclose(f) == 0);
}

/// The JPEGs of an .mjpeg stream, split by their own marker structure.
std::vector<std::string> splitMjpeg(const std::string& stream) {
  std::vector<std::string> frames;
  const auto* data = reinterpret_cast<const uint8_t*>(stream.data());
  std::size_t pos = 0;
  while (pos < stream.size()) {
    std::size_t length = 0;
    REQUIRE(epitrack::hal::measureJpeg(data + pos, stream.size() - pos, length) ==
            epitrack::hal::JpegExtent::kComplete);
    frames.push_back(stream.substr(pos, length));
    pos += length;
  }
  return frames;
}

std::string recordedFrame(const std::string& dir, long number) {
  char name[32];
  std::snprintf(name, sizeof(name), "/%06ld.pgm", number);
  return dir + name;
}

/// Pose lines and the summary of a pose file.
std::vector<DeviceLine> readPoses(const std::string& path, std::string& summary) {
  std::vector<DeviceLine> lines;
  epitrack::test::parseDeviceOutput(readWholeFile(path), lines, summary);
  return lines;
}

/// The `record_frame` of each line of a pose file, in order (-1 where it is absent).
std::vector<long> recordFrames(const std::string& path) {
  std::vector<long> out;
  const std::string text = readWholeFile(path);
  std::size_t pos = 0;
  while (pos < text.size()) {
    auto nl = text.find('\n', pos);
    if (nl == std::string::npos) nl = text.size();
    const std::string line = text.substr(pos, nl - pos);
    pos = nl + 1;
    if (line.empty() || line.find("\"summary\"") != std::string::npos) continue;
    out.push_back(static_cast<long>(jsonNumber(line, "record_frame", -1)));
  }
  return out;
}

}  // namespace

TEST_CASE("Pose line: record_frame follows frame when recording, absent otherwise",
          "[device][record]") {
  char line[512];
  const epitrack::PoseCw pose;
  int n = epitrack::device::formatPoseLine(line, sizeof(line), 41, 37, 1.366667,
                                           epitrack::LiveStatus::kTracking, 250, pose, 2.5);
  REQUIRE(n > 0);
  REQUIRE(static_cast<std::size_t>(n) < sizeof(line));
  std::string text(line, static_cast<std::size_t>(n));
  CHECK(text.rfind("{\"frame\": 41, \"record_frame\": 37, \"t\": 1.366667, ", 0) == 0);
  CHECK(text.back() == '\n');
  CHECK(jsonNumber(text, "frame") == 41.0);
  CHECK(jsonNumber(text, "record_frame") == 37.0);
  CHECK(jsonNumber(text, "features") == 250.0);
  n = epitrack::device::formatPoseLine(line, sizeof(line), 41, -1, 1.366667,
                                       epitrack::LiveStatus::kInitializing, 250, pose, 2.5);
  REQUIRE(n > 0);
  text.assign(line, static_cast<std::size_t>(n));
  CHECK(text.rfind("{\"frame\": 41, \"t\": 1.366667, \"status\": \"initializing\", ", 0) == 0);
  CHECK(text.find("record_frame") == std::string::npos);
}

TEST_CASE("epitrack-device --record: record_frame names each pose line's recorded frame",
          "[device][record][cli]") {
  TempDir dir("device-recnum");
  const std::string clip = dir.file("clip");
  REQUIRE(run(binaryPath("tools/synth/epitrack-synth") +
              " --scene orbit --frames 30 --size 320x240 --focal 280 --target-wander 0.5 --out " +
              clip + " 2>/dev/null") == 0);
  const std::string args = " --intrinsics " + clip + "/intrinsics.txt";
  // An MJPEG take of the clip, then its frame 10 damaged (a JPEG with no image: SOI, EOI): the
  // source still gives that frame its number, so the source's numbers have a gap at 10, the
  // corrupt frame is neither processed nor recorded, and the recording's numbers run one behind
  // from there on.
  const std::string take = dir.file("take.mjpeg");
  REQUIRE(run(device() + " --source " + clip + "/frames" + args + " --record " + take +
              " --poses /dev/null 2>/dev/null") == 0);
  std::vector<std::string> jpegs = splitMjpeg(readWholeFile(take));
  REQUIRE(jpegs.size() == 30);
  constexpr long kDamaged = 10;
  jpegs[kDamaged] = std::string("\xFF\xD8\xFF\xD9", 4);
  std::string damaged_stream;
  for (const auto& j : jpegs) damaged_stream += j;
  const std::string damaged = dir.file("damaged.mjpeg");
  writeBytes(damaged, damaged_stream);

  // Every frame processed (a replay without --realtime drops nothing).
  const std::string all_rec = dir.file("rec-all");
  const std::string all_poses = dir.file("all.jsonl");
  REQUIRE(run(device() + " --source " + damaged + args + " --record " + all_rec + " --poses " +
              all_poses + " 2>/dev/null") == 0);
  std::string summary;
  const std::vector<DeviceLine> all = readPoses(all_poses, summary);
  const std::vector<long> all_numbers = recordFrames(all_poses);
  REQUIRE(all.size() == 29);
  REQUIRE(all_numbers.size() == all.size());
  CHECK(jsonNumber(summary, "corrupt") == 1.0);
  for (std::size_t i = 0; i < all.size(); ++i) {
    const long expected_frame = static_cast<long>(i) + (static_cast<long>(i) < kDamaged ? 0 : 1);
    CHECK(all[i].frame == expected_frame);
    CHECK(all_numbers[i] == static_cast<long>(i));  // the recording has no gap
  }
  CHECK(::access(recordedFrame(all_rec, 28).c_str(), F_OK) == 0);
  CHECK(::access(recordedFrame(all_rec, 29).c_str(), F_OK) != 0);
  // The recorded frame a line names is the frame that line was computed from: replaying the
  // recording reproduces every pose exactly, its `frame` being the line's `record_frame`.
  const std::string replay_poses = dir.file("replay-all.jsonl");
  REQUIRE(run(device() + " --source " + all_rec + args + " --poses " + replay_poses +
              " 2>/dev/null") == 0);
  const std::vector<DeviceLine> replay = readPoses(replay_poses, summary);
  REQUIRE(replay.size() == all.size());
  for (std::size_t i = 0; i < all.size(); ++i) {
    CHECK(replay[i].frame == all_numbers[i]);
    CHECK(replay[i].status == all[i].status);
    CHECK(replay[i].features == all[i].features);
    for (int k = 0; k < 3; ++k) CHECK(replay[i].p[k] == all[i].p[k]);
    for (int k = 0; k < 4; ++k) CHECK(replay[i].q[k] == all[i].q[k]);
  }
  CHECK(jsonNumber(summary, "tracked") > 10);

  // Paced faster than the loop keeps up with (400 fps): frames are dropped, yet all recorded.
  // The frames the pose lines name, replayed alone and in order, give the same poses: the live
  // loop's result depends on the frames it processed and nothing else (no clock, no thread).
  const std::string paced_rec = dir.file("rec-paced");
  const std::string paced_poses = dir.file("paced.jsonl");
  REQUIRE(run(device() + " --source " + damaged + args + " --realtime --set fps=400 --record " +
              paced_rec + " --poses " + paced_poses + " 2>/dev/null") == 0);
  const std::vector<DeviceLine> paced = readPoses(paced_poses, summary);
  const std::vector<long> paced_numbers = recordFrames(paced_poses);
  REQUIRE(!paced.empty());
  REQUIRE(paced_numbers.size() == paced.size());
  const double dropped = jsonNumber(summary, "dropped");
  INFO("paced: " << paced.size() << " frames processed, summary " << summary);
  // The source gap at the damaged frame counts as one drop; pacing adds the rest.
  CHECK(dropped == static_cast<double>(29 - paced.size()) + 1.0);
  for (long n = 0; n < 29; ++n) {  // the recording is independent of the dropping
    CHECK(readWholeFile(recordedFrame(paced_rec, n)) == readWholeFile(recordedFrame(all_rec, n)));
  }
  const std::string picked = dir.file("picked");
  REQUIRE(run("mkdir -p " + picked) == 0);
  for (std::size_t i = 0; i < paced.size(); ++i) {
    REQUIRE(paced_numbers[i] >= 0);
    if (i > 0) CHECK(paced_numbers[i] > paced_numbers[i - 1]);
    // record_frame and frame differ by the damaged frame only (the recording has no gap).
    CHECK(paced[i].frame == paced_numbers[i] + (paced_numbers[i] < kDamaged ? 0 : 1));
    REQUIRE(::symlink(recordedFrame(paced_rec, paced_numbers[i]).c_str(),
                      recordedFrame(picked, static_cast<long>(i)).c_str()) == 0);
  }
  const std::string picked_poses = dir.file("picked.jsonl");
  REQUIRE(run(device() + " --source " + picked + args + " --poses " + picked_poses +
              " 2>/dev/null") == 0);
  const std::vector<DeviceLine> again = readPoses(picked_poses, summary);
  REQUIRE(again.size() == paced.size());
  for (std::size_t i = 0; i < paced.size(); ++i) {
    CHECK(again[i].status == paced[i].status);
    CHECK(again[i].features == paced[i].features);
    for (int k = 0; k < 3; ++k) CHECK(again[i].p[k] == paced[i].p[k]);
    for (int k = 0; k < 4; ++k) CHECK(again[i].q[k] == paced[i].q[k]);
  }
}

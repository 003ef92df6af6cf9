// SIGINT/SIGTERM during epitrack-solve and epitrack-track (issue 9 "No data lost"): the commands
// are started for real with a Y4M clip on a pipe as standard input, signalled while they work, and
// must leave a valid summary.json (solve) or a complete tracks.csv (track), no temporary file, and
// exit with 128 + the signal. Also: an output directory holding a solve is refused without
// --force and left untouched.

#include <algorithm>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <catch2/catch.hpp>

#include "hal/io/file_util.hpp"
#include "hal/io/tracks_csv.hpp"
#include "tests/support/process.hpp"
#include "tests/support/test_support.hpp"
#include "tools/synth/synthetic_sequence.hpp"

namespace {

using epitrack::test::binaryPath;
using epitrack::test::jsonNumber;
using epitrack::test::jsonString;
using epitrack::test::readWholeFile;
using epitrack::test::shellQuote;
using epitrack::test::SpawnedCommand;
using epitrack::test::TempDir;
namespace fs = std::filesystem;

constexpr int kWidth = 320;
constexpr int kHeight = 240;  // 76.8 kB a frame: more than a pipe's 64 KiB buffer

// A rendered orbit as Y4M (mono): the header, then "FRAME\n" + luma per frame.
struct Y4mClip {
  std::string header;
  std::vector<std::string> frames;
};

const Y4mClip& orbitClip() {
  static const Y4mClip clip = [] {
    epitrack::synth::SynthOptions o;
    o.kind = epitrack::synth::SceneKind::kOrbit;
    o.frames = 90;
    o.width = kWidth;
    o.height = kHeight;
    o.focal = 280.0;
    o.target_wander = 0.5;
    o.seed = 5;
    const epitrack::synth::SyntheticSequence seq(o);
    epitrack::synth::FrameRenderer renderer(seq);
    Y4mClip c;
    // (appended, not a literal + std::string sum: GCC 12's -Wrestrict misfires on that in the
    // armhf build)
    c.header = "YUV4MPEG2 W";
    c.header += std::to_string(kWidth) + " H" + std::to_string(kHeight) + " F30:1 Ip A1:1 Cmono\n";
    epitrack::Image<uint8_t> image;
    for (int f = 0; f < o.frames; ++f) {
      renderer.render(f, image);
      std::string frame = "FRAME\n";
      for (int y = 0; y < kHeight; ++y)
        frame.append(reinterpret_cast<const char*>(image.row(y)), static_cast<std::size_t>(kWidth));
      c.frames.push_back(std::move(frame));
    }
    return c;
  }();
  return clip;
}

// Every file below `dir`, relative, sorted.
std::vector<std::string> filesBelow(const std::string& dir) {
  std::vector<std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_regular_file()) files.push_back(fs::relative(e.path(), dir).string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

bool anyTemporary(const std::vector<std::string>& files) {
  return std::any_of(files.begin(), files.end(),
                     [](const std::string& f) { return f.find(".tmp") != std::string::npos; });
}

// The "files" array of summary.json.
std::vector<std::string> jsonFiles(const std::string& json) {
  std::vector<std::string> files;
  const auto p = json.find("\"files\": [");
  if (p == std::string::npos) return files;
  const auto end = json.find(']', p);
  std::size_t q = p + 10;
  while (true) {
    const auto a = json.find('"', q);
    if (a == std::string::npos || a > end) break;
    const auto b = json.find('"', a + 1);
    files.push_back(json.substr(a + 1, b - a - 1));
    q = b + 1;
  }
  return files;
}

// A minimal structural check of JSON: balanced brackets outside strings, nothing after the end,
// no NaN/inf tokens.
bool looksLikeJson(const std::string& json) {
  int depth = 0;
  bool in_string = false;
  std::size_t end = std::string::npos;
  for (std::size_t i = 0; i < json.size(); ++i) {
    const char c = json[i];
    if (in_string) {
      if (c == '\\')
        ++i;
      else if (c == '"')
        in_string = false;
      continue;
    }
    if (c == '"') in_string = true;
    if (c == '{' || c == '[') ++depth;
    if (c == '}' || c == ']') {
      if (--depth < 0) return false;
      if (depth == 0) {
        end = i;
        break;
      }
    }
  }
  if (end == std::string::npos || depth != 0) return false;
  for (std::size_t i = end + 1; i < json.size(); ++i)
    if (json[i] != '\n' && json[i] != ' ') return false;
  return json.find("nan") == std::string::npos && json.find("inf") == std::string::npos;
}

// Checks what every interrupted solve must leave: a valid summary.json saying "interrupted" that
// lists exactly the other files present, none of them temporary.
void checkInterruptedSolve(const std::string& out, const std::string& signal_name) {
  const std::string summary = readWholeFile(out + "/summary.json");
  INFO(summary.substr(0, 600));
  REQUIRE(looksLikeJson(summary));
  CHECK(jsonString(summary, "status") == "interrupted");
  CHECK(jsonString(summary, "signal") == signal_name);
  CHECK_FALSE(jsonString(summary, "stage").empty());
  const auto present = filesBelow(out);
  CHECK_FALSE(anyTemporary(present));
  std::vector<std::string> listed = jsonFiles(summary);
  listed.push_back("summary.json");
  std::sort(listed.begin(), listed.end());
  CHECK(listed == present);
}

// Feeds `command` the clip's header and first `frames` frames, then sends `sig` and closes its
// input. Each write returns once the command has read all but a pipe buffer (< 1 frame) of it, so
// the command is then working on frame `frames - 1` or later, or blocked reading the next; the
// signal is delivered before the blocked read ends. Returns the exit code.
int interruptAfterFrames(SpawnedCommand& command, const Y4mClip& clip, int frames, int sig) {
  REQUIRE(command.started());
  REQUIRE(command.writeInput(clip.header.data(), clip.header.size()));
  for (int f = 0; f < frames; ++f)
    REQUIRE(command.writeInput(clip.frames[static_cast<std::size_t>(f)].data(),
                               clip.frames[static_cast<std::size_t>(f)].size()));
  REQUIRE(command.signal(sig));
  command.closeInput();
  return command.wait();
}

}  // namespace

TEST_CASE("SIGINT while epitrack-solve tracks leaves only a summary.json saying so",
          "[solve][interrupt]") {
  const Y4mClip& clip = orbitClip();
  TempDir dir("interrupt-solve");
  const std::string out = dir.file("solve");
  SpawnedCommand solve(binaryPath("tools/solve/epitrack-solve") + " - --out " + shellQuote(out) +
                           epitrack::test::liveFeatureBudgetOption() + " --quiet",
                       dir.file("stderr.txt"));
  constexpr int kFramesSent = 30;
  const int exit_code = interruptAfterFrames(solve, clip, kFramesSent, SIGINT);
  INFO(solve.stderrText());
  CHECK(exit_code == 130);
  checkInterruptedSolve(out, "SIGINT");
  const std::string summary = readWholeFile(out + "/summary.json");
  CHECK(jsonString(summary, "stage") == "tracking");
  CHECK(jsonNumber(summary, "frames") >= kFramesSent - 1);
  CHECK(jsonNumber(summary, "frames") <= kFramesSent);
  CHECK(jsonNumber(summary, "solved_frames") == 0);
  CHECK(filesBelow(out) == std::vector<std::string>{"summary.json"});
  // One line on stderr says so.
  CHECK(solve.stderrText().find("interrupted") != std::string::npos);
}

TEST_CASE("SIGTERM while epitrack-solve solves or renders leaves consistent outputs",
          "[solve][interrupt]") {
  const Y4mClip& clip = orbitClip();
  // Signal once each stage has begun (its progress line is on stderr): whatever point the solve
  // has reached, what it leaves must be consistent; the stage it names is at or after it.
  struct Case {
    const char* wait_for;
    std::set<std::string> stages;
  };
  const std::vector<Case> cases = {
      {"solving: 0/4",
       {"calibration", "initialization", "registration", "bundle_adjustment", "rendering",
        "exports"}},
      {"rendering: 5/", {"rendering", "exports"}},
  };
  for (const auto& c : cases) {
    DYNAMIC_SECTION("signal after '" << c.wait_for << "'") {
      TempDir dir("interrupt-solve2");
      const std::string out = dir.file("solve");
      SpawnedCommand solve(binaryPath("tools/solve/epitrack-solve") + " - --out " +
                               shellQuote(out) + epitrack::test::liveFeatureBudgetOption() +
                               " --render cube",
                           dir.file("stderr.txt"));
      REQUIRE(solve.started());
      REQUIRE(solve.writeInput(clip.header.data(), clip.header.size()));
      for (const auto& frame : clip.frames) REQUIRE(solve.writeInput(frame.data(), frame.size()));
      solve.closeInput();
      REQUIRE(solve.waitForStderr(c.wait_for, 60.0));
      REQUIRE(solve.signal(SIGTERM));
      const int exit_code = solve.wait();
      INFO(solve.stderrText());
      const std::string summary = readWholeFile(out + "/summary.json");
      if (exit_code == 0) {
        // It finished before the signal arrived: a normal solve.
        CHECK(jsonString(summary, "status") == "ok");
        CHECK_FALSE(anyTemporary(filesBelow(out)));
        continue;
      }
      CHECK(exit_code == 143);
      checkInterruptedSolve(out, "SIGTERM");
      const std::string stage = jsonString(summary, "stage");
      CHECK(c.stages.count(stage) == 1);
      const auto files = jsonFiles(summary);
      const bool exports = std::find(files.begin(), files.end(), "cameras.tum") != files.end();
      if (stage == "rendering" || stage == "exports" || stage == "bundle_adjustment") {
        // The solve had finished: its exports are there and the solver's own status is kept.
        CHECK(exports);
        CHECK(jsonString(summary, "solve_status") == "ok");
        CHECK(jsonNumber(summary, "solved_frames") > 0);
      } else {
        CHECK_FALSE(exports);
        CHECK(files.empty());
      }
      if (stage == "rendering") {
        // The video ends with the last frame rendered: as many frames as augmented/*.jpg.
        const auto n = std::count_if(files.begin(), files.end(), [](const std::string& f) {
          return f.rfind("augmented/", 0) == 0;
        });
        CHECK(n >= 5);
        CHECK(n < static_cast<long>(clip.frames.size()));
        CHECK(std::find(files.begin(), files.end(), "augmented.avi") != files.end());
        // AVI 1.0 main header: dwTotalFrames at byte 48.
        const std::string avi = readWholeFile(out + "/augmented.avi");
        REQUIRE(avi.size() > 52);
        const auto byte = [&avi](std::size_t i) {
          return static_cast<long>(static_cast<unsigned char>(avi[i]));
        };
        CHECK((byte(48) | byte(49) << 8 | byte(50) << 16 | byte(51) << 24) == n);
      }
    }
  }
}

TEST_CASE("SIGINT while epitrack-track tracks writes tracks.csv complete for the frames tracked",
          "[track][interrupt]") {
  const Y4mClip& clip = orbitClip();
  TempDir dir("interrupt-track");
  const std::string csv = dir.file("tracks.csv");
  SpawnedCommand track(
      binaryPath("tools/track/epitrack-track") + " - --out " + shellQuote(csv) + " --quiet",
      dir.file("stderr.txt"));
  constexpr int kFramesSent = 25;
  const int exit_code = interruptAfterFrames(track, clip, kFramesSent, SIGINT);
  INFO(track.stderrText());
  CHECK(exit_code == 130);
  CHECK(filesBelow(dir.path()) == std::vector<std::string>{"stderr.txt", "tracks.csv"});
  std::vector<epitrack::hal::TrackRow> rows;
  std::string error;
  REQUIRE(epitrack::hal::readTracksCsv(csv, rows, error));
  // Every frame from 0 to the last one tracked has rows: no frame is partial or missing.
  std::map<int64_t, int> per_frame;
  for (const auto& r : rows) ++per_frame[r.frame];
  REQUIRE_FALSE(per_frame.empty());
  const int64_t last = per_frame.rbegin()->first;
  CHECK(last >= kFramesSent - 2);
  CHECK(last <= kFramesSent - 1);
  CHECK(static_cast<int64_t>(per_frame.size()) == last + 1);
  for (const auto& [frame, n] : per_frame) CHECK(n > 50);
}

TEST_CASE("epitrack-solve refuses an output directory holding a solve unless --force",
          "[solve][cli]") {
  TempDir dir("force");
  const std::string clip = dir.file("clip");
  REQUIRE(epitrack::test::run(binaryPath("tools/synth/epitrack-synth") +
                              " --scene orbit --target-wander 0.5 --frames 30 --size 240x180 "
                              "--focal 220 --quiet --out " +
                              shellQuote(clip)) == 0);
  const std::string solve = binaryPath("tools/solve/epitrack-solve") + " " +
                            shellQuote(clip + "/frames") + " --quiet --out ";
  const std::string out = dir.file("solve");
  REQUIRE(epitrack::test::run(solve + shellQuote(out) + " 2>/dev/null") == 0);
  const auto before = filesBelow(out);
  REQUIRE(std::find(before.begin(), before.end(), "cameras.tum") != before.end());
  const auto summary_before = readWholeFile(out + "/summary.json");
  const auto mtime = fs::last_write_time(out + "/summary.json");

  // Refused: one line naming the directory and --force, exit 2, nothing touched.
  auto r = epitrack::test::runCaptured(solve + shellQuote(out), dir.file("refused"));
  CHECK(r.exit_code == 2);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  CHECK(r.err.find(out) != std::string::npos);
  CHECK(r.err.find("--force") != std::string::npos);
  CHECK(filesBelow(out) == before);
  CHECK(readWholeFile(out + "/summary.json") == summary_before);
  CHECK(fs::last_write_time(out + "/summary.json") == mtime);

  // The same for a directory that holds only one output file of a solve (e.g. a clip's
  // intrinsics.txt, which a solve would overwrite).
  r = epitrack::test::runCaptured(solve + shellQuote(clip), dir.file("refused2"));
  CHECK(r.exit_code == 2);
  CHECK(r.err.find("intrinsics.txt") != std::string::npos);

  // --force replaces the earlier solve; files that are not a solve's stay.
  REQUIRE(epitrack::hal::writeTextAtomic(out + "/notes.txt", "mine\n", r.err));
  CHECK(epitrack::test::run(solve + shellQuote(out) + " --force 2>/dev/null") == 0);
  auto after = filesBelow(out);
  after.erase(std::remove(after.begin(), after.end(), "notes.txt"), after.end());
  CHECK(after == before);
  CHECK(readWholeFile(out + "/notes.txt") == "mine\n");
  CHECK(jsonString(readWholeFile(out + "/summary.json"), "status") == "ok");
}

#include <catch2/catch.hpp>

#include <cstdio>
#include <string>

#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include "tools/export/progress.hpp"

using epitrack::io::ProgressReporter;

namespace {

std::string readAll(std::FILE* f) {
  std::rewind(f);
  std::string text;
  char buf[4096];
  std::size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof(buf), f)) > 0) text.append(buf, n);
  return text;
}

int countLines(const std::string& s) {
  int n = 0;
  for (const char c : s) n += c == '\n' ? 1 : 0;
  return n;
}

std::string runStage(ProgressReporter::Mode mode, long total) {
  std::FILE* f = std::tmpfile();
  REQUIRE(f != nullptr);
  {
    ProgressReporter progress(mode, f);
    progress.begin("tracking", total);
    for (long i = 1; i <= total; ++i) progress.update(i);
    progress.end();
  }
  const std::string text = readAll(f);
  std::fclose(f);
  return text;
}

}  // namespace

TEST_CASE("progress: plain lines at most every 5 % when not a terminal", "[progress]") {
  // A temporary file is not a terminal: kAuto picks lines.
  std::FILE* f = std::tmpfile();
  REQUIRE(f != nullptr);
  CHECK(ProgressReporter(ProgressReporter::Mode::kAuto, f).mode() ==
        ProgressReporter::Mode::kLines);
  std::fclose(f);

  const std::string text = runStage(ProgressReporter::Mode::kAuto, 1000);
  CHECK(text.find('\r') == std::string::npos);
  CHECK(countLines(text) == 21);  // 0/1000, then 50/1000 ... 1000/1000
  CHECK(text.rfind("tracking: 0/1000\n", 0) == 0);
  CHECK(text.find("tracking: 50/1000\n") != std::string::npos);
  const std::string last = "tracking: 1000/1000\n";
  REQUIRE(text.size() >= last.size());
  CHECK(text.substr(text.size() - last.size()) == last);

  // Few steps: every step, and the final state once.
  const std::string small = runStage(ProgressReporter::Mode::kLines, 3);
  CHECK(small == "tracking: 0/3\ntracking: 1/3\ntracking: 2/3\ntracking: 3/3\n");
}

TEST_CASE("progress: a bar redrawn in place on a terminal", "[progress]") {
  const std::string text = runStage(ProgressReporter::Mode::kBar, 500);
  CHECK(text.find('\r') != std::string::npos);
  CHECK(countLines(text) == 1);  // one line, finished by end()
  CHECK(text.find("100% 500/500") != std::string::npos);
  // Redrawn once per percent, not per step.
  int redraws = 0;
  for (const char c : text) redraws += c == '\r' ? 1 : 0;
  CHECK(redraws == 101);
}

TEST_CASE("progress: nothing when quiet", "[progress]") {
  CHECK(runStage(ProgressReporter::Mode::kQuiet, 100).empty());
  std::FILE* f = std::tmpfile();
  REQUIRE(f != nullptr);
  {
    ProgressReporter progress(ProgressReporter::Mode::kQuiet, f);
    progress.message("hello");
  }
  CHECK(readAll(f).empty());
  std::fclose(f);
}

TEST_CASE("progress: unknown totals and messages", "[progress]") {
  std::FILE* f = std::tmpfile();
  REQUIRE(f != nullptr);
  {
    ProgressReporter progress(ProgressReporter::Mode::kLines, f);
    progress.begin("bundle adjustment", 0);
    progress.update(3);
    progress.end();
    progress.message("focal: 612.3 px");
  }
  CHECK(readAll(f) == "bundle adjustment: started\nbundle adjustment: done\nfocal: 612.3 px\n");
  std::fclose(f);
}

TEST_CASE("progress: kAuto picks the bar on a terminal", "[progress]") {
  const int master = ::posix_openpt(O_RDWR | O_NOCTTY);
  if (master < 0 || ::grantpt(master) != 0 || ::unlockpt(master) != 0) {
    std::printf("EPITRACK-SKIP: no pseudo-terminal available\n");
    if (master >= 0) ::close(master);
    return;
  }
  const char* name = ::ptsname(master);
  REQUIRE(name != nullptr);
  std::FILE* terminal = std::fopen(name, "w");
  REQUIRE(terminal != nullptr);
  CHECK(ProgressReporter(ProgressReporter::Mode::kAuto, terminal).mode() ==
        ProgressReporter::Mode::kBar);
  std::fclose(terminal);
  ::close(master);
}

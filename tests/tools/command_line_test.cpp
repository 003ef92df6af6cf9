// Clear command lines (issue 9): every installed command rejects an unknown option, every numeric
// option's out-of-range values and a missing input file with exactly one line on stderr that
// names the problem, and exit code 2; `--help` exits 0 and documents every option. The options
// and their ranges are read from each command's own --help (the `[lo..hi]` after a numeric
// option), so a new option is covered as soon as it exists; the contract options of
// ARCHITECTURE.md are listed here so that none can disappear from --help unnoticed.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <catch2/catch.hpp>

#include "hal/io/file_util.hpp"
#include "tests/support/process.hpp"
#include "tests/support/test_support.hpp"
#include "tools/common/command_line.hpp"

namespace {

using epitrack::test::binaryPath;
using epitrack::test::CommandOutput;
using epitrack::test::shellQuote;
using epitrack::test::TempDir;

// A tiny clip (3 frames, 64x48) and its intrinsics, shared by every command's valid arguments.
struct Fixture {
  TempDir dir{"cli"};
  std::string clip;        // epitrack-synth output folder
  std::string frames;      // its frames/
  std::string intrinsics;  // its intrinsics.txt
  std::string missing;     // a path that does not exist
  int counter = 0;
  Fixture() {
    clip = dir.file("clip");
    frames = clip + "/frames";
    intrinsics = clip + "/intrinsics.txt";
    missing = dir.file("no-such-file");
    const int rc = epitrack::test::run(binaryPath("tools/synth/epitrack-synth") +
                                       " --frames 3 --size 64x48 --focal 60 --quiet --out " +
                                       shellQuote(clip));
    if (rc != 0) std::fprintf(stderr, "fixture: epitrack-synth failed (%d)\n", rc);
  }
  CommandOutput run(const std::string& command) {
    return epitrack::test::runCaptured(command, dir.file("run" + std::to_string(counter++)));
  }
};

Fixture& fixture() {
  static Fixture f;
  return f;
}

// One command: how to run it, arguments that make its command line otherwise valid, the options
// ARCHITECTURE.md promises, and command lines naming a missing file (with the path to be named).
struct CommandCase {
  std::string name;   // as in messages, e.g. "epitrack-bench frontend"
  std::string exe;    // shell prefix (binary + subcommand)
  std::string valid;  // arguments appended before the one under test
  std::vector<std::string> contract_options;
  std::vector<std::pair<std::string, std::string>> missing_files;  // (arguments, missing path)
};

std::vector<CommandCase> commandCases() {
  Fixture& f = fixture();
  const std::string frames = shellQuote(f.frames);
  const std::string k = shellQuote(f.intrinsics);
  const std::string gt = shellQuote(f.clip + "/groundtruth.txt");
  const std::string miss = shellQuote(f.missing);
  const std::string out = shellQuote(f.dir.file("out"));
  std::vector<CommandCase> cases = {
      {"epitrack-synth",
       binaryPath("tools/synth/epitrack-synth"),
       " --frames 2 --size 32x32 --quiet --out " + out,
       {"scene", "frames", "size", "focal", "noise", "distortion", "seed", "out"},
       // --out below a regular file cannot be created.
       {{" --frames 2 --size 32x32 --out " + shellQuote(f.intrinsics + "/x"),
         f.intrinsics + "/x"}}},
      {"epitrack-solve",
       binaryPath("tools/solve/epitrack-solve"),
       " " + frames + " --quiet --out " + out,
       {"out", "intrinsics", "focal", "refine-focal", "distortion", "mask", "origin", "render",
        "quiet", "force", "matcher", "tracks"},
       {{" " + miss + " --out " + out, f.missing},
        {" " + frames + " --out " + out + " --intrinsics " + miss, f.missing},
        {" " + frames + " --out " + out + " --tracks " + miss, f.missing},
        {" " + frames + " --out " + out + " --mask " + miss, f.missing}}},
      {"epitrack-track",
       binaryPath("tools/track/epitrack-track"),
       " " + frames + " --quiet --out " + shellQuote(f.dir.file("t.csv")),
       {"out", "features", "window", "levels", "matcher"},
       {{" " + miss + " --out " + shellQuote(f.dir.file("t.csv")), f.missing},
        {" " + frames + " --out " + shellQuote(f.dir.file("t.csv")) + " --mask " + miss,
         f.missing}}},
      {"epitrack-record",
       binaryPath("tools/record/epitrack-record"),
       " " + frames + " --quiet --out " + shellQuote(f.dir.file("r.mjpeg")),
       {"out", "max-frames", "quality"},
       {{" " + miss + " --out " + shellQuote(f.dir.file("r.mjpeg")), f.missing}}},
      {"epitrack-eval",
       binaryPath("tools/eval/epitrack-eval"),
       " --gt " + gt + " --est " + gt,
       {"gt", "est", "gt-intrinsics", "est-intrinsics"},
       {{" --gt " + miss + " --est " + gt, f.missing},
        {" --gt " + gt + " --est " + miss, f.missing},
        {" --gt " + gt + " --est " + gt + " --gt-intrinsics " + miss + " --est-intrinsics " + k,
         f.missing},
        {" --gt " + gt + " --est " + gt + " --gt-intrinsics " + k + " --est-intrinsics " + miss,
         f.missing}}},
      {"epitrack-device",
       binaryPath("firmware_like/epitrack-device"),
       " --source " + frames + " --max-frames 1 --poses " + shellQuote(f.dir.file("p.jsonl")),
       {"source", "intrinsics", "poses", "record", "max-frames", "realtime"},
       {{" --source " + miss, f.missing},
        {" --source " + frames + " --intrinsics " + miss, f.missing},
        {" --source " + frames + " --config " + miss, f.missing}}},
  };
#ifdef EPITRACK_HAVE_BENCH
  const std::string bench = binaryPath("tools/bench/epitrack-bench");
  cases.push_back({"epitrack-bench frontend",
                   bench + " frontend",
                   " " + frames + " --repeat 1",
                   {"repeat", "threads"},
                   {{" " + miss, f.missing}}});
  cases.push_back({"epitrack-bench pyramid",
                   bench + " pyramid",
                   " " + frames + " --repeat 1",
                   {"repeat", "threads"},
                   {{" " + miss, f.missing}}});
  cases.push_back({"epitrack-bench geometry",
                   bench + " geometry",
                   " --scenes 1 --repeat 1",
                   {"repeat", "threads"},
                   {}});
  cases.push_back({"epitrack-bench device",
                   bench + " device",
                   " " + frames + " --intrinsics " + k + " --frames 10 --repeat 1",
                   {"repeat", "threads"},
                   {{" " + miss + " --intrinsics " + k, f.missing},
                    {" " + frames + " --intrinsics " + miss, f.missing}}});
  cases.push_back({"epitrack-bench solve",
                   bench + " solve",
                   " " + frames + " --focal 420 --repeat 1",
                   {"repeat", "threads", "frames", "focal"},
                   {{" " + miss + " --focal 420", f.missing}}});
  cases.push_back({"epitrack-bench rolling-shutter",
                   bench + " rolling-shutter",
                   " " + frames + " --focal 420 --repeat 1",
                   {"repeat", "threads", "frames", "readout", "focal"},
                   {{" " + miss + " --focal 420", f.missing}}});
#endif
  return cases;
}

// An option as --help shows it: `  --name METAVAR  [lo..hi]`.
struct HelpOption {
  std::string name;
  bool takes_value = false;
  bool numeric = false;
  std::string lo, hi;
};

std::vector<HelpOption> optionsInHelp(const std::string& help) {
  std::vector<HelpOption> options;
  static const std::regex line(R"(^  --([a-z0-9-]+)( [^ ]+)?(  \[([^\]]+)\.\.([^\]]+)\])?)");
  std::istringstream in(help);
  std::string text;
  while (std::getline(in, text)) {
    std::smatch m;
    if (!std::regex_search(text, m, line) || m[1] == "help") continue;
    HelpOption o;
    o.name = m[1];
    o.takes_value = m[2].matched;
    o.numeric = m[3].matched;
    o.lo = m[4];
    o.hi = m[5];
    options.push_back(o);
  }
  return options;
}

// epitrack-device's configuration keys as --help lists them: `  key   help [lo..hi]`.
std::vector<HelpOption> deviceKeysInHelp(const std::string& help) {
  std::vector<HelpOption> keys;
  static const std::regex line(R"(^  ([a-z0-9_]+) +.*\[([^\]]+)\.\.([^\]]+)\]$)");
  const auto start = help.find("configuration keys");
  std::istringstream in(start == std::string::npos ? std::string() : help.substr(start));
  std::string text;
  while (std::getline(in, text)) {
    std::smatch m;
    if (!std::regex_search(text, m, line)) continue;
    keys.push_back({m[1], true, true, m[2], m[3]});
  }
  return keys;
}

// Values just outside [lo..hi]: below by max(1, |lo|), above by max(1, |hi|) (integers stay
// integers).
std::vector<std::string> outOfRange(const std::string& lo, const std::string& hi) {
  const bool integers =
      lo.find_first_of(".e") == std::string::npos && hi.find_first_of(".e") == std::string::npos;
  std::vector<std::string> values;
  if (integers) {
    const long long l = std::strtoll(lo.c_str(), nullptr, 10);
    const long long h = std::strtoll(hi.c_str(), nullptr, 10);
    values.push_back(std::to_string(l - 1));
    values.push_back(std::to_string(h + 1));
  } else {
    const double l = std::strtod(lo.c_str(), nullptr);
    const double h = std::strtod(hi.c_str(), nullptr);
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%.17g", l - std::max(1.0, std::abs(l)));
    values.emplace_back(buf);
    std::snprintf(buf, sizeof(buf), "%.17g", h + std::max(1.0, std::abs(h)));
    values.emplace_back(buf);
  }
  return values;
}

// Exactly one non-empty line.
bool oneLine(const std::string& err) {
  return err.size() > 1 && err.back() == '\n' && err.find('\n') == err.size() - 1;
}

}  // namespace

TEST_CASE("Every command rejects bad command lines with one line naming the problem and exit 2",
          "[cli][tools]") {
  Fixture& f = fixture();
  REQUIRE(epitrack::hal::isDirectory(f.frames));
  int checked_values = 0;
  for (const CommandCase& c : commandCases()) {
    INFO(c.name);
    // --help: exit 0, every contract option documented.
    const CommandOutput help = f.run(c.exe + " --help");
    CHECK(help.exit_code == 0);
    CHECK(help.err.empty());
    const auto options = optionsInHelp(help.out);
    CHECK(options.size() >= c.contract_options.size());
    for (const auto& name : c.contract_options) {
      INFO("--" << name);
      CHECK(help.out.find("--" + name) != std::string::npos);
    }

    // An unknown option.
    CommandOutput r = f.run(c.exe + c.valid + " --no-such-option 3");
    CHECK(r.exit_code == 2);
    CHECK(oneLine(r.err));
    CHECK(r.err.find("--no-such-option") != std::string::npos);

    // Every numeric option --help lists refuses values outside its range, and every other
    // option taking a value refuses a missing value, naming the option (so each is known to the
    // parser: an unknown one would be named as unknown).
    for (const HelpOption& o : options) {
      INFO("--" << o.name);
      if (o.numeric) {
        for (const std::string& v : outOfRange(o.lo, o.hi)) {
          INFO("value " << v);
          r = f.run(c.exe + c.valid + " --" + o.name + " " + v);
          CHECK(r.exit_code == 2);
          CHECK(oneLine(r.err));
          CHECK(r.err.find("--" + o.name) != std::string::npos);
          CHECK(r.err.find(v) != std::string::npos);
          ++checked_values;
        }
      }
      // A non-numeric option without its value at the end of the line: named as needing one.
      if (o.takes_value && !o.numeric) {
        r = f.run(c.exe + c.valid + " --" + o.name);
        CHECK(r.exit_code == 2);
        CHECK(oneLine(r.err));
        CHECK(r.err.find("--" + o.name) != std::string::npos);
      }
    }

    // A missing input file: exit 2, one line naming the file.
    for (const auto& [args, path] : c.missing_files) {
      INFO("arguments:" << args);
      r = f.run(c.exe + args);
      CHECK(r.exit_code == 2);
      CHECK(oneLine(r.err));
      CHECK(r.err.find(path) != std::string::npos);
    }
  }
#ifdef EPITRACK_HAVE_BENCH
  CHECK(checked_values > 100);
#else
  CHECK(checked_values > 60);  // without the benchmark's subcommands (sanitizer builds)
#endif
}

TEST_CASE("epitrack-device refuses every configuration value out of its range, naming the key",
          "[cli][tools][device]") {
  Fixture& f = fixture();
  const std::string exe = binaryPath("firmware_like/epitrack-device") + " --source " +
                          shellQuote(f.frames) + " --max-frames 1";
  const CommandOutput help = f.run(exe + " --help");
  const auto keys = deviceKeysInHelp(help.out);
  CHECK(keys.size() >= 25);
  for (const auto& key : keys) {
    for (const std::string& v : outOfRange(key.lo, key.hi)) {
      INFO(key.name << "=" << v);
      const CommandOutput r = f.run(exe + " --set " + key.name + "=" + v);
      CHECK(r.exit_code == 2);
      CHECK(oneLine(r.err));
      CHECK(r.err.find("--set " + key.name + "=" + v) != std::string::npos);
    }
  }
  // An unknown key and a value that is not KEY=VALUE.
  CommandOutput r = f.run(exe + " --set no_such_key=1");
  CHECK(r.exit_code == 2);
  CHECK(oneLine(r.err));
  CHECK(r.err.find("no_such_key") != std::string::npos);
  r = f.run(exe + " --set features");
  CHECK(r.exit_code == 2);
  CHECK(oneLine(r.err));
}

TEST_CASE("epitrack-bench names a missing or unknown subcommand in one line",
          "[cli][tools][bench]") {
#ifdef EPITRACK_HAVE_BENCH
  Fixture& f = fixture();
  const std::string bench = binaryPath("tools/bench/epitrack-bench");
  CommandOutput r = f.run(bench);
  CHECK(r.exit_code == 2);
  CHECK(oneLine(r.err));
  r = f.run(bench + " nosuch");
  CHECK(r.exit_code == 2);
  CHECK(oneLine(r.err));
  CHECK(r.err.find("nosuch") != std::string::npos);
  r = f.run(bench + " --help");
  CHECK(r.exit_code == 0);
  for (const char* sub : {"frontend", "pyramid", "geometry", "device"})
    CHECK(r.out.find(sub) != std::string::npos);
#else
  std::printf("EPITRACK-SKIP: epitrack-bench not built (EPITRACK_BUILD_BENCH=OFF)\n");
#endif
}

TEST_CASE("CommandLine --help lists every registered option with the range of numbers",
          "[cli][tools]") {
  int n = 0;
  double x = 0.0;
  bool flag = false;
  std::string word, text;
  epitrack::tools::CommandLine cl("prog", "[options]", "A test.");
  cl.integer("count", "N", "a count", &n, -3, 12);
  cl.real("scale", "S", "a scale", &x, 0.5, 1e6);
  cl.flag("quick", "a flag", &flag);
  cl.choice("mode", {"a", "b"}, "a word", &word);
  cl.text("name", "TEXT", "a text", &text);
  const std::string help = cl.helpText();
  for (const auto& name : cl.optionNames()) CHECK(help.find("  --" + name) != std::string::npos);
  CHECK(cl.optionNames().size() == 5);
  CHECK(help.find("--count N  [-3..12]") != std::string::npos);
  CHECK(help.find("--scale S  [0.5..1e+06]") != std::string::npos);
  const auto parsed = optionsInHelp(help);
  REQUIRE(parsed.size() == 5);
  CHECK(parsed[0].numeric);
  CHECK(parsed[0].lo == "-3");
  CHECK(parsed[0].hi == "12");
  CHECK(outOfRange(parsed[0].lo, parsed[0].hi) == std::vector<std::string>{"-4", "13"});
  CHECK(outOfRange(parsed[1].lo, parsed[1].hi) == std::vector<std::string>{"-0.5", "2000000"});
  CHECK_FALSE(parsed[2].takes_value);
  CHECK_FALSE(parsed[3].numeric);
}

#pragma once

// Helpers shared by the Catch2 tests: temporary directories, the real-data location and a
// visible skip (ctest marks a test "Skipped" when its output contains EPITRACK-SKIP).

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>

#include <unistd.h>

#include "algo/image/image.hpp"
#include "algo/tracking/feature_tracker.hpp"

namespace epitrack::test {

/// epitrack-solve's option for the live tracker's feature budget (FeatureTrackerOptions'
/// max_features, 300; the solve's own default is twice that, tools::kSolveFeatures). For tests of
/// the command's behaviour rather than its accuracy, and for comparisons with the device: about
/// half the solve's time, under ASan too.
inline std::string liveFeatureBudgetOption() {
  // (appended, not a literal + std::string sum: GCC 12's -Wrestrict misfires on that in the armhf
  // build)
  std::string option = " --features ";
  option += std::to_string(FeatureTrackerOptions{}.max_features);
  return option;
}

/// A fresh directory under $TMPDIR (or /tmp), removed when the object dies unless
/// EPITRACK_KEEP_TEST_FILES is set.
class TempDir {
 public:
  explicit TempDir(const std::string& tag = "test") {
    const char* base = std::getenv("TMPDIR");
    std::string tmpl =
        std::string(base != nullptr ? base : "/tmp") + "/epitrack-" + tag + "-XXXXXX";
    path_ = ::mkdtemp(tmpl.data()) != nullptr ? tmpl : std::string();
  }
  ~TempDir() {
    if (!path_.empty() && std::getenv("EPITRACK_KEEP_TEST_FILES") == nullptr) {
      const std::string cmd = "rm -rf '" + path_ + "'";
      [[maybe_unused]] const int rc = std::system(cmd.c_str());
    }
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  [[nodiscard]] const std::string& path() const { return path_; }
  [[nodiscard]] std::string file(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

/// ../shared/data (configured at build time, overridable with EPITRACK_SHARED_DATA).
inline std::string sharedDataDir() {
  if (const char* env = std::getenv("EPITRACK_SHARED_DATA")) return env;
  return EPITRACK_SHARED_DATA;
}

/// True when the sequence folder exists; otherwise prints the visible skip marker.
inline bool haveSharedSequence(const std::string& name) {
  const std::string dir = sharedDataDir() + "/" + name + "/frames";
  if (::access(dir.c_str(), R_OK) == 0) return true;
  std::printf("EPITRACK-SKIP: %s not found (needs ../shared/data beside the project)\n",
              dir.c_str());
  return false;
}

/// Shell prefix that runs a built command, e.g. binaryPath("tools/synth/epitrack-synth"). In a
/// cross build whose tests run under qemu-user, it starts with the emulator (and its -L prefix), so
/// commands spawned by tests run too; use it only to build command lines, not as a file path.
inline std::string binaryPath(const std::string& relative) {
  // Appended to one string, not operator+ on temporaries: the tests are compiled at -O1
  // (tests/CMakeLists.txt), where GCC 12 reports a false -Warray-bounds inside the move of the
  // temporary that `std::string(...) + "/"` returns.
  std::string path;
#ifdef EPITRACK_TEST_EMULATOR
  path.append(EPITRACK_TEST_EMULATOR).append(" ");
#endif
  path.append(EPITRACK_BINARY_DIR).append("/").append(relative);
  return path;
}

/// Runs a shell command, returns its exit status (or -1).
inline int run(const std::string& command) {
  const int rc = std::system(command.c_str());
  if (rc == -1 || !WIFEXITED(rc)) return -1;
  return WEXITSTATUS(rc);
}

/// The whole file as text; "" when it cannot be read.
inline std::string readWholeFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// The string value of the first field named `key` in a JSON text such as summary.json ("" when
/// absent). Enough for the flat files the commands write; not a JSON parser.
inline std::string jsonString(const std::string& json, const std::string& key) {
  const auto at = json.find("\"" + key + "\"");
  if (at == std::string::npos) return {};
  const auto q1 = json.find('"', json.find(':', at) + 1);
  if (q1 == std::string::npos) return {};
  const auto q2 = json.find('"', q1 + 1);
  return json.substr(q1 + 1, q2 - q1 - 1);
}

/// The numeric value of the first field named `key`; `missing` when absent (by default NaN, so
/// any comparison with it fails).
inline double jsonNumber(const std::string& json, const std::string& key,
                         double missing = std::numeric_limits<double>::quiet_NaN()) {
  const auto at = json.find("\"" + key + "\"");
  if (at == std::string::npos) return missing;
  return std::strtod(json.c_str() + json.find(':', at) + 1, nullptr);
}

/// Fills an image with seeded uniform random bytes.
inline void fillRandom(ImageView<uint8_t> img, uint32_t seed) {
  std::mt19937 rng(seed);
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) img(x, y) = static_cast<uint8_t>(rng() >> 24);
  }
}

}  // namespace epitrack::test

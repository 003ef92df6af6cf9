#pragma once

// epitrack-bench subcommands register themselves here (one file per subcommand), so the main
// program dispatches without knowing them.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

namespace epitrack::bench {

using BenchFn = int (*)(int argc, const char* const* argv);

struct BenchEntry {
  BenchFn run;
  const char* summary;
};

inline std::map<std::string, BenchEntry>& registry() {
  static std::map<std::string, BenchEntry> r;
  return r;
}

struct BenchRegistrar {
  BenchRegistrar(const char* name, const char* summary, BenchFn fn) {
    registry()[name] = {fn, summary};
  }
};

/// Order statistics of repeated timings (milliseconds).
struct TimingStats {
  double median = 0.0;
  double mean = 0.0;
  double p95 = 0.0;
  double min = 0.0;
  double max = 0.0;
  std::size_t n = 0;
};

inline TimingStats summarize(std::vector<double> ms) {
  TimingStats s;
  s.n = ms.size();
  if (ms.empty()) return s;
  std::sort(ms.begin(), ms.end());
  s.median =
      ms.size() % 2 == 1 ? ms[ms.size() / 2] : 0.5 * (ms[ms.size() / 2 - 1] + ms[ms.size() / 2]);
  double sum = 0.0;
  for (double v : ms) sum += v;
  s.mean = sum / static_cast<double>(ms.size());
  s.p95 =
      ms[std::min(ms.size() - 1,
                  static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(ms.size()))) - 1)];
  s.min = ms.front();
  s.max = ms.back();
  return s;
}

/// Wall-clock stopwatch in milliseconds.
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  void restart() { start_ = std::chrono::steady_clock::now(); }
  [[nodiscard]] double ms() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_)
        .count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

/// Builds one JSON object line incrementally: JsonLine().add("bench",
/// "frontend").add("ms", 1.2).str().
class JsonLine {
 public:
  JsonLine& add(const std::string& key, const std::string& value) {
    std::string escaped;
    for (const char c : value) {
      if (c == '"' || c == '\\') escaped += '\\';
      escaped += c;
    }
    return raw(key, "\"" + escaped + "\"");
  }
  JsonLine& add(const std::string& key, const char* value) { return add(key, std::string(value)); }
  JsonLine& add(const std::string& key, double value) {
    char buf[64];
    if (!std::isfinite(value)) return raw(key, "null");
    std::snprintf(buf, sizeof(buf), "%.6g", value);
    return raw(key, buf);
  }
  JsonLine& add(const std::string& key, int value) { return raw(key, std::to_string(value)); }
  JsonLine& add(const std::string& key, long value) { return raw(key, std::to_string(value)); }
  JsonLine& add(const std::string& key, std::size_t value) {
    return raw(key, std::to_string(value));
  }
  JsonLine& add(const std::string& key, bool value) { return raw(key, value ? "true" : "false"); }
  JsonLine& timing(const std::string& prefix, const TimingStats& s) {
    return add(prefix + "_median", s.median)
        .add(prefix + "_mean", s.mean)
        .add(prefix + "_p95", s.p95);
  }
  JsonLine& raw(const std::string& key, const std::string& json) {
    body_ += (body_.empty() ? "" : ", ") + std::string("\"") + key + "\": " + json;
    return *this;
  }
  [[nodiscard]] std::string str() const { return "{" + body_ + "}"; }
  void print() const { std::printf("%s\n", str().c_str()); }

 private:
  std::string body_;
};

}  // namespace epitrack::bench

#pragma once

// Reading epitrack-device's pose stream back in tests.

#include <cstdlib>
#include <string>
#include <vector>

#include "hal/io/text_formats.hpp"
#include "tests/support/test_support.hpp"

namespace epitrack::test {

struct DeviceLine {
  long frame = -1;
  double t = 0.0;
  std::string status;
  int features = 0;
  double q[4] = {0, 0, 0, 1};
  double p[3] = {0, 0, 0};
  double ms = 0.0;
  /// While initializing: why ("init": {"reason"}) and the figures behind it (-1: absent).
  std::string init_reason;
  int init_tracks = -1, init_common = -1, init_points = -1;
  double init_displacement_px = -1.0, init_parallax_deg = -1.0;
};

inline bool jsonArray(const std::string& json, const std::string& key, double* out, int n) {
  const auto at = json.find("\"" + key + "\": [");
  if (at == std::string::npos) return false;
  const char* s = json.c_str() + json.find('[', at) + 1;
  for (int i = 0; i < n; ++i) {
    char* end = nullptr;
    out[i] = std::strtod(s, &end);
    if (end == s) return false;
    s = end;
    while (*s == ',' || *s == ' ') ++s;
  }
  return true;
}

/// Splits the stream into per-frame lines and the final summary line.
inline void parseDeviceOutput(const std::string& text, std::vector<DeviceLine>& lines,
                              std::string& summary) {
  std::size_t pos = 0;
  while (pos < text.size()) {
    auto nl = text.find('\n', pos);
    if (nl == std::string::npos) nl = text.size();
    const std::string l = text.substr(pos, nl - pos);
    pos = nl + 1;
    if (l.empty()) continue;
    if (l.find("\"summary\"") != std::string::npos) {
      summary = l;
      continue;
    }
    DeviceLine d;
    d.frame = static_cast<long>(jsonNumber(l, "frame", -1));
    d.t = jsonNumber(l, "t", 0);
    d.status = jsonString(l, "status");
    d.features = static_cast<int>(jsonNumber(l, "features", 0));
    jsonArray(l, "q", d.q, 4);
    jsonArray(l, "p", d.p, 3);
    d.ms = jsonNumber(l, "ms", 0);
    if (l.find("\"init\": {") != std::string::npos) {
      d.init_reason = jsonString(l, "reason");
      d.init_tracks = static_cast<int>(jsonNumber(l, "tracks", -1));
      d.init_common = static_cast<int>(jsonNumber(l, "common", -1));
      d.init_points = static_cast<int>(jsonNumber(l, "points", -1));
      d.init_displacement_px = jsonNumber(l, "displacement_px", -1);
      d.init_parallax_deg = jsonNumber(l, "parallax_deg", -1);
    }
    lines.push_back(d);
  }
}

/// Tracking lines as a trajectory (t = frame index, as groundtruth.txt).
inline std::vector<hal::TrajectoryEntry> trackingTrajectory(const std::vector<DeviceLine>& lines) {
  std::vector<hal::TrajectoryEntry> out;
  for (const auto& d : lines) {
    if (d.status != "tracking") continue;
    hal::TrajectoryEntry e;
    e.t = static_cast<double>(d.frame);
    e.position = Eigen::Vector3d(d.p[0], d.p[1], d.p[2]);
    e.rotation = Eigen::Quaterniond(d.q[3], d.q[0], d.q[1], d.q[2]).normalized();
    out.push_back(e);
  }
  return out;
}

}  // namespace epitrack::test

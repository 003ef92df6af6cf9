#include "hal/io/text_formats.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "hal/io/file_util.hpp"

namespace epitrack::hal {
namespace {

// Splits one line into numbers; false on a token that is not a finite number.
bool parseNumbers(const std::string& line, std::vector<double>& out) {
  out.clear();
  const char* p = line.c_str();
  while (*p != '\0') {
    while (*p == ' ' || *p == '\t' || *p == '\r' || *p == ',') ++p;
    if (*p == '\0') break;
    char* end = nullptr;
    const double v = std::strtod(p, &end);
    if (end == p || !std::isfinite(v)) return false;
    out.push_back(v);
    p = end;
    if (*p != '\0' && *p != ' ' && *p != '\t' && *p != '\r' && *p != ',') return false;
  }
  return true;
}

bool isBlankOrComment(const std::string& line) {
  for (const char c : line) {
    if (c == '#') return true;
    if (c != ' ' && c != '\t' && c != '\r') return false;
  }
  return true;
}

/// Appends `v` as "%.<decimals>f", however long it prints: "%.9f" of 1e300 is 310 characters,
/// which a fixed buffer would cut, losing the rest of the line (found by fuzzing).
void appendFixed(std::string& out, int decimals, double v) {
  char buf[64];
  const int n = std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  if (n < 0) return;
  if (static_cast<std::size_t>(n) < sizeof(buf)) {
    out.append(buf, static_cast<std::size_t>(n));
    return;
  }
  const std::size_t start = out.size();
  out.resize(start + static_cast<std::size_t>(n) + 1);
  std::snprintf(out.data() + start, static_cast<std::size_t>(n) + 1, "%.*f", decimals, v);
  out.resize(start + static_cast<std::size_t>(n));
}

std::string number(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.10g", v);
  return buf;
}

}  // namespace

bool parseTrajectory(const std::string& text, std::vector<TrajectoryEntry>& entries,
                     std::string& error) {
  entries.clear();
  std::istringstream in(text);
  std::string line;
  std::vector<double> v;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (isBlankOrComment(line)) continue;
    if (!parseNumbers(line, v) || v.size() != 8) {
      error = "line " + std::to_string(line_no) + ": expected 't tx ty tz qx qy qz qw' (8 numbers)";
      return false;
    }
    TrajectoryEntry e;
    e.t = v[0];
    e.position = Eigen::Vector3d(v[1], v[2], v[3]);
    e.rotation = Eigen::Quaterniond(v[7], v[4], v[5], v[6]);
    // stableNorm: the plain norm overflows for components near 1e155 and above, and dividing
    // by infinity turned such a quaternion into zeros (found by fuzzing).
    const double n = e.rotation.coeffs().stableNorm();
    if (!(n > 1e-9) || !std::isfinite(n)) {
      error = "line " + std::to_string(line_no) +
              (std::isfinite(n) ? ": zero quaternion" : ": quaternion too large to normalise");
      return false;
    }
    e.rotation.coeffs() /= n;
    entries.push_back(e);
  }
  return true;
}

std::string formatTrajectory(const std::vector<TrajectoryEntry>& entries,
                             const std::string& comment) {
  std::string out;
  if (!comment.empty()) out += "# " + comment + "\n";
  out += "# t tx ty tz qx qy qz qw  (T_wc: camera centre, camera-to-world rotation)\n";
  for (const auto& e : entries) {
    const bool integral = e.t == std::floor(e.t) && std::abs(e.t) < 1e15;
    if (integral) {
      out += std::to_string(static_cast<long long>(e.t));
    } else {
      appendFixed(out, 6, e.t);
    }
    for (const double v : {e.position.x(), e.position.y(), e.position.z(), e.rotation.x(),
                           e.rotation.y(), e.rotation.z(), e.rotation.w()}) {
      out += ' ';
      appendFixed(out, 9, v);
    }
    out += '\n';
  }
  return out;
}

bool parseIntrinsics(const std::string& text, CameraIntrinsics& k, std::string& error) {
  std::istringstream in(text);
  std::string line;
  std::vector<double> v;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (isBlankOrComment(line)) continue;
    if (!parseNumbers(line, v) || (v.size() != 6 && v.size() != 7 && v.size() != 8)) {
      error = "line " + std::to_string(line_no) + ": expected 'fx fy cx cy width height [k1 k2]'";
      return false;
    }
    if (!(v[0] > 0.0) || !(v[1] > 0.0)) {
      error = "line " + std::to_string(line_no) + ": focal lengths must be positive";
      return false;
    }
    if (v[4] < 1 || v[5] < 1 || v[4] > 65536 || v[5] > 65536 || v[4] != std::floor(v[4]) ||
        v[5] != std::floor(v[5])) {
      error = "line " + std::to_string(line_no) + ": width and height must be positive integers";
      return false;
    }
    k = CameraIntrinsics{};
    k.fx = v[0];
    k.fy = v[1];
    k.cx = v[2];
    k.cy = v[3];
    k.width = static_cast<int>(v[4]);
    k.height = static_cast<int>(v[5]);
    if (v.size() >= 7) k.k1 = v[6];
    if (v.size() >= 8) k.k2 = v[7];
    return true;
  }
  error = "no intrinsics line found";
  return false;
}

std::string formatIntrinsics(const CameraIntrinsics& k, const std::string& comment) {
  std::string out;
  if (!comment.empty()) out += "# " + comment + "\n";
  out += "# fx fy cx cy width height" + std::string(k.hasDistortion() ? " k1 k2" : "") + "\n";
  out += number(k.fx) + " " + number(k.fy) + " " + number(k.cx) + " " + number(k.cy) + " " +
         std::to_string(k.width) + " " + std::to_string(k.height);
  if (k.hasDistortion()) out += " " + number(k.k1) + " " + number(k.k2);
  out += "\n";
  return out;
}

bool readTextFile(const std::string& path, std::string& text, std::string& error) {
  std::vector<uint8_t> bytes;
  if (!readFileInto(path, bytes, error)) return false;
  text.assign(bytes.begin(), bytes.end());
  return true;
}

bool readTrajectoryFile(const std::string& path, std::vector<TrajectoryEntry>& entries,
                        std::string& error) {
  std::string text;
  if (!readTextFile(path, text, error)) return false;
  if (!parseTrajectory(text, entries, error)) {
    error = "'" + path + "' " + error;
    return false;
  }
  return true;
}

bool readIntrinsicsFile(const std::string& path, CameraIntrinsics& k, std::string& error) {
  std::string text;
  if (!readTextFile(path, text, error)) return false;
  if (!parseIntrinsics(text, k, error)) {
    error = "'" + path + "' " + error;
    return false;
  }
  return true;
}

}  // namespace epitrack::hal

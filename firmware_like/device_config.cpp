#include "firmware_like/device_config.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <map>
#include <sstream>

namespace epitrack::device {

namespace {

// The notation of epitrack's other commands' --help: [lo..hi].
std::string rangeText(double lo, double hi) {
  std::ostringstream s;
  s << "[" << lo << ".." << hi << "]";
  return s.str();
}

std::string rangeText(long lo, long hi) {
  std::ostringstream s;
  s << "[" << lo << ".." << hi << "]";
  return s.str();
}

bool parseInt(const std::string& v, long lo, long hi, int& out, std::string& error) {
  errno = 0;
  char* end = nullptr;
  const long x = std::strtol(v.c_str(), &end, 10);
  if (v.empty() || end == nullptr || *end != '\0' || errno != 0) {
    error = "'" + v + "' is not an integer";
    return false;
  }
  if (x < lo || x > hi) {
    error = "'" + v + "' is outside " + rangeText(lo, hi);
    return false;
  }
  out = static_cast<int>(x);
  return true;
}

bool parseReal(const std::string& v, double lo, double hi, double& out, std::string& error) {
  errno = 0;
  char* end = nullptr;
  const double x = std::strtod(v.c_str(), &end);
  if (v.empty() || end == nullptr || *end != '\0' || errno != 0 || !std::isfinite(x)) {
    error = "'" + v + "' is not a number";
    return false;
  }
  if (x < lo || x > hi) {
    error = "'" + v + "' is outside " + rangeText(lo, hi);
    return false;
  }
  out = x;
  return true;
}

bool parseBool(const std::string& v, bool& out, std::string& error) {
  if (v == "1" || v == "true" || v == "yes" || v == "on") {
    out = true;
    return true;
  }
  if (v == "0" || v == "false" || v == "no" || v == "off") {
    out = false;
    return true;
  }
  error = "'" + v + "' is not a boolean (true/false, 1/0, yes/no, on/off)";
  return false;
}

struct Key {
  std::string help;
  std::function<bool(DeviceConfig&, const std::string&, std::string&)> apply;
  std::string range;  // "[lo..hi]" of numeric keys
};

// An integer key in [lo, hi]; `set` stores it (and may refuse it with a reason).
Key intKey(const std::string& help, long lo, long hi,
           const std::function<bool(DeviceConfig&, int, std::string&)>& set) {
  return {help,
          [=](DeviceConfig& c, const std::string& v, std::string& e) {
            int x = 0;
            return parseInt(v, lo, hi, x, e) && set(c, x, e);
          },
          rangeText(lo, hi)};
}

Key intKey(const std::string& help, long lo, long hi,
           const std::function<int&(DeviceConfig&)>& field) {
  return intKey(help, lo, hi, [field](DeviceConfig& c, int x, std::string&) {
    field(c) = x;
    return true;
  });
}

Key realKey(const std::string& help, double lo, double hi,
            const std::function<double&(DeviceConfig&)>& field) {
  return {help,
          [=](DeviceConfig& c, const std::string& v, std::string& e) {
            return parseReal(v, lo, hi, field(c), e);
          },
          rangeText(lo, hi)};
}

Key boolKey(const std::string& help, const std::function<bool&(DeviceConfig&)>& field) {
  return {help + " (true/false)",
          [=](DeviceConfig& c, const std::string& v, std::string& e) {
            return parseBool(v, field(c), e);
          },
          {}};
}

Key textKey(const std::string& help, bool allow_empty,
            const std::function<std::string&(DeviceConfig&)>& field) {
  return {help,
          [=](DeviceConfig& c, const std::string& v, std::string& e) {
            if (v.empty() && !allow_empty) {
              e = "expected a non-empty value";
              return false;
            }
            field(c) = v;
            return true;
          },
          {}};
}

const std::map<std::string, Key>& keyTable() {
  static const std::map<std::string, Key> table = [] {
    using C = DeviceConfig;
    std::map<std::string, Key> t;
    t["source"] =
        textKey("INPUT: frame directory, .y4m, .mjpeg or v4l2:/dev/videoN?width=W&height=H", false,
                [](C& c) -> std::string& { return c.source; });
    t["intrinsics"] = textKey("intrinsics.txt (fx fy cx cy width height [k1 k2])", true,
                              [](C& c) -> std::string& { return c.intrinsics_path; });
    t["poses"] = textKey("pose stream: - (standard output) or a file", false,
                         [](C& c) -> std::string& { return c.poses; });
    t["record"] =
        textKey("record the camera frames: FILE.mjpeg (JPEG) or a directory (lossless PGM frames)",
                true, [](C& c) -> std::string& { return c.record; });
    t["max_frames"] = intKey("stop after N frames (0: until the end)", 0, 2000000000L,
                             [](C& c) -> int& { return c.max_frames; });
    t["realtime"] = boolKey("pace replay at the nominal rate; late frames are dropped",
                            [](C& c) -> bool& { return c.realtime; });
    t["fps"] = realKey("nominal rate of image directories", 0.1, 100000.0,
                       [](C& c) -> double& { return c.fps; });
    t["readout_ms"] = realKey(
        "rolling shutter: the sensor's readout time, first row to last, in ms (0: global shutter); "
        "used in the live map's resection and windowed adjustment",
        0.0, 1000.0, [](C& c) -> double& { return c.readout_ms; });
    t["focal"] = realKey("focal in pixels when no intrinsics are given (0: self-calibrate it)", 0.0,
                         1e6, [](C& c) -> double& { return c.focal; });
    t["warmup_frames"] = intKey("frames left out of the timing statistics", 0, 1000000,
                                [](C& c) -> int& { return c.warmup_frames; });
    t["features"] =
        intKey("tracked features (capacity of the tracker and of the map's per-frame buffers)", 16,
               4000, [](C& c, int n, std::string&) {
                 c.tracker.max_features = n;
                 c.map.max_features = n;
                 return true;
               });
    t["window"] = intKey("LK window side in pixels (odd)", 5, 61, [](C& c, int n, std::string& e) {
      if (n % 2 == 0) {
        e = std::to_string(n);  // (appended, not summed: GCC 12's -Wrestrict misfires on the sum)
        e.insert(0, 1, '\'');
        e += "' is even (the window needs a centre pixel)";
        return false;
      }
      c.tracker.window = n;
      return true;
    });
    t["levels"] = intKey("pyramid levels beyond the base", 0, 6,
                         [](C& c) -> int& { return c.tracker.levels; });
    t["lk_affine"] =
        boolKey("LK with an affine template warp at the base level (else translation only)",
                [](C& c) -> bool& { return c.tracker.affine; });
    t["lk_occlusion_aware"] = {
        "LK residual over the window's centre and stretch-gated template refresh, the 2D "
        "tracker's default (true/false; the device default false: the whole-window set, whose "
        "live accuracy is measured)",
        [](C& c, const std::string& v, std::string& e) {
          bool on = false;
          if (!parseBool(v, on, e)) return false;
          if (on) {
            c.tracker.occlusionAware();
          } else {
            c.tracker.wholeWindow();
          }
          return true;
        },
        {}};
    t["lk_iterations"] = intKey("LK iterations per pyramid level", 1, 100,
                                [](C& c) -> int& { return c.tracker.max_iterations; });
    t["redetect_fraction"] =
        realKey("detect new features when fewer than this fraction of `features` are tracked", 0.0,
                1.0, [](C& c) -> double& { return c.tracker.redetect_fraction; });
    t["redetect_cells"] = intKey(
        "re-detect only in the grid cells (about this many) that lost tracks (0: the whole frame)",
        0, 10000, [](C& c) -> int& { return c.tracker.redetect_cells; });
    t["min_distance"] = realKey("minimum distance between features, px", 1.0, 200.0,
                                [](C& c) -> double& { return c.tracker.min_distance; });
    t["map_prediction"] = boolKey(
        "predict the tracks with the map: constant-velocity pose, the map points projected (LK's "
        "start and the gate's centre)",
        [](C& c) -> bool& { return c.map.map_prediction; });
    t["map_prediction_radius"] = realKey(
        "px: how far LK may land from a map prediction before the track's own prediction is used "
        "(it also sets LK's start level)",
        0.5, 200.0, [](C& c) -> double& { return c.tracker.prediction_radius_px; });
    t["max_points"] =
        intKey("map point capacity", 64, 1000000, [](C& c) -> int& { return c.map.max_points; });
    t["max_keyframes"] = intKey("keyframes kept (a ring)", 3, 1000,
                                [](C& c) -> int& { return c.map.max_keyframes; });
    t["ba_window"] = intKey("newest keyframes refined by the windowed bundle adjustment", 2, 100,
                            [](C& c) -> int& { return c.map.ba_window; });
    t["ba_fixed"] = intKey("older keyframes joining the adjustment as fixed cameras", 0, 100,
                           [](C& c) -> int& { return c.map.ba_fixed; });
    t["ba_iterations"] = intKey("Levenberg-Marquardt iterations per adjustment (0: none)", 0, 100,
                                [](C& c) -> int& { return c.map.ba_iterations; });
    t["reproj_threshold_px"] = realKey("PnP inlier / triangulation threshold, px", 0.1, 50.0,
                                       [](C& c) -> double& { return c.map.reproj_threshold_px; });
    t["keyframe_parallax_deg"] =
        realKey("median parallax that makes a keyframe", 0.1, 45.0,
                [](C& c) -> double& { return c.map.keyframe_parallax_deg; });
    t["keyframe_max_gap"] = intKey("frames after which a keyframe is taken anyway", 1, 100000,
                                   [](C& c) -> int& { return c.map.keyframe_max_gap; });
    t["init_min_parallax_deg"] =
        realKey("median parallax of the initial points", 0.1, 45.0,
                [](C& c) -> double& { return c.map.init_min_parallax_deg; });
    t["init_min_displacement"] =
        realKey("median track displacement (fraction of the width) before an initial pair is tried",
                0.0, 0.5, [](C& c) -> double& { return c.map.init_min_displacement; });
    t["init_max_gap"] =
        intKey("frames after which an initialisation reference that never succeeded is renewed", 1,
               1000000, [](C& c) -> int& { return c.map.init_max_gap; });
    t["young_map_keyframes"] =
        intKey("keyframes before the map counts as mature (dense keyframes until then)", 0, 1000,
               [](C& c) -> int& { return c.map.young_map_keyframes; });
    t["young_map_keyframe_gap"] = intKey("frames between keyframes while the map is young", 1, 1000,
                                         [](C& c) -> int& { return c.map.young_map_keyframe_gap; });
    t["calib_pair_displacement"] = realKey(
        "self-calibration: median displacement (fraction of the width) that closes a frame pair",
        0.005, 0.5, [](C& c) -> double& { return c.map.calib_pair_displacement; });
    t["calib_min_pairs"] = intKey("self-calibration: F pairs before a focal is accepted", 1, 1000,
                                  [](C& c) -> int& { return c.map.calib_min_pairs; });
    t["calib_max_frames"] =
        intKey("self-calibration: frames after which the fallback focal (1.2 x max(w, h)) is used",
               1, 100000000, [](C& c) -> int& { return c.map.calib_max_frames; });
    t["init_min_points"] = intKey("points the initial pair must triangulate", 8, 100000,
                                  [](C& c) -> int& { return c.map.init_min_points; });
    t["min_pnp_inliers"] = intKey("fewer PnP inliers: the frame is lost and the map restarts", 6,
                                  100000, [](C& c) -> int& { return c.map.min_pnp_inliers; });
    t["seed"] = intKey("RANSAC seed", 0, 2000000000L, [](C& c, int s, std::string&) {
      c.map.seed = static_cast<uint64_t>(s);
      return true;
    });
    return t;
  }();
  return table;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return {};
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

}  // namespace

bool applyConfigValueReason(DeviceConfig& config, const std::string& key, const std::string& value,
                            std::string& reason) {
  const auto& table = keyTable();
  const auto it = table.find(key);
  if (it == table.end()) {
    reason = "unknown configuration key '" + key + "'";
    return false;
  }
  return it->second.apply(config, value, reason);
}

bool applyConfigValue(DeviceConfig& config, const std::string& key, const std::string& value,
                      std::string& error) {
  if (keyTable().count(key) == 0) return applyConfigValueReason(config, key, value, error);
  std::string why;
  if (!applyConfigValueReason(config, key, value, why)) {
    error = "bad value for '" + key + "': " + why;
    return false;
  }
  return true;
}

std::string configKeyRange(const std::string& key) {
  const auto it = keyTable().find(key);
  return it == keyTable().end() ? std::string() : it->second.range;
}

bool applyConfigText(DeviceConfig& config, const std::string& text, const std::string& origin,
                     std::string& error) {
  std::size_t pos = 0;
  int line_no = 0;
  while (pos <= text.size()) {
    const auto nl = text.find('\n', pos);
    const std::string raw =
        text.substr(pos, nl == std::string::npos ? std::string::npos : nl - pos);
    pos = nl == std::string::npos ? text.size() + 1 : nl + 1;
    ++line_no;
    const auto hash = raw.find('#');
    const std::string line = trim(hash == std::string::npos ? raw : raw.substr(0, hash));
    if (line.empty()) continue;
    const auto eq = line.find('=');
    if (eq == std::string::npos) {
      error = origin;
      error.append(":").append(std::to_string(line_no)).append(": expected 'key = value'");
      return false;
    }
    std::string why;
    if (!applyConfigValue(config, trim(line.substr(0, eq)), trim(line.substr(eq + 1)), why)) {
      error = origin;
      error.append(":").append(std::to_string(line_no)).append(": ").append(why);
      return false;
    }
  }
  return true;
}

bool validateConfig(const DeviceConfig& config, std::string& error) {
  if (config.source.empty()) {
    error = "no source (--source INPUT or 'source = INPUT' in the configuration file)";
    return false;
  }
  if (config.map.ba_window + config.map.ba_fixed > config.map.max_keyframes) {
    error = "ba_window + ba_fixed must not exceed max_keyframes";
    return false;
  }
  if (config.map.max_points < config.map.max_features) {
    error = "max_points must be at least features";
    return false;
  }
  return true;
}

const std::vector<std::pair<std::string, std::string>>& configKeys() {
  static const std::vector<std::pair<std::string, std::string>> keys = [] {
    std::vector<std::pair<std::string, std::string>> k;
    for (const auto& [name, key] : keyTable())
      k.emplace_back(name, key.range.empty() ? key.help : key.help + " " + key.range);
    return k;
  }();
  return keys;
}

}  // namespace epitrack::device

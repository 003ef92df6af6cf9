#include "firmware_like/device_config.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <map>

namespace epitrack::device {

namespace {

bool parseInt(const std::string& v, long lo, long hi, int& out, std::string& error) {
  errno = 0;
  char* end = nullptr;
  const long x = std::strtol(v.c_str(), &end, 10);
  if (v.empty() || end == nullptr || *end != '\0' || errno != 0) {
    error = "'" + v + "' is not an integer";
    return false;
  }
  if (x < lo || x > hi) {
    error = "'" + v + "' is outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
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
    error = "'" + v + "' is outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
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
};

Key intKey(const char* help, long lo, long hi, int DeviceConfig::*member) {
  return {help, [=](DeviceConfig& c, const std::string& v, std::string& e) {
            return parseInt(v, lo, hi, c.*member, e);
          }};
}

const std::map<std::string, Key>& keyTable() {
  static const std::map<std::string, Key> table = [] {
    std::map<std::string, Key> t;
    t["source"] = {"INPUT: frame directory, .y4m, .mjpeg or v4l2:/dev/videoN?width=W&height=H",
                   [](DeviceConfig& c, const std::string& v, std::string& e) {
                     if (v.empty()) {
                       e = "empty source";
                       return false;
                     }
                     c.source = v;
                     return true;
                   }};
    t["intrinsics"] = {"intrinsics.txt (fx fy cx cy width height [k1 k2])",
                       [](DeviceConfig& c, const std::string& v, std::string&) {
                         c.intrinsics_path = v;
                         return true;
                       }};
    t["poses"] = {"pose stream: - (standard output) or a file",
                  [](DeviceConfig& c, const std::string& v, std::string& e) {
                    if (v.empty()) {
                      e = "empty pose output";
                      return false;
                    }
                    c.poses = v;
                    return true;
                  }};
    t["record"] = {
        "record the camera frames: FILE.mjpeg (JPEG) or a directory (lossless PGM frames)",
        [](DeviceConfig& c, const std::string& v, std::string&) {
          c.record = v;
          return true;
        }};
    t["max_frames"] =
        intKey("stop after N frames (0: until the end)", 0, 2000000000L, &DeviceConfig::max_frames);
    t["realtime"] = {"pace replay at the nominal rate; late frames are dropped (true/false)",
                     [](DeviceConfig& c, const std::string& v, std::string& e) {
                       return parseBool(v, c.realtime, e);
                     }};
    t["fps"] = {"nominal rate of image directories",
                [](DeviceConfig& c, const std::string& v, std::string& e) {
                  return parseReal(v, 0.1, 100000.0, c.fps, e);
                }};
    t["focal"] = {"focal in pixels when no intrinsics are given (0: self-calibrate it)",
                  [](DeviceConfig& c, const std::string& v, std::string& e) {
                    return parseReal(v, 0.0, 1e6, c.focal, e);
                  }};
    t["warmup_frames"] = intKey("frames left out of the timing statistics", 0, 1000000,
                                &DeviceConfig::warmup_frames);
    t["features"] = {
        "tracked features (capacity of the tracker and of the map's per-frame buffers)",
        [](DeviceConfig& c, const std::string& v, std::string& e) {
          int n = 0;
          if (!parseInt(v, 16, 4000, n, e)) return false;
          c.tracker.max_features = n;
          c.map.max_features = n;
          return true;
        }};
    t["window"] = {"LK window side in pixels (odd)",
                   [](DeviceConfig& c, const std::string& v, std::string& e) {
                     int n = 0;
                     if (!parseInt(v, 5, 61, n, e)) return false;
                     if (n % 2 == 0) {
                       e = "'" + v + "' is even (the window needs a centre pixel)";
                       return false;
                     }
                     c.tracker.window = n;
                     return true;
                   }};
    t["levels"] = {"pyramid levels beyond the base",
                   [](DeviceConfig& c, const std::string& v, std::string& e) {
                     return parseInt(v, 0, 6, c.tracker.levels, e);
                   }};
    t["lk_affine"] = {"LK with an affine template warp at the base level (else translation only)",
                      [](DeviceConfig& c, const std::string& v, std::string& e) {
                        return parseBool(v, c.tracker.affine, e);
                      }};
    t["lk_iterations"] = {"LK iterations per pyramid level",
                          [](DeviceConfig& c, const std::string& v, std::string& e) {
                            return parseInt(v, 1, 100, c.tracker.max_iterations, e);
                          }};
    t["redetect_fraction"] = {
        "detect new features when fewer than this fraction of `features` are tracked",
        [](DeviceConfig& c, const std::string& v, std::string& e) {
          return parseReal(v, 0.0, 1.0, c.tracker.redetect_fraction, e);
        }};
    t["min_distance"] = {"minimum distance between features, px",
                         [](DeviceConfig& c, const std::string& v, std::string& e) {
                           return parseReal(v, 1.0, 200.0, c.tracker.min_distance, e);
                         }};
    t["max_points"] = {"map point capacity",
                       [](DeviceConfig& c, const std::string& v, std::string& e) {
                         return parseInt(v, 64, 1000000, c.map.max_points, e);
                       }};
    t["max_keyframes"] = {"keyframes kept (a ring)",
                          [](DeviceConfig& c, const std::string& v, std::string& e) {
                            return parseInt(v, 3, 1000, c.map.max_keyframes, e);
                          }};
    t["ba_window"] = {"newest keyframes refined by the windowed bundle adjustment",
                      [](DeviceConfig& c, const std::string& v, std::string& e) {
                        return parseInt(v, 2, 100, c.map.ba_window, e);
                      }};
    t["ba_fixed"] = {"older keyframes joining the adjustment as fixed cameras",
                     [](DeviceConfig& c, const std::string& v, std::string& e) {
                       return parseInt(v, 0, 100, c.map.ba_fixed, e);
                     }};
    t["ba_iterations"] = {"Levenberg-Marquardt iterations per adjustment (0: none)",
                          [](DeviceConfig& c, const std::string& v, std::string& e) {
                            return parseInt(v, 0, 100, c.map.ba_iterations, e);
                          }};
    t["reproj_threshold_px"] = {"PnP inlier / triangulation threshold, px",
                                [](DeviceConfig& c, const std::string& v, std::string& e) {
                                  return parseReal(v, 0.1, 50.0, c.map.reproj_threshold_px, e);
                                }};
    t["keyframe_parallax_deg"] = {"median parallax that makes a keyframe",
                                  [](DeviceConfig& c, const std::string& v, std::string& e) {
                                    return parseReal(v, 0.1, 45.0, c.map.keyframe_parallax_deg, e);
                                  }};
    t["keyframe_max_gap"] = {"frames after which a keyframe is taken anyway",
                             [](DeviceConfig& c, const std::string& v, std::string& e) {
                               return parseInt(v, 1, 100000, c.map.keyframe_max_gap, e);
                             }};
    t["init_min_parallax_deg"] = {"median parallax of the initial points",
                                  [](DeviceConfig& c, const std::string& v, std::string& e) {
                                    return parseReal(v, 0.1, 45.0, c.map.init_min_parallax_deg, e);
                                  }};
    t["init_min_displacement"] = {
        "median track displacement (fraction of the width) before an initial pair is tried",
        [](DeviceConfig& c, const std::string& v, std::string& e) {
          return parseReal(v, 0.0, 0.5, c.map.init_min_displacement, e);
        }};
    t["init_max_gap"] = {
        "frames after which an initialisation reference that never succeeded is renewed",
        [](DeviceConfig& c, const std::string& v, std::string& e) {
          return parseInt(v, 1, 1000000, c.map.init_max_gap, e);
        }};
    t["young_map_keyframes"] = {
        "keyframes before the map counts as mature (dense keyframes until then)",
        [](DeviceConfig& c, const std::string& v, std::string& e) {
          return parseInt(v, 0, 1000, c.map.young_map_keyframes, e);
        }};
    t["young_map_keyframe_gap"] = {"frames between keyframes while the map is young",
                                   [](DeviceConfig& c, const std::string& v, std::string& e) {
                                     return parseInt(v, 1, 1000, c.map.young_map_keyframe_gap, e);
                                   }};
    t["calib_pair_displacement"] = {
        "self-calibration: median displacement (fraction of the width) that closes a frame pair",
        [](DeviceConfig& c, const std::string& v, std::string& e) {
          return parseReal(v, 0.005, 0.5, c.map.calib_pair_displacement, e);
        }};
    t["calib_min_pairs"] = {"self-calibration: F pairs before a focal is accepted",
                            [](DeviceConfig& c, const std::string& v, std::string& e) {
                              return parseInt(v, 1, 1000, c.map.calib_min_pairs, e);
                            }};
    t["calib_max_frames"] = {
        "self-calibration: frames after which the fallback focal (1.2 x max(w, h)) is used",
        [](DeviceConfig& c, const std::string& v, std::string& e) {
          return parseInt(v, 1, 100000000, c.map.calib_max_frames, e);
        }};
    t["init_min_points"] = {"points the initial pair must triangulate",
                            [](DeviceConfig& c, const std::string& v, std::string& e) {
                              return parseInt(v, 8, 100000, c.map.init_min_points, e);
                            }};
    t["min_pnp_inliers"] = {"fewer PnP inliers: the frame is lost and the map restarts",
                            [](DeviceConfig& c, const std::string& v, std::string& e) {
                              return parseInt(v, 6, 100000, c.map.min_pnp_inliers, e);
                            }};
    t["seed"] = {"RANSAC seed", [](DeviceConfig& c, const std::string& v, std::string& e) {
                   int s = 0;
                   if (!parseInt(v, 0, 2000000000L, s, e)) return false;
                   c.map.seed = static_cast<uint64_t>(s);
                   return true;
                 }};
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

bool applyConfigValue(DeviceConfig& config, const std::string& key, const std::string& value,
                      std::string& error) {
  const auto& table = keyTable();
  const auto it = table.find(key);
  if (it == table.end()) {
    error = "unknown configuration key '" + key + "'";
    return false;
  }
  std::string why;
  if (!it->second.apply(config, value, why)) {
    error = "bad value for '" + key + "': " + why;
    return false;
  }
  return true;
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
      error = origin + ":" + std::to_string(line_no) + ": expected 'key = value'";
      return false;
    }
    std::string why;
    if (!applyConfigValue(config, trim(line.substr(0, eq)), trim(line.substr(eq + 1)), why)) {
      error = origin + ":" + std::to_string(line_no) + ": " + why;
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
    for (const auto& [name, key] : keyTable()) k.emplace_back(name, key.help);
    return k;
  }();
  return keys;
}

}  // namespace epitrack::device

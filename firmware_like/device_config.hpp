#pragma once

#include <string>
#include <vector>

#include "algo/sfm/live_map.hpp"
#include "algo/tracking/feature_tracker.hpp"

namespace epitrack::device {

/// Everything epitrack-device needs, read once before any frame: the command line and an optional
/// `key = value` file (the command line wins). Capacities here size every buffer of the loop.
struct DeviceConfig {
  std::string source;           ///< INPUT (ARCHITECTURE.md "Inputs")
  std::string intrinsics_path;  ///< intrinsics.txt; empty: centred pinhole with `focal`
  std::string poses = "-";      ///< pose stream: "-" standard output, or a file
  std::string record;           ///< recording: FILE.mjpeg, or a directory of PGM frames
  int max_frames = 0;           ///< 0: until the stream ends or a signal
  bool realtime = false;        ///< pace replay at the nominal rate and drop late frames
  double fps = 30.0;            ///< nominal rate of sources without one (image directories)
  double focal = 0.0;           ///< focal without intrinsics (0: self-calibrated)
  /// Rolling shutter: the sensor's readout, first row to last, in ms (0: global shutter); with
  /// the source's frame rate it becomes map.readout_frames (docs/device.md).
  double readout_ms = 0.0;
  int warmup_frames = 10;  ///< frames left out of the timing statistics
  /// The whole-window residual and refresh set (lk_occlusion_aware = false): the live map was
  /// tuned and measured with it; with the tracker's occlusion-aware default the live KITTI
  /// highway excerpt tracks 24 frames instead of 33.
  FeatureTrackerOptions tracker = FeatureTrackerOptions{}.wholeWindow();
  LiveMapOptions map;
};

/// One `key value` pair (keys as in `configKeys()`); false with `error` on an unknown key or a
/// bad value.
bool applyConfigValue(DeviceConfig& config, const std::string& key, const std::string& value,
                      std::string& error);

/// The same without the key in the message (only why the value is refused), for callers that
/// name the option themselves (`--features: '5' is outside [16..4000]`).
bool applyConfigValueReason(DeviceConfig& config, const std::string& key, const std::string& value,
                            std::string& reason);

/// "[lo..hi]" for a numeric key, empty otherwise.
std::string configKeyRange(const std::string& key);

/// A configuration file: `key = value` lines, `#` comments, blank lines. Errors name the line.
bool applyConfigText(DeviceConfig& config, const std::string& text, const std::string& origin,
                     std::string& error);

/// Checks across keys (capacities that must agree); false with `error`.
bool validateConfig(const DeviceConfig& config, std::string& error);

/// Every accepted key with a one-line description, ending with its range `[lo..hi]` when numeric
/// (for --help and the README).
const std::vector<std::pair<std::string, std::string>>& configKeys();

}  // namespace epitrack::device

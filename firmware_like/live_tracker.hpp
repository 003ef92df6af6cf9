#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>

#include "algo/geometry/camera_intrinsics.hpp"
#include "algo/image/image_view.hpp"
#include "algo/sfm/live_map.hpp"
#include "algo/tracking/feature_tracker.hpp"

namespace epitrack::device {

/// One frame through the live loop.
struct LiveFrameOutput {
  LiveFrameResult map;    ///< status, pose (world-to-camera), map figures
  int features = 0;       ///< live 2D tracks after the frame
  double ms = 0.0;        ///< processing time of the frame (tracker + map)
  double track_ms = 0.0;  ///< of which the 2D tracker
};

/// The device's per-frame work (ARCHITECTURE.md data flow, firmware_like): the 2D FeatureTracker
/// then the LiveMap. Both reserve everything at construction for frames of the intrinsics' size;
/// `process` never allocates. Header-only so tests can drive exactly the device's loop.
class LiveTracker {
 public:
  enum class Status { kOk, kSizeMismatch };

  LiveTracker(const FeatureTrackerOptions& tracker_options, const LiveMapOptions& map_options,
              const CameraIntrinsics& intrinsics)
      : tracker_(tracker_options, intrinsics.width, intrinsics.height),
        map_(map_options, intrinsics) {}

  Status process(ImageView<const uint8_t> frame, LiveFrameOutput& out) {
    const auto start = std::chrono::steady_clock::now();
    if (tracker_.track(frame) != FeatureTracker::Status::kOk) return Status::kSizeMismatch;
    const auto tracked = std::chrono::steady_clock::now();
    const auto features = tracker_.features();
    out.map = map_.process(features);
    out.features = static_cast<int>(features.size());
    const auto end = std::chrono::steady_clock::now();
    out.ms = std::chrono::duration<double, std::milli>(end - start).count();
    out.track_ms = std::chrono::duration<double, std::milli>(tracked - start).count();
    return Status::kOk;
  }

  [[nodiscard]] const FeatureTracker& tracker() const { return tracker_; }
  [[nodiscard]] const LiveMap& map() const { return map_; }

 private:
  FeatureTracker tracker_;
  LiveMap map_;
};

}  // namespace epitrack::device

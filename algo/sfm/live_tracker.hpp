#pragma once

#include <cstdint>

#include "algo/geometry/camera_intrinsics.hpp"
#include "algo/image/image_view.hpp"
#include "algo/sfm/live_map.hpp"
#include "algo/tracking/feature_tracker.hpp"

namespace epitrack {

/// One frame through the live loop.
struct LiveFrameOutput {
  LiveFrameResult map;  ///< status, pose (world-to-camera), map figures
  int features = 0;     ///< live 2D tracks after the frame
};

/// The live loop's per-frame work (ARCHITECTURE.md data flow: the device's loop, epitrack-bench
/// device): the 2D FeatureTracker then the LiveMap. Both reserve everything at construction for
/// frames of the intrinsics' size; `track`, `locate` and `process` never allocate. It reads no
/// clock: a caller that times the stages calls `track` and `locate` in turn (process = both).
class LiveTracker {
 public:
  enum class Status { kOk, kSizeMismatch };

  LiveTracker(const FeatureTrackerOptions& tracker_options, const LiveMapOptions& map_options,
              const CameraIntrinsics& intrinsics)
      : tracker_(tracker_options, intrinsics.width, intrinsics.height),
        map_(map_options, intrinsics) {}

  /// The 2D tracker on `frame`; kSizeMismatch (and nothing changed) for a frame that is not of
  /// the intrinsics' size.
  Status track(ImageView<const uint8_t> frame) {
    return tracker_.track(frame) == FeatureTracker::Status::kOk ? Status::kOk
                                                                : Status::kSizeMismatch;
  }

  /// The live map on the tracks of the frame `track` took last: the pose, or why there is none.
  void locate(LiveFrameOutput& out) {
    const auto features = tracker_.features();
    out.map = map_.process(features);
    out.features = static_cast<int>(features.size());
  }

  /// `track` then, when it succeeds, `locate`.
  Status process(ImageView<const uint8_t> frame, LiveFrameOutput& out) {
    if (track(frame) != Status::kOk) return Status::kSizeMismatch;
    locate(out);
    return Status::kOk;
  }

  [[nodiscard]] const FeatureTracker& tracker() const { return tracker_; }
  [[nodiscard]] const LiveMap& map() const { return map_; }

 private:
  FeatureTracker tracker_;
  LiveMap map_;
};

}  // namespace epitrack

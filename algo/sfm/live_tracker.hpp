#pragma once

#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

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
        map_(map_options, intrinsics),
        predictions_(static_cast<std::size_t>(std::max(tracker_options.max_features, 0))) {}

  /// The 2D tracker on `frame` (with the map's predictions where it has them, see
  /// LiveMapOptions::map_prediction); kSizeMismatch (and nothing changed) for a frame that is
  /// not of the intrinsics' size.
  Status track(ImageView<const uint8_t> frame) {
    prediction_count_ = 0;
    if (map_.options().map_prediction && tracked_poses_ == 2) {
      prediction_count_ = map_.predictTracks(constantVelocityPose(previous_pose_, last_pose_),
                                             std::span<TrackPrediction>(predictions_));
      tracker_.setPredictions(lastPredictions());
    }
    return tracker_.track(frame) == FeatureTracker::Status::kOk ? Status::kOk
                                                                : Status::kSizeMismatch;
  }

  /// The live map on the tracks of the frame `track` took last: the pose, or why there is none.
  void locate(LiveFrameOutput& out) {
    const auto features = tracker_.features();
    out.map = map_.process(features);
    out.features = static_cast<int>(features.size());
    // The pose history of the constant-velocity prediction: consecutive tracked frames only, and
    // not a repeated frame (the tracker kept it out of its filters: the camera did not move by a
    // frame's motion; a zero step in the history would predict the next new frame where the
    // camera was).
    if (out.map.status != LiveStatus::kTracking) {
      tracked_poses_ = 0;
      return;
    }
    if (tracker_.lastStats().repeated != 0) return;
    previous_pose_ = last_pose_;
    last_pose_ = out.map.pose;
    tracked_poses_ = std::min(tracked_poses_ + 1, 2);
  }

  /// `track` then, when it succeeds, `locate`.
  Status process(ImageView<const uint8_t> frame, LiveFrameOutput& out) {
    if (track(frame) != Status::kOk) return Status::kSizeMismatch;
    locate(out);
    return Status::kOk;
  }

  [[nodiscard]] const FeatureTracker& tracker() const { return tracker_; }
  [[nodiscard]] const LiveMap& map() const { return map_; }
  /// The map's predictions handed to the tracker for the frame `track` took last (by id).
  [[nodiscard]] std::span<const TrackPrediction> lastPredictions() const {
    return {predictions_.data(), static_cast<std::size_t>(prediction_count_)};
  }

 private:
  /// The next pose if the camera keeps the motion from `previous` to `last` (world to camera).
  static PoseCw constantVelocityPose(const PoseCw& previous, const PoseCw& last) {
    const Eigen::Matrix3d R_step = last.R_cw * previous.R_cw.transpose();
    const Eigen::Vector3d t_step = last.t_cw - R_step * previous.t_cw;
    PoseCw next;
    next.R_cw = R_step * last.R_cw;
    next.t_cw = R_step * last.t_cw + t_step;
    return next;
  }

  FeatureTracker tracker_;
  LiveMap map_;
  std::vector<TrackPrediction> predictions_;  // max_features
  PoseCw previous_pose_, last_pose_;          // the last two tracked frames' poses
  int tracked_poses_ = 0;                     // of them valid (consecutive tracked frames)
  int prediction_count_ = 0;                  // predictions_ in use for the last frame
};

}  // namespace epitrack

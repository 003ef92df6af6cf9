#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "algo/features/shi_tomasi_detector.hpp"
#include "algo/filter/kalman_filter_cv.hpp"
#include "algo/flow/pyramidal_lk.hpp"
#include "algo/image/image_view.hpp"
#include "algo/image/pyramid.hpp"

namespace epitrack {

/// One live track after a frame.
struct TrackedFeature {
  int32_t id = 0;  ///< stable for the track's life, increasing from 0
  float x = 0.0f;  ///< position in the last frame (pixels)
  float y = 0.0f;
  int32_t age = 0;  ///< frames since detection (0 on the frame it was detected)
};

struct FeatureTrackerOptions {
  int max_features = 300;          ///< target and capacity
  int window = 21;                 ///< LK window side (odd)
  int levels = 3;                  ///< pyramid levels beyond the base
  double min_distance = 10.0;      ///< between features, px (grid based)
  double redetect_fraction = 0.9;  ///< re-detect when fewer than this fraction of max_features live
  int redetect_interval = 0;       ///< also re-detect every N frames when below target (0: never)
  double min_quality = 0.001;      ///< floor of the detector's adaptive threshold (relative)
  bool kalman_gate = true;         ///< reject LK measurements outside the Kalman chi-square gate
  bool forward_backward = false;   ///< reserved: align back into the previous frame (not yet used)
  int max_iterations = 10;         ///< LK iterations per level
  bool affine = true;              ///< base level: affine template warp (else translation only)
  int predicted_after = 3;         ///< tracks at least this old start LK at predicted_start_level
  int predicted_start_level = 0;   ///< (the Kalman prediction replaces the coarse levels)
  double epsilon = 0.01;           ///< LK convergence, px
  double min_eigen = 4.0;          ///< LK texture threshold, (gray/px)^2 per pixel
  // Residuals are relative: RMS error after the intensity offset / template contrast (see
  // PyramidalLk::align). With the affine template the residual stays small while the point is
  // visible; occlusion or sliding onto other structure raises it.
  double refresh_residual = 1e9;    ///< take a new template beyond this (off by default: drifts)
  double max_residual = 0.5;        ///< drop the track beyond this residual (occlusion)
  double max_residual_jump = 0.15;  ///< drop when the residual grows by more than this in a frame
  KalmanCvOptions kalman{};
};

/// Per-frame figures of the last `track` call (for benchmarks and logs). Times are processor
/// milliseconds of the process (std::clock), so a busy machine does not inflate them.
struct FrameStats {
  double pyramid_ms = 0.0;
  double lk_ms = 0.0;
  double kalman_ms = 0.0;
  double detect_ms = 0.0;
  int tracked = 0;
  int lost_lk = 0;  ///< all LK losses; by reason:
  int lost_left_image = 0;
  int lost_no_convergence = 0;
  int lost_low_texture = 0;
  int lost_gate = 0;
  int lost_residual = 0;
  int lost_mask = 0;
  int detected = 0;
  int refreshed = 0;
  long lk_iterations = 0;
};

/// The paper's Figure 4 loop: detect on the first frame; per frame build the pyramid, align every
/// track (pyramidal LK against its template, starting from the Kalman prediction), gate the
/// measurement with the track's constant-velocity Kalman filter, drop outliers, occluded and
/// masked tracks, and re-detect (Shi-Tomasi, away from live tracks) when the live count falls below
/// `redetect_fraction` of `max_features`. Everything is allocated in the constructor; `track` for
/// frames of the configured size never allocates.
class FeatureTracker {
 public:
  enum class Status { kOk, kSizeMismatch, kNotConfigured };

  FeatureTracker(const FeatureTrackerOptions& options, int width, int height);

  /// Processes the next frame. `mask`: empty, or the frame size with 0 = never track here.
  Status track(ImageView<const uint8_t> frame, ImageView<const uint8_t> mask = {});

  /// Live tracks after the last frame (valid until the next `track`).
  [[nodiscard]] std::span<const TrackedFeature> features() const {
    return {output_.data(), static_cast<std::size_t>(output_count_)};
  }
  [[nodiscard]] const FrameStats& lastStats() const { return stats_; }
  [[nodiscard]] const FeatureTrackerOptions& options() const { return options_; }
  [[nodiscard]] int frameCount() const { return frame_index_; }
  [[nodiscard]] const Pyramid& pyramid() const { return pyramid_; }

 private:
  struct Track {
    int32_t id = 0;
    int32_t age = 0;
    float x = 0.0f;
    float y = 0.0f;
    float residual = 0.0f;
    bool live = false;
    PatchShape shape;
    KalmanFilterCv kalman;
  };
  void detect(ImageView<const uint8_t> mask);

  FeatureTrackerOptions options_;
  int width_ = 0;
  int height_ = 0;
  Pyramid pyramid_;
  ShiTomasiDetector detector_;
  PyramidalLk lk_;
  std::vector<Track> tracks_;         // max_features slots
  std::vector<Point2f> live_points_;  // scratch for the detector
  std::vector<Corner> corners_;       // scratch for the detector
  std::vector<TrackedFeature> output_;
  int output_count_ = 0;
  int live_count_ = 0;
  int32_t next_id_ = 0;
  int frame_index_ = 0;
  int frames_since_detect_ = 0;
  FrameStats stats_;
};

}  // namespace epitrack

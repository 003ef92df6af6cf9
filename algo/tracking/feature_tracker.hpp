#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "algo/features/shi_tomasi_detector.hpp"
#include "algo/filter/kalman_filter_cv.hpp"
#include "algo/flow/pyramidal_lk.hpp"
#include "algo/image/image_view.hpp"
#include "algo/image/pyramid.hpp"
#include "algo/tracking/epipolar_track_filter.hpp"
#include "algo/tracking/global_motion.hpp"

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
  /// Re-detection by grid cells (docs/tracker.md, "Re-detection"): the image is cut into about
  /// this many cells, and a re-detection searches only the cells below their share of
  /// max_features that lost tracks since their last search, or whose retry is due (a cell that
  /// could not be filled: retried every redetect_cell_retry frames). 0: the whole frame.
  int redetect_cells = 0;
  int redetect_cell_retry = 10;
  /// At least this many frames between two re-detections, unless a cell that held tracks has
  /// emptied (that is refilled at once). 1: a re-detection may run on every frame.
  int redetect_min_gap = 1;
  /// A searched cell takes corners up to its share of max_features only (uniform coverage; the
  /// strongest corners of the searched cells otherwise, up to max_features in all).
  bool redetect_fill_share = true;
  double min_quality = 0.001;  ///< floor of the detector's adaptive threshold (relative)
  bool kalman_gate = true;     ///< reject LK measurements outside the Kalman chi-square gate
  /// The gate's innovation covariance is widened by (gate_speed_fraction * predicted speed)^2:
  /// real image motion accelerates in proportion to its speed (forward motion, zoom, a hand).
  double gate_speed_fraction = 0.25;
  int max_iterations = 10;        ///< LK iterations per level
  bool affine = true;             ///< base level: affine template warp (else translation only)
  int predicted_after = 3;        ///< tracks at least this old start LK at predicted_start_level
  int predicted_start_level = 0;  ///< (the Kalman prediction replaces the coarse levels)
  /// A track seen once has no velocity yet: start it from the median displacement of its
  /// neighbours tracked in the same frame (within neighbour_radius of the larger image side).
  bool neighbour_prior = true;
  double neighbour_radius = 0.15;
  double epsilon = 0.01;   ///< LK convergence, px
  double min_eigen = 4.0;  ///< LK texture threshold, (gray/px)^2 per pixel
  /// LK residual over the central (2r+1)^2 window (see LkOptions; -1, the default: a quarter of
  /// the window, 5 for 21x21; 0: the whole window, see below).
  int residual_radius = -1;
  // Residuals are relative: RMS error after the intensity offset / template contrast, over the
  // central 11x11 of the window (see
  // PyramidalLk::align). With the affine template the residual stays small while the point is
  // visible; occlusion or sliding onto other structure raises it, and so do noise, blur and
  // compression on real footage, for every track alike. So each threshold is the larger of a
  // fixed value (what a clean image needs) and a multiple of the frame's median residual.
  // A track is dropped beyond max_residual, or when its residual jumps by more than
  // max_residual_jump above its own running level (on its first tracked frame: above
  // max_residual_jump and residual_scale_young frame medians).
  double max_residual = 0.5;          ///< drop beyond this residual (occlusion)
  double max_residual_jump = 0.15;    ///< drop when the residual jumps by more than this
  double residual_scale_max = 3.0;    ///< ... or this many frame medians
  double residual_scale_jump = 1.5;   ///< ... or this many frame medians
  double residual_scale_young = 3.0;  ///< a young track's first residual: this many medians
  /// Template refresh (the template update problem, Matthews, Ishikawa & Baker 2004): a track
  /// whose template no longer looks like its patch must pass the forward-backward check, then
  /// takes a new template at its position; each refresh costs one re-sampling error. A track
  /// qualifies when its residual exceeds refresh_residual (or residual_scale_refresh frame
  /// medians) while its affine shape stretches the template by at least refresh_min_stretch
  /// (singular values beyond [1/s, s]; appearance changed by the warp: foreshortening, scale,
  /// the resampling blur), or whatever its residual once the stretch reaches refresh_stretch
  /// (before the alignment of a strongly warped template turns biased). A residual that grows
  /// while the shape stays close to a rotation is occlusion or another surface sliding in: such
  /// tracks are not refreshed (they die at max_residual), so they cannot follow an occluding
  /// edge. (0: no condition on the stretch / no refresh by stretch alone.)
  ///
  /// The defaults are the occlusion-aware set: the residual over the central 11x11 pixels
  /// (residual_radius -1), a refresh beyond 0.4 (below max_residual, so it fires before the
  /// drop) when the shape stretches by 1.3, or at any residual from a stretch of 1.4: on the
  /// rendered orbit 94 % of the visible first-frame corners survive 100 frames (79 % with the
  /// whole-window set), with the accuracy targets kept. `wholeWindow()` is the earlier set
  /// (whole-window residual, refresh beyond 0.5 whatever the shape); the live device keeps it
  /// (README, on-device accuracy).
  double refresh_residual = 0.4;
  double residual_scale_refresh = 1.5;
  double refresh_min_stretch = 1.3;
  double refresh_stretch = 1.4;
  /// The occlusion-aware residual and refresh settings described above (the defaults).
  FeatureTrackerOptions& occlusionAware() {
    const FeatureTrackerOptions defaults;  // the values are the member initializers above
    residual_radius = defaults.residual_radius;
    refresh_residual = defaults.refresh_residual;
    refresh_min_stretch = defaults.refresh_min_stretch;
    refresh_stretch = defaults.refresh_stretch;
    return *this;
  }
  /// The earlier whole-window residual and refresh settings (see above).
  FeatureTrackerOptions& wholeWindow() {
    residual_radius = 0;
    refresh_residual = 0.5;
    refresh_min_stretch = 0.0;
    refresh_stretch = 0.0;
    return *this;
  }
  /// The forward-backward check (young and drifted tracks): the track's patch in this frame,
  /// aligned back into the previous frame from the mirrored prediction, must land within this
  /// of where the track came from (0: no check, no refresh).
  double forward_backward_px = 0.75;
  bool forward_backward = false;  ///< check every track, not only young and drifted ones
  /// The backward alignment starts on the finest pyramid level where the forward alignment's
  /// correction (how far the track landed from its prediction, which is how far the mirrored
  /// start is from the answer) is at most this many of the level's pixels (0, the default: the
  /// coarsest). 2 px saves about 500 LK iterations per frame on the KITTI highway excerpt (of
  /// 8 800) and 50 on the orbit, but moves the real templeRing 12-30 self-calibrated focal 1.8 %
  /// off (its solve flips with small changes of the tracks; docs/tracker.md).
  double forward_backward_start_px = 0.0;
  KalmanCvOptions kalman{};
  /// The epipolar check (docs/tracker.md "Epipolar check"): tracks that stay off the rigid
  /// two-view relation (F, or H for a rotation or a plane) over a window of frames are dropped.
  /// Off by default: on the occlusion clip it does not lower the errors (the far tracks there
  /// jump onto an occluder and then follow it rigidly); it costs 0.3 ms per 704x576 frame on
  /// average (up to 1 ms on a checking frame; LK takes 1.3 ms there).
  bool epipolar_check = false;
  EpipolarFilterOptions epipolar{};
  /// The camera's image motion per frame (docs/tracker.md, the motion model): up to
  /// motion_anchors established tracks, spread over a 4x4 grid, are probed first through the
  /// whole pyramid; a robust similarity between their constant-velocity predictions and where
  /// they are found (what the camera changed) is a control input of every Kalman filter, so every
  /// track's prediction and gate follow a camera jerk.
  bool global_motion = true;
  int motion_anchors = 48;
  /// The global motion is what departs from the tracks' own constant velocity (the camera's
  /// acceleration); this fraction of it is added to every track's velocity (1: the camera keeps
  /// its new velocity, as a pan or a vehicle does; 0: it returns, as shake does).
  double motion_velocity_gain = 1.0;
  /// The fitted motion is used when at least motion_clear_majority of the probed anchors are its
  /// inliers, or motion_min_inlier_fraction of them and it moves some image corner by at least
  /// motion_min_shift_px; else the frame keeps each track's own prediction (see the .cpp).
  double motion_clear_majority = 0.7;
  double motion_min_inlier_fraction = 0.5;
  double motion_min_shift_px = 5.0;
  /// The anchors are probed in two rounds: first motion_quick_per_cell per grid cell (16 of the
  /// 48); when those agree (motion_clear_majority) on a motion that moves no image corner by
  /// motion_quiet_px or more, the tracks' own velocities predict the frame and the model is
  /// the identity; otherwise (a jerk, parallax, a split vote) the other anchors are probed too and
  /// the model is decided on all of them (the same fit as one round). 0: one round; 1 at most.
  int motion_quick_per_cell = 1;
  double motion_quiet_px = 1.0;
  GlobalMotionOptions motion{};
  /// A frame whose mean absolute difference from the previous one is at most this many 1/256
  /// grey levels (64: 0.25) repeats it: the tracks stay, no filter is updated, no LK runs
  /// (framesNearlyEqual; docs/tracker.md, "Repeated frames"). 0: every frame is tracked.
  uint32_t repeat_max_mean_diff_q8 = 64;
  /// When more than this fraction of the tracks judged by the gate (at least gate_release_min)
  /// fail it in one frame, the frame moved, not the tracks: the gate is not applied that frame.
  double gate_release_fraction = 0.5;
  int gate_release_min = 10;
  /// Predictions supplied from outside (setPredictions: the live map's projections of its points
  /// under a predicted pose). LK starts on the finest pyramid level whose reach covers this many
  /// pixels (its window's quarter, scaled by the level), and a track that does not converge there,
  /// or lands farther than this from the prediction, is aligned again from its own prediction as
  /// if it had none (the map point may be wrong: a poorly triangulated one, a drifted track).
  double prediction_radius_px = 4.0;
};

/// A supplied position of a track in the next frame (FeatureTracker::setPredictions).
struct TrackPrediction {
  int32_t id = 0;
  float x = 0.0f;
  float y = 0.0f;
};

/// Why a track was dropped (see FeatureTracker::lost).
enum class TrackLoss : uint8_t {
  kLeftImage,        ///< the LK window left the image
  kLowTexture,       ///< the template has too little texture
  kNoConvergence,    ///< the LK update did not settle
  kResidual,         ///< residual too high, or a jump above the track's level (occlusion)
  kForwardBackward,  ///< the forward-backward check failed
  kGate,             ///< outside the Kalman gate (the paper §4.2)
  kMask,             ///< moved into a masked region
  kEpipolar,         ///< off the rigid two-view relation over several checks (EpipolarTrackFilter)
};
const char* trackLossName(TrackLoss loss);

/// A track dropped in the last frame, with its last accepted position.
struct LostTrack {
  int32_t id = 0;
  float x = 0.0f;
  float y = 0.0f;
  int32_t age = 0;
  TrackLoss reason = TrackLoss::kGate;
};

/// Fault injection (tests of the outlier gate): called with every track's LK measurement of the
/// frame before it is judged; it may move (x, y). `frame` counts track() calls from 0.
using MeasurementHook = void (*)(void* context, int32_t track_id, int frame, float& x, float& y);

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
  int lost_forward_backward = 0;
  int lost_mask = 0;
  int lost_epipolar = 0;  ///< dropped by the epipolar check (not part of lost_lk)
  double epipolar_ms = 0.0;
  int detected = 0;
  int detect_cells = 0;  ///< grid cells searched by the re-detection (all of them: whole frame)
  int refreshed = 0;
  int forward_backward_checks = 0;
  double residual_median = 0.0;  ///< the frame's typical relative residual (the scale)
  long lk_iterations = 0;
  int predicted = 0;              ///< tracks aligned from a supplied prediction (setPredictions)
  int prediction_fallbacks = 0;   ///< ... of them aligned again from their own prediction
  long predicted_iterations = 0;  ///< LK iterations of the tracks with a supplied prediction
  int motion_anchors = 0;         ///< anchor tracks aligned for the global motion
  int motion_inliers = 0;         ///< ... that agree with it (0: no model, the last one kept)
  double motion_dx = 0.0;         ///< the global motion at the image centre, px
  double motion_dy = 0.0;
  int repeated = 0;       ///< 1: the frame repeated the previous one; tracks kept, nothing aligned
  int gate_released = 0;  ///< tracks let through because the whole frame failed the gate
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
  /// The input lost `count` frames (corrupt, dropped) before the next `track` call: the Kalman
  /// prediction then spans 1 + count frame intervals instead of one.
  void skipFrames(int count) { skipped_frames_ += count > 0 ? count : 0; }

  /// Live tracks after the last frame (valid until the next `track`).
  [[nodiscard]] std::span<const TrackedFeature> features() const {
    return {output_.data(), static_cast<std::size_t>(output_count_)};
  }
  /// Tracks dropped by the last `track` call, with the reason (valid until the next call).
  [[nodiscard]] std::span<const LostTrack> lost() const {
    return {lost_.data(), static_cast<std::size_t>(lost_count_)};
  }
  [[nodiscard]] const FrameStats& lastStats() const { return stats_; }
  /// Installs (or with nullptr removes) a measurement hook; see MeasurementHook.
  void setMeasurementHook(MeasurementHook hook, void* context) {
    measurement_hook_ = hook;
    measurement_hook_context_ = context;
  }
  /// Positions where tracks are expected in the next frame, by id (at most max_features; more are
  /// ignored). Used by the next `track` call only: a track with one starts LK there (see
  /// prediction_radius_px) and its gate is centred there; the others keep their own prediction.
  void setPredictions(std::span<const TrackPrediction> predictions);
  [[nodiscard]] const FeatureTrackerOptions& options() const { return options_; }
  [[nodiscard]] int frameCount() const { return frame_index_; }
  [[nodiscard]] const Pyramid& pyramid() const { return pyramids_[current_]; }

 private:
  struct Candidate {  // this frame's alignment of a track, before it is judged
    float x = 0.0f;
    float y = 0.0f;
    float predicted_x = 0.0f;  // where the alignment started
    float predicted_y = 0.0f;
    float residual = 0.0f;
    PatchShape shape;
    LkStatus status = LkStatus::kNoConvergence;
    bool gate_ok = true;    // inside the Kalman gate (judged before the per-track decisions)
    bool supplied = false;  // aligned from a supplied prediction (setPredictions)
  };
  struct Track {
    int32_t id = 0;
    int32_t age = 0;
    float x = 0.0f;
    float y = 0.0f;
    float residual = 0.0f;        // last frame's
    float residual_level = 0.0f;  // running level (exponential average)
    bool live = false;
    PatchShape shape;
    KalmanFilterCv kalman;
    Candidate candidate;
  };
  /// Detects new tracks away from the live ones: in `regions`, or the whole frame when empty.
  void detect(ImageView<const uint8_t> mask, std::span<const DetectionRegion> regions);
  /// This frame's re-detection decision and search (whole frame or grid cells).
  void redetect(ImageView<const uint8_t> mask);
  /// Fewer live tracks than redetect_fraction of max_features, or redetect_interval reached.
  [[nodiscard]] bool redetectDue() const;
  /// The cell policy (redetect_cells > 0), when a re-detection is due: searches the needy cells.
  void redetectInCells(ImageView<const uint8_t> mask);
  /// Live tracks per grid cell into cell_count_.
  void countTracksPerCell();
  /// After a search of the cells flagged in cell_needy_ (all when `all`): their new level and
  /// the frame of their next retry.
  void recordSearchedCells(bool all);
  /// The runs of needy cells of each grid row into regions_, each wanting its cells' deficits
  /// below their share (no cap with redetect_fill_share off); returns the count.
  int needyRegions();
  /// The epipolar check over this frame's accepted tracks; drops the ones it rejects.
  void epipolarCheck();
  /// Aligns track `slot` into this frame (its candidate); `young`: seen in one frame only.
  void alignOne(std::size_t slot, bool young);
  /// Ends track `t`: counted in `counter`, recorded in lost_ with `reason`.
  void dropTrack(Track& t, int& counter, TrackLoss reason);
  /// The live tracks into the output array (what `features()` returns).
  void publishTracks();
  /// A frame equal to the previous one: tracks kept, filters untouched (see the .cpp).
  void keepRepeatedFrame();
  /// The end of alignOne: the measurement hook and the neighbours' record of the motion.
  void finishAlignment(Track& t, bool young, float x0, float y0);
  /// Picks the anchors, probes them and fits this frame's global motion (motion_).
  void estimateGlobalMotion();
  /// Probes up to per_cell anchors per grid cell into motion_estimator_, skipping the first
  /// skip_first_per_cell of each cell (probed before); returns the anchors counted.
  int probeAnchors(int per_cell, int skip_first_per_cell);
  /// The largest displacement of an image corner under `m`, px.
  [[nodiscard]] double cornerShift(const SimilarityMotion& m) const;
  static constexpr int kMotionGrid = 4;  // anchors are spread over a kMotionGrid^2 grid
  struct FirstRoundProbe {  // an anchor's prediction and where the first round found it
    double px, py, qx, qy;
  };
  // The first round's probes (quick <= 1 per cell) in slot order, the slot list ended by -1.
  FirstRoundProbe first_round_[kMotionGrid * kMotionGrid] = {};
  int first_round_slot_[kMotionGrid * kMotionGrid + 1] = {};
  int first_round_count_ = 0;
  int first_round_next_ = 0;
  /// Where anchor `t` is expected before the global motion is known: its own constant-velocity
  /// prediction (with the Kalman filter), else the last frame's global motion.
  void anchorPrediction(const Track& t, double& px, double& py) const;
  /// Moves every live track's Kalman filter by the global motion and predicts it.
  void predictAll();
  /// Keeps or drops track `slot` after alignOne (residual, check, mask, gate).
  void decideOne(std::size_t slot, bool young, double residual_scale,
                 ImageView<const uint8_t> mask);
  /// Median displacement of the tracks already tracked this frame near (x, y).
  void neighbourMotion(float x, float y, float& dx, float& dy);
  /// Forward-backward check of a track that moved from (x0, y0) to (x, y) with the prediction
  /// (px, py): its patch at (x, y) in this frame, aligned back into the previous frame from the
  /// mirrored prediction, must land within forward_backward_px of (x0, y0).
  bool forwardBackward(float x0, float y0, float x, float y, float px, float py);
  /// The Kalman gate centred on (cx, cy), with the innovation covariance widened in proportion to
  /// the speed.
  bool gateAccepts(const KalmanFilterCv& kalman, double mx, double my, double cx, double cy) const;
  /// Track `t`'s own prediction for this frame into (px, py) (its last position on entry).
  void ownPrediction(const Track& t, bool young, float& px, float& py);
  /// The supplied prediction of track `id` for this frame, or nullptr.
  [[nodiscard]] const TrackPrediction* suppliedPrediction(int32_t id) const;
  /// Aligns candidate `c` of track `slot` from a supplied prediction `p` on the level the radius
  /// needs; false when it did not converge within prediction_radius_px of it.
  bool alignFromSupplied(int slot, const TrackPrediction& p, Candidate& c);

  FeatureTrackerOptions options_;
  int width_ = 0;
  int height_ = 0;
  Pyramid pyramids_[2];  // this frame's and the previous one (for the forward-backward check)
  int current_ = 0;
  ShiTomasiDetector detector_;
  PyramidalLk lk_;
  EpipolarTrackFilter epipolar_;
  std::vector<Track> tracks_;         // max_features slots
  std::vector<Point2f> live_points_;  // scratch for the detector
  std::vector<Corner> corners_;       // scratch for the detector
  std::vector<TrackedFeature> output_;
  std::vector<LostTrack> lost_;               // max_features slots
  std::vector<TrackPrediction> predictions_;  // max_features, sorted by id (setPredictions)
  int prediction_count_ = 0;
  int prediction_start_level_ = 0;  // LK's start level for a supplied prediction
  int lost_count_ = 0;
  MeasurementHook measurement_hook_ = nullptr;
  void* measurement_hook_context_ = nullptr;
  // Displacements of the tracks tracked so far this frame (for neighbour priors), and scratch.
  std::vector<float> moved_x_, moved_y_, moved_dx_, moved_dy_, scratch_dx_, scratch_dy_;
  int moved_count_ = 0;
  float global_dx_ = 0.0f;  // median of all moved_* (valid when moved_count_ > 0)
  float global_dy_ = 0.0f;
  bool global_ready_ = false;
  GlobalMotionEstimator motion_estimator_;
  SimilarityMotion motion_;       // this frame's camera motion (previous frame -> this one)
  SimilarityMotion last_motion_;  // the previous frame's (the anchors' prediction)
  bool gate_released_ = false;    // this frame failed the gate as a whole (see track)
  int output_count_ = 0;
  int live_count_ = 0;
  int32_t next_id_ = 0;
  int frame_index_ = 0;
  int skipped_frames_ = 0;  ///< frames lost since the last track() call
  int frames_since_detect_ = 0;
  // The re-detection grid (redetect_cells > 0): cell_cols_ x cell_rows_ cells of the image.
  int cell_cols_ = 0;
  int cell_rows_ = 0;
  int cell_share_ = 0;                    // max_features / cells, rounded up
  std::vector<int> cell_count_;           // live tracks per cell (this frame)
  std::vector<int> cell_held_;            // live tracks right after the cell's last search
  std::vector<int> cell_retry_at_;        // frame from which a cell short of its share is re-tried
  std::vector<uint8_t> cell_needy_;       // this frame's cells to search
  std::vector<DetectionRegion> regions_;  // their rectangles (runs of a grid row), deficits
  FrameStats stats_;
};

}  // namespace epitrack

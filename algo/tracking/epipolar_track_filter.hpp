#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/geometry/fundamental.hpp"
#include "algo/geometry/homography.hpp"

namespace epitrack {

struct EpipolarFilterOptions {
  /// Past frames of track history kept: the reference frame is at most `window` frames back.
  int window = 10;
  /// The reference frame is the most recent one whose median track displacement against the
  /// current frame reaches this (px); with none, the oldest frame of the window that still
  /// shares min_tracks tracks with the current one. A long span lets a slow slide grow beyond
  /// the threshold (0.4 px/frame over 10 frames: 4 px); fast motion needs a shorter one (tracks
  /// leave the view, and F is well conditioned after a few frames already).
  double min_displacement_px = 40.0;
  /// No check when even the oldest frame's median displacement stays below this (px): over a
  /// tiny baseline neither F nor the error scale is reliable.
  double min_span_displacement_px = 2.0;
  /// Tracks present in both frames needed for a check (the eight-point RANSAC's support).
  int min_tracks = 24;
  /// A track's error (Sampson distance to F, or transfer distance of H) is beyond the frame's
  /// threshold when it exceeds the larger of min_error_px and median_multiple times the median
  /// error of all checked tracks (the frame's noise scale: blur, noise, lens distortion).
  double min_error_px = 1.0;
  double median_multiple = 6.0;
  /// A model whose RANSAC inliers are fewer than this fraction of the checked tracks does not
  /// describe the frame pair (rolling shutter, a non-rigid scene, a bad fit): it rejects nothing.
  double min_inlier_fraction = 0.8;
  /// A check every `interval` frames (the history is recorded every frame): the cost is two
  /// RANSAC fits per check, and a slide needs several frames to grow anyway.
  int interval = 2;
  /// Checks in a row a track must fail before it is rejected (one noisy frame is not enough).
  int consecutive = 2;
  /// RANSAC of F and H: inlier threshold (px), a fixed iteration bound, the seed.
  double ransac_threshold_px = 1.0;
  int ransac_iterations = 200;
  uint64_t seed = 1;
  /// Noise floor of the GRIC model selection (px): the noise estimate is the larger of this
  /// and the robust scale of the F fit's Sampson distances.
  double gric_min_sigma_px = 0.25;
};

/// What the last check did (for logs and tests).
struct EpipolarCheckSummary {
  enum class Model : uint8_t { kNone, kFundamental, kHomography };
  Model model = Model::kNone;  ///< kNone: no check (too little displacement or too few tracks)
  int reference_age = 0;       ///< frames between the reference frame and the current one
  int checked = 0;             ///< tracks present in both frames
  int inliers = 0;             ///< RANSAC inliers of the model used
  double median_displacement_px = 0.0;
  double median_error_px = 0.0;
  double threshold_px = 0.0;
  int beyond = 0;    ///< tracks beyond the threshold in this check
  int rejected = 0;  ///< ... of which failed `consecutive` checks in a row
};

/// Epipolar outlier rejection over 2D tracks (issue 20 item 2; the paper's §5.1 eight-point
/// RANSAC applied to the tracks themselves). Keeps a ring of the last `window` frames' track
/// positions by slot and id; per frame it picks the most recent frame with enough displacement
/// against the current one, fits F (normalized eight-point in RANSAC, seeded, bounded) and H
/// (four-point DLT in RANSAC) between the two, lets Torr's GRIC choose (H for a pure rotation or
/// a plane, where F is undetermined), and flags every track whose error is beyond the frame's
/// threshold; a track flagged `consecutive` checks in a row is rejected. A track that slides
/// along an occluding edge is smooth and forward-backward consistent, but not rigid: its
/// displacement leaves its epipolar line. Everything is sized at construction; `beginFrame`,
/// `observe` and `endFrame` never allocate, and the result is a pure function of the input.
class EpipolarTrackFilter {
 public:
  /// `capacity`: the number of track slots (slot indices 0..capacity-1).
  EpipolarTrackFilter(const EpipolarFilterOptions& options, int capacity);

  /// Starts a frame: no track observed yet.
  void beginFrame();
  /// The position of the track `id` living in `slot` in this frame (ignored out of range).
  void observe(int slot, int32_t id, float x, float y);
  /// Checks this frame's tracks against the reference frame, records the frame into the history
  /// and returns how many tracks were rejected (see rejected()).
  int endFrame();
  /// True when the track observed in `slot` this frame was rejected by endFrame.
  [[nodiscard]] bool rejected(int slot) const {
    return slot >= 0 && slot < capacity_ && rejected_[static_cast<std::size_t>(slot)] != 0;
  }
  /// The error (px) of the track in `slot` in the last check (negative: not checked).
  [[nodiscard]] float error(int slot) const {
    return slot >= 0 && slot < capacity_ ? error_[static_cast<std::size_t>(slot)] : -1.0f;
  }
  [[nodiscard]] const EpipolarCheckSummary& lastCheck() const { return summary_; }
  [[nodiscard]] const EpipolarFilterOptions& options() const { return options_; }
  /// Forgets the history (a cut, a new clip).
  void reset();

 private:
  /// Position of history frame `age` frames back (1 = the previous frame) in the ring.
  [[nodiscard]] std::size_t ringRow(int age) const;
  /// Chooses the reference frame; returns its age (0: none).
  int chooseReference();
  /// Gathers the correspondences between the reference frame `age` back and this frame.
  int gather(int age);
  void check(int age);
  void record();

  EpipolarFilterOptions options_;
  int capacity_ = 0;
  int window_ = 0;
  // The history ring: window_ rows of capacity_ slots (id -1: no track in that slot then).
  std::vector<float> hist_x_, hist_y_;
  std::vector<int32_t> hist_id_;
  int newest_ = -1;  // row of the most recent recorded frame
  int filled_ = 0;   // recorded frames (<= window_)
  // This frame's observations.
  std::vector<float> cur_x_, cur_y_;
  std::vector<int32_t> cur_id_;
  // Per slot: the track whose strikes are counted, its failed checks in a row, the verdict.
  std::vector<int32_t> strike_id_;
  std::vector<int> strikes_;
  std::vector<uint8_t> rejected_;
  std::vector<float> error_;
  // Correspondences of one check and scratch.
  std::vector<Eigen::Vector2d> x_ref_, x_cur_;
  std::vector<int> pair_slot_;
  std::vector<double> values_;
  int pairs_ = 0;
  FundamentalRansac fundamental_;
  HomographyRansac homography_;
  uint64_t checks_ = 0;  // checks run so far (mixed into the RANSAC seed)
  uint64_t frames_ = 0;  // endFrame calls since construction or reset
  EpipolarCheckSummary summary_;
};

}  // namespace epitrack

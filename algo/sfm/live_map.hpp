#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/geometry/camera_intrinsics.hpp"
#include "algo/geometry/essential.hpp"
#include "algo/geometry/essential_five_point.hpp"
#include "algo/geometry/focal_self_calibration.hpp"
#include "algo/geometry/fundamental.hpp"
#include "algo/geometry/homography.hpp"
#include "algo/geometry/pnp.hpp"
#include "algo/geometry/pose.hpp"
#include "algo/geometry/rolling_shutter.hpp"
#include "algo/sfm/bundle_adjustment.hpp"
#include "algo/tracking/feature_tracker.hpp"

namespace epitrack {

/// Capacities and thresholds of the live map. Every buffer is sized from these at construction.
struct LiveMapOptions {
  int max_features = 300;  ///< tracks per frame (the FeatureTracker's max_features)
  int max_points = 2000;   ///< map points alive at once ("full" stops triangulation, never grows)
  int max_keyframes = 32;  ///< keyframes kept (poses and observations), a ring
  int ba_window = 10;      ///< newest keyframes refined at each new keyframe
  int ba_fixed =
      5;  ///< older keyframes joining the adjustment as fixed cameras, spread over the ring
  /// Levenberg-Marquardt iterations per windowed adjustment. Few on purpose: consecutive windows
  /// overlap (a keyframe is refined by ba_window adjustments), so the map still converges over
  /// the keyframes, while one adjustment cannot drag the window far along the monocular map's
  /// weak mode (rotation traded for translation and depth), which the poses already sent cannot
  /// follow. Measured on 5 rendered orbits and 2 hand-held walks (README, device accuracy):
  /// 6 iterations gave live/offline ATE ratios up to 4.5, 2 (with young_map_keyframes 8) <= 1.9.
  int ba_iterations = 2;
  double huber_px = 1.0;
  double reproj_threshold_px = 2.5;      ///< PnP inlier and triangulation acceptance threshold
  int init_min_tracks = 60;              ///< tracks common to the reference frame and the current
  double init_min_displacement = 0.015;  ///< median track displacement (x image width) to try
  double init_min_parallax_deg = 2.0;    ///< median parallax of the initial points
  int init_min_points = 50;              ///< triangulated points needed to accept an initial pair
  int init_max_gap = 300;  ///< frames after which a reference that never initialised is renewed
  double min_point_parallax_deg = 1.0;  ///< triangulation: angle between the two rays
  double keyframe_parallax_deg = 0.3;   ///< new keyframe at this median parallax to the last
  int keyframe_max_gap = 8;             ///< or after this many frames
  int young_map_keyframes = 8;          ///< until the map has this many keyframes ...
  int young_map_keyframe_gap = 1;       ///< ... a keyframe every this many frames
  double keyframe_min_tracked = 0.7;  ///< or when inliers fall below this fraction of the last kf's
  int min_pnp_inliers = 15;           ///< fewer: the frame is lost
  int max_outlier_frames = 2;  ///< consecutive PnP outlier frames that detach a track's point
  /// Robust pose refinement (as SolverOptions): each frame's pose is refined once more on the
  /// PnP inliers within outlier_sigmas of the residual scale (median-based, smoothed over
  /// frames), with a Huber threshold of huber_sigmas. 0 disables it.
  double outlier_sigmas = 4.0;
  double huber_sigmas = 2.0;
  double min_outlier_px = 0.1;
  uint64_t seed = 1;
  /// Rolling shutter (issue 27): the sensor's readout from the first row to the last, in frame
  /// intervals (0: global shutter). Each tracked frame's pose is then its middle row's, refined
  /// with the camera's motion over the readout after the PnP (refineRollingShutterPose), and the
  /// windowed adjustment refines the keyframes' motions with their poses (BundleAdjuster::solve
  /// with motions). Everything is sized at construction: no allocation per frame either way.
  double readout_frames = 0.0;
  // Focal self-calibration (paper §5.2) before the map, when the intrinsics are not given: the
  // camera is taken as a centred pinhole (fx = fy = f, principal point at the image centre) and f
  // is estimated from the fundamental matrices of frame pairs over the first seconds.
  bool self_calibrate = false;
  int calib_references = 8;               ///< reference frames followed at once
  int calib_reference_interval = 10;      ///< frames between new references
  double calib_pair_displacement = 0.04;  ///< median displacement (x width) that closes a pair
  int calib_min_pairs = 5;                ///< F pairs before a focal is accepted
  int calib_max_pairs = 24;               ///< a ring: the newest pairs are kept
  int calib_max_frames = 450;             ///< no observable focal by then: the fallback focal
  double fallback_focal_widths = 1.2;     ///< fallback focal, x max(width, height)
  /// The live loop (LiveTracker) predicts the next frame's tracks with the map: the pose by
  /// constant velocity from the last two tracked frames, the map points of the live tracks
  /// projected with it (predictTracks), handed to the FeatureTracker as LK's start and the
  /// gate's centre (FeatureTrackerOptions::prediction_radius_px).
  bool map_prediction = true;
};

enum class LiveStatus { kInitializing, kTracking, kLost };
const char* toString(LiveStatus s);

/// Why the live map is still initialising: the step of the two-view initialisation (or of the
/// focal self-calibration before it) that the frame did not pass.
enum class LiveInitStage {
  kNone,               ///< not initialising (tracking, lost, or initialised on this frame)
  kCalibrating,        ///< self-calibrating the focal: F pairs collected so far in `pairs`
  kNewReference,       ///< a new reference frame was taken (the old one faded out or got old)
  kTooFewTracks,       ///< fewer tracks common with the reference than init_min_tracks
  kTooLittleMotion,    ///< the common tracks moved less than init_min_displacement
  kNoTwoViewGeometry,  ///< F-RANSAC failed, too few inliers, or an ambiguous cheirality
  kTooFewPoints,       ///< fewer triangulated points than init_min_points
  kTooLittleParallax,  ///< the points' median parallax below init_min_parallax_deg
};
const char* toString(LiveInitStage s);

/// The initialisation's figures on one frame (LiveFrameResult::init), for the device's output.
struct LiveInitProgress {
  LiveInitStage stage = LiveInitStage::kNone;
  int tracks_alive = 0;          ///< tracks in this frame
  int common_tracks = 0;         ///< of them, also in the reference frame
  double displacement_px = 0.0;  ///< their median displacement since the reference
  int points = 0;                ///< points triangulated by this frame's attempt (0: none made)
  double parallax_deg = 0.0;     ///< their median parallax (0: no attempt got that far)
  int64_t reference_frame = -1;  ///< frame index of the reference (-1: none)
  int pairs = 0;                 ///< kCalibrating: F pairs collected for the focal so far
};

/// What `LiveMap::process` concluded for one frame.
struct LiveFrameResult {
  LiveStatus status = LiveStatus::kInitializing;
  PoseCw pose;               ///< world-to-camera; valid when tracking
  int map_matches = 0;       ///< tracks of this frame with a map point
  int inliers = 0;           ///< PnP inliers (tracking)
  bool keyframe = false;     ///< this frame became a keyframe
  bool initialized = false;  ///< the map was (re)initialised on this frame
  bool calibrated = false;   ///< calibration ended on this frame (self-calibrated or fallback)
  int points = 0;            ///< map points in use after the frame
  LiveInitProgress init;     ///< while kInitializing: why, and how far it got
};

/// The live 3D tracker of the device (paper §5 run causally, Figure 2): 2D tracks in, a camera
/// pose out, every frame. While initialising, the first frame with tracks is the reference; once
/// the median track displacement is large enough, F-RANSAC (§5.1), E from F with the given
/// intrinsics, the cheirality test over all inliers (§5.3) and two-view refinement give the
/// relative pose, and the inliers are triangulated; the pair is accepted when enough points with
/// enough median parallax exist. Afterwards each frame is resected by PnP-RANSAC + refinement on
/// the map points of its tracks (§5.4); a frame becomes a keyframe by measured parallax (or track
/// loss or a gap), tracks without a point are triangulated between their first keyframe and the
/// new one, and a windowed bundle adjustment refines the newest keyframes against older ones spread
/// over the keyframe ring (fixed: they hold the gauge and the long baselines). When resection fails
/// the frame is `kLost` and the map restarts from it.
///
/// Memory: records per live track, a keyframe ring with its observations, the point pool and the
/// solvers' workspaces are sized at construction; `process` never allocates.
class LiveMap {
 public:
  LiveMap(const LiveMapOptions& options, const CameraIntrinsics& intrinsics);

  /// One frame's tracks (at most max_features, ids as the FeatureTracker gives them).
  LiveFrameResult process(std::span<const TrackedFeature> features);
  /// Where the live tracks with a usable map point are seen by a camera of pose `pose` (in
  /// pixels, with the lens distortion), into `out` (room for max_features); returns the count.
  /// Points behind the camera or projecting outside the image are left out.
  int predictTracks(const PoseCw& pose, std::span<TrackPrediction> out) const;
  /// Forgets the map and starts initialising again from the next frame.
  void reset();

  [[nodiscard]] int pointCount() const { return points_in_use_; }
  [[nodiscard]] int keyframeCount() const { return static_cast<int>(kf_next_seq_ - kf_first_seq_); }
  [[nodiscard]] bool initialized() const { return state_ == State::kTracking; }
  [[nodiscard]] const LiveMapOptions& options() const { return options_; }
  /// The intrinsics in use (the self-calibrated focal once `focalKnown`).
  [[nodiscard]] const CameraIntrinsics& intrinsics() const { return K_; }
  /// False while self-calibration has not produced a focal yet.
  [[nodiscard]] bool focalKnown() const { return state_ != State::kCalibrating; }
  /// Pairs the self-calibration used (0 with given intrinsics).
  [[nodiscard]] int calibrationPairs() const { return calib_pairs_used_; }
  /// True when self-calibration gave up (no observable focal within calib_max_frames).
  [[nodiscard]] bool focalFallback() const { return calib_fallback_; }
  /// Bytes reserved by this object's buffers (for the memory report).
  [[nodiscard]] std::size_t reservedBytes() const;

 private:
  enum class State { kCalibrating, kInitializing, kTracking };
  struct TrackRecord {
    int32_t id = 0;
    int point = -1;                 // map point of this track, -1 none
    int64_t first_kf = -1;          // keyframe sequence of the first observation kept, -1 none
    Eigen::Vector2d first_n{0, 0};  // normalized coordinates in that keyframe
    Eigen::Vector2d first_px{0, 0};
    bool has_ref = false;  // observed in the initialisation reference frame
    Eigen::Vector2d ref_n{0, 0};
    Eigen::Vector2d ref_px{0, 0};
    Eigen::Vector2d n{0, 0};   // this frame, normalized (undistorted)
    Eigen::Vector2d px{0, 0};  // this frame, raw pixels
    int outlier_frames = 0;
    bool inlier = false;  // PnP inlier this frame
  };
  struct MapPointSlot {
    Eigen::Vector3d X = Eigen::Vector3d::Zero();
    bool used = false;
    bool valid = false;     // usable for resection and adjustment
    bool attached = false;  // a live track refers to it
    int64_t last_kf = -1;   // newest keyframe observing it
  };
  struct KeyframeObservation {
    int point = 0;
    Eigen::Vector2d px{0, 0};
  };
  struct Keyframe {
    int64_t seq = -1;
    int64_t frame = 0;
    PoseCw pose;
    RollingShutterMotion motion;  ///< over the readout (zero for a global shutter)
    int obs_count = 0;
    int inliers = 0;
  };

  void mergeTracks(std::span<const TrackedFeature> features);
  bool calibrateStep();
  [[nodiscard]] Eigen::Vector2d normalize(double x, double y) const;
  void setReference();
  /// The initial pair's F, or E from five points where the matches are a plane's (see .cpp).
  bool initialPairModel(std::span<const Eigen::Vector2d> x1, std::span<const Eigen::Vector2d> x2,
                        std::span<const Eigen::Vector2d> n1, std::span<const Eigen::Vector2d> n2,
                        const Eigen::Matrix3d& K, const FundamentalResult& fr, Eigen::Matrix3d& F,
                        std::span<const uint8_t>& mask);
  bool tryInitialize(LiveFrameResult& result);
  bool trackFrame(LiveFrameResult& result);
  void robustRefine(std::size_t matches, PnpResult& pr);
  /// Rolling shutter: the frame's middle-row pose and motion_ refined on the PnP inliers.
  void refineRollingShutter(std::size_t matches, PnpResult& pr);
  bool needKeyframe(const PoseCw& pose, int inliers);
  int64_t addKeyframe(const PoseCw& pose, int inliers);
  void addObservation(int64_t kf_seq, int point, const Eigen::Vector2d& px);
  int triangulateNew(int64_t kf_seq);
  void adjustWindow();
  void restoreScale(int n_cams, int n_pts);
  int allocatePoint(const Eigen::Vector3d& X);
  void collectGarbage();
  Keyframe* keyframe(int64_t seq);
  KeyframeObservation* keyframeObservations(int64_t seq);
  static double median(std::span<double> values);

  LiveMapOptions options_;
  CameraIntrinsics K_;
  State state_ = State::kInitializing;
  int64_t frame_ = 0;       // frames processed
  int64_t ref_frame_ = -1;  // frame of the initialisation reference, -1 none
  // Tracks: sorted by id (ids only grow, so new tracks append), double-buffered for the merge.
  std::vector<TrackedFeature> sorted_features_;
  std::vector<TrackRecord> records_, records_next_;
  int record_count_ = 0;
  // Map points (a pool with a free stack).
  std::vector<MapPointSlot> points_;
  std::vector<int> free_points_;
  int free_count_ = 0;
  int points_in_use_ = 0;
  // Keyframe ring: keyframe seq lives in slot seq % max_keyframes.
  std::vector<Keyframe> keyframes_;
  std::vector<KeyframeObservation> kf_obs_;  // max_keyframes x max_features
  int64_t kf_first_seq_ = 0;
  int64_t kf_next_seq_ = 0;
  int64_t frames_since_kf_ = 0;
  // Solvers and their scratch.
  FundamentalRansac fundamental_;
  PnpRansac pnp_;
  BundleAdjuster ba_;
  std::vector<Eigen::Vector2d> x1_, x2_, n1_, n2_;  // max_features
  std::vector<Eigen::Vector3d> X_;
  std::vector<int> record_of_match_;
  std::vector<int> accepted_;  // initialisation: matches that triangulated
  std::vector<double> scratch_;
  std::vector<uint8_t> robust_mask_;  // max_features
  double robust_sigma_px_ = 0.0;      // smoothed residual scale of the tracked frames
  std::vector<BaCamera> ba_cameras_;
  std::vector<uint8_t> ba_fixed_;
  std::vector<int64_t> ba_kf_seq_;
  std::vector<Eigen::Vector3d> ba_points_;
  std::vector<int> ba_point_index_;    // pool index of each adjusted point
  std::vector<int> ba_slot_of_point_;  // max_points, -1 when not in the adjustment
  std::vector<BaObservation> ba_obs_;
  // Rolling shutter (options_.readout_frames > 0): the frame's motion over the readout (the last
  // tracked frame's, the start of the next refinement) and the compacted inliers it is refined on.
  RollingShutter shutter_;
  RollingShutterMotion motion_;
  std::vector<Eigen::Vector3d> rs_X_;             // max_features
  std::vector<Eigen::Vector2d> rs_px_;            // max_features
  std::vector<RollingShutterMotion> ba_motions_;  // ba_window + ba_fixed
  // Self-calibration: a ring of reference frames (tracks sorted by id) and of F matrices.
  struct CalibReference {
    int64_t frame = -1;
    int count = 0;
  };
  HomographyRansac homography_;
  EssentialRansac essential_;  // the initial pair of a plane (see initialPairModel)
  std::vector<CalibReference> calib_refs_;
  std::vector<int32_t> calib_ids_;         // calib_references x max_features
  std::vector<Eigen::Vector2d> calib_px_;  // calib_references x max_features
  std::vector<Eigen::Matrix3d> calib_F_;   // calib_max_pairs
  std::vector<FocalPairEstimate> calib_per_pair_;
  int64_t calib_pairs_total_ = 0;
  int calib_pairs_used_ = 0;
  bool calib_fallback_ = false;
};

}  // namespace epitrack

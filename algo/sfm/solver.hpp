#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "algo/geometry/focal_self_calibration.hpp"
#include "algo/geometry/pose.hpp"
#include "algo/sfm/distortion_trial.hpp"
#include "algo/sfm/rotation_adjustment.hpp"
#include "algo/sfm/track_table.hpp"
#include "algo/sfm/view_pair_contradiction.hpp"

namespace epitrack {

struct SolverOptions {
  double focal_px = 0.0;      ///< > 0: the focal is given (and kept unless refine_given_focal)
  double k1 = 0.0, k2 = 0.0;  ///< given radial distortion
  /// Given principal point and pixel aspect (fy / fx); by default the image centre and square
  /// pixels, the model of the self-calibration (paper §5.2).
  bool has_principal_point = false;
  double cx = 0.0, cy = 0.0;
  double aspect = 1.0;
  int refine_distortion = 0;  ///< 0 none, 1 k1, 2 k1 and k2 (estimated in the final adjustment)
  /// With refine_distortion 0 and no given distortion: try k1 and k2 in one more final
  /// adjustment and keep them when the lens shows (Solver::adjustDetectingDistortion): an
  /// unmodelled lens otherwise bends into the focal and the path (k1 = -0.2 at 640x480: the
  /// focal 42 % off).
  bool detect_distortion = false;
  /// detect_distortion keeps k1, k2 when they move some pixel of the image by at least this much
  /// (the largest displacement over the radii of the image)...
  double detect_distortion_min_px = 2.0;
  /// ...and lower the median reprojection error of the adjusted cameras by at least this
  /// fraction. On undistorted clips k1, k2 come out moving pixels by 0.6 px at most and lower
  /// the median by 0-4 %; a k1 of -0.2 moves the corners by 31 px and lowers it by 82 %.
  double detect_distortion_min_drop = 0.2;
  /// With keyframe_collection, detect_distortion also tries the lens during the registration,
  /// first when this many views are registered (2: the initial pair) and again each time their
  /// number has doubled since the last trial: a lens left out while the views are registered
  /// has misled the registration before the final adjustments could see it.
  int detect_distortion_min_views = 2;
  /// Key frames whose lens was estimated from k1 = k2 = 0 (detected, or refine_distortion):
  /// register the views again from a new initial pair with the lens the registration ended
  /// with, and keep whichever registration leaves the lower median reprojection error (and no
  /// fewer views). The initial pair's relative pose was found through the unmodelled lens; with
  /// the focal held (given) the adjustments may not leave it (8 views 14 degrees apart through
  /// k1 = -0.28, focal given: rotations 164 degrees off, ok).
  bool keyframe_lens_reregistration = true;
  bool refine_given_focal = false;
  double fallback_focal_widths =
      1.2;  ///< focal when it is neither given nor observable (x max(w, h))
  /// When F does not observe the focal (a critical motion for the paper's self-calibration: an
  /// orbit whose optical axes meet, forward motion, a long lens): the fallback is the minimum of
  /// a profile over candidate focals, each a whole solve with that focal, scored by the median
  /// reprojection error of every observation of a map point (false: fallback_focal_widths).
  bool focal_sweep = true;
  double keyframe_parallax_deg =
      2.0;                    ///< new keyframe when the median parallax to the last reaches this
  int keyframe_max_gap = 40;  ///< or after this many frames
  double min_point_parallax_deg = 1.0;  ///< triangulation: smallest angle between the extreme rays
  double reproj_threshold_px = 2.5;     ///< PnP inlier / triangulation acceptance threshold
  int ba_window = 8;                    ///< keyframes refined while solving (older ones fixed)
  /// Solved frames that are not keyframes join the final global adjustments as cameras, evenly
  /// spread over the clip, at most this many (0: keyframes only). Measured on five rendered
  /// orbits: mean ATE 0.0052 -> 0.0038 %, mean rotation error 0.020 -> 0.016 deg (40 frames).
  int final_extra_frames = 40;
  double huber_px = 1.0;
  /// Robust statistics of the global adjustments: the residual scale sigma is estimated from
  /// the median reprojection error (a 2D Gaussian error's norm has median 1.1774 sigma); beyond
  /// `outlier_sigmas` sigmas an observation is left out of the global adjustments and of the
  /// final per-frame poses, and the Huber threshold becomes `huber_sigmas` sigmas (never more
  /// than huber_px). Tracks that are not fixed scene points (occlusion corners, T-junctions,
  /// features sliding along an edge) fit a solve to a few tenths of a pixel and bias it through
  /// a fixed 1 px Huber loss; a clean clip's sigma is a few hundredths. 0 disables either.
  double outlier_sigmas = 4.0;
  double huber_sigmas = 2.0;
  double min_outlier_px = 0.1;  ///< the robust cut never goes below this (pixels)
  int max_track_views = 12;     ///< views used to triangulate a new track
  uint64_t seed = 1;
  /// Key frames, not video (tracks from descriptor matching, a few views each): the initial pair
  /// is searched over the whole clip (every frame a candidate, its partners up to
  /// `keyframe_pair_gap` frames on), and frames are registered in next-best-view order (the
  /// unsolved frame that sees the most map points first, Schoenberger & Frahm 2016 §4.2, "next
  /// best view"), each one a keyframe, its new tracks triangulated from every solved view at
  /// once; a frame that fails is tried again when the map it sees has grown.
  bool keyframe_collection = false;
  int keyframe_pair_gap = 4;
  int keyframe_min_inliers = 12;            ///< PnP inliers a key frame needs ...
  double keyframe_min_inlier_ratio = 0.25;  ///< ... and this fraction of the map points it sees
  /// A key frame that sees too few map points for PnP is registered from its relative pose to
  /// the solved frame it shares most tracks with (five-point E-RANSAC, at least
  /// keyframe_min_pair_inliers): rotation and direction of travel from E, the distance from the
  /// map points it sees (at least keyframe_min_scale_points agreeing), then refined on them.
  bool keyframe_relative_pose = true;
  int keyframe_min_pair_inliers = 30;
  int keyframe_min_scale_points = 5;
  /// The relative pose must be one its matches determine (relativePoseOverSeeds,
  /// algo/geometry/determined_relative_pose.hpp): E-RANSAC with this many seeds, the rotations
  /// of the hypotheses within a tenth of the most inliers within this many degrees of the best
  /// one (well-determined pairs: 1.5 at most on TUM and the rendered scenes); otherwise the view
  /// waits for PnP.
  int keyframe_relative_pose_trials = 5;
  double keyframe_max_rotation_spread_deg = 3.0;
  int keyframe_global_every = 5;  ///< a global adjustment after every this many registrations
  /// When no view is left to register: global adjustment, re-triangulation of every solved
  /// view's tracks, and every unregistered view tried again, at most this many times.
  int keyframe_retry_rounds = 2;
  /// After a key-frame solve, every pair of solved views with at least this many E-RANSAC
  /// inliers among their matches is checked against the solve (Solver::checkViewPairs): the
  /// pair is contradicted when the solve's relative pose explains (Sampson distance within
  /// reproj_threshold_px) fewer than keyframe_pair_min_support of the matches E explains. A
  /// registration gone wrong shows there (TUM cabinet key frames, `--seed 2`: pairs at frames
  /// 51-53, whose poses are 20-27 degrees off, explain 0.47-0.54; right ones 0.9-1.1). 0: off.
  int keyframe_pair_check_min_inliers = 60;
  double keyframe_pair_min_support = 0.6;
  /// A reconstruction that solves fewer than this fraction of the frames (views) is `kPartial`,
  /// never `kOk` (issues 20 and 22: a solve of 8 frames in 200 is not a result to call done).
  double min_solved_fraction = 0.9;
  /// A solve whose camera centres the final adjustment leaves uncertain by more than this
  /// fraction of the mean frame-to-frame step (RMS of the centres' standard deviations over the
  /// path length per step, Solver::assessCentres) is `kTrajectoryUncertain`, never `kOk` (issue
  /// 20: a fast pan that walks solved its rotations and focal to a few hundredths but its path
  /// to 7-22 %; measured 0.21-0.25 step there, at most 0.06 on the clips that solve well,
  /// docs/solver.md "Camera path check"). 0: not checked.
  double max_centre_sd_steps = 0.12;
  /// The tripod solve's rotations (chained from pairwise homographies) are refined by a
  /// rotation-only bundle adjustment over every solved frame (RotationAdjuster).
  bool tripod_adjustment = true;
  /// A rolling shutter's readout in frame intervals (first row to last; 0: global shutter),
  /// used by the tripod solve's adjustment on the tracks as exposed (Solver::setExposedTracks).
  /// The solver's own tracks are then expected at the frames' middle-row times
  /// (shiftTracksToReferenceRow); a general solve is refined for the rolling shutter after the
  /// solve (refineRollingShutter), a rotating camera has no points for that.
  double readout_frames = 0.0;
  /// Estimate the readout in the tripod solve's adjustment (epitrack-solve --readout auto), on
  /// the tracks as exposed (the solver's own when readout_frames is 0, else those of
  /// setExposedTracks): the readout whose row model fits best, with its standard error. Kept
  /// (the rotations and focal of that model) when above three standard errors and
  /// readout_min_frames.
  bool estimate_readout = false;
  double readout_min_frames = 0.03;  ///< 1 ms at 30 fps
  /// The final (global) adjustments stop once a step lowers the cost by less than this fraction.
  /// 1e-6: on the 340-frame orbit the figures are equal to 5 digits and the final adjustments take
  /// 0.28 s instead of 0.59 (the adjuster's default 1e-10 ran all 30 iterations). A solve whose
  /// result is only a start, such as the rolling-shutter refinement's, may stop earlier.
  double final_function_tolerance = 1e-6;
};

/// Why a frame has no camera (SolvedFrame::unsolved), judged after the solve from what the
/// frame's tracks offered; kNone for a solved frame.
enum class UnsolvedCause {
  kNone,
  kTracksLost,    ///< fewer tracked features than a pose needs, or than a quarter of the median
                  ///< solved frame's (a blank view, blur, a cut)
  kNotConnected,  ///< its tracks reach no solved frame: nothing links it to the map
  kTooLittleParallax,  ///< tracks shared with solved frames, but too few became 3D points
  kResectionFailed,    ///< enough 3D points in view, but no pose fits enough of them
  kNoReconstruction,   ///< the solve failed before any frame was solved (Solver::status says why)
};
/// A short machine-readable name ("tracks-lost", ...).
const char* toString(UnsolvedCause c);
/// What the cause means, in a few words for a message ("fewer than 12 tracked features", ...).
const char* describe(UnsolvedCause c);

/// Consecutive frames [first, last] that are all solved (cause kNone) or all unsolved for the
/// same cause.
struct FrameRange {
  int first = 0;
  int last = 0;
  bool solved = false;
  UnsolvedCause cause = UnsolvedCause::kNone;
};

/// One frame of the solve.
struct SolvedFrame {
  bool solved = false;
  bool keyframe = false;
  PoseCw pose;
  int inliers = 0;
  double rms_px = 0.0;
  /// Standard deviation of the camera centre (world units, sqrt of its covariance's trace) from
  /// the final adjustment, for its cameras (0: not one of them, the gauge camera, or not measured).
  double centre_sd = 0.0;
  UnsolvedCause unsolved = UnsolvedCause::kNoReconstruction;  ///< kNone once solved
};

/// The frames split into runs of solved frames and runs of unsolved frames with one cause, in
/// frame order.
std::vector<FrameRange> frameRanges(const std::vector<SolvedFrame>& frames);

struct MapPoint {
  Eigen::Vector3d X = Eigen::Vector3d::Zero();
  int track = -1;
  bool valid = false;
  int keyframe_observations = 0;
  double reproj_px = 0.0;  ///< RMS over its inlier observations in solved frames
  int observations = 0;
};

/// The tripod test (Solver::checkRotationModel): whether a pure rotation explains the tracks to
/// their noise level over the clip's widest windows, not only over the short calibration pairs.
struct RotationCheck {
  int windows = 0;           ///< frame windows tested (each as long as 30 tracks persist)
  int parallax_windows = 0;  ///< windows whose ratio exceeds kRotationResidualRatio (parallax)
  double noise_px = 0.0;     ///< median over the windows of the noise scale (sigma, from F)
  double residual_px = 0.0;  ///< median over the windows of the homography residual scale
  double ratio = 0.0;        ///< median over the windows of residual / noise
  bool holds = false;        ///< a rotation: at most a fifth of the windows show parallax
};
/// Tracks a window of the tripod test keeps (its last frame is the farthest that shares them).
inline constexpr int kRotationWindowTracks = 30;
/// The largest ratio of a window's homography residual scale to its tracks' noise scale that is
/// still a rotation (per window, measured: median 1.3-1.4 and 12 % of the windows beyond 2 on
/// rendered tripod pans, 1.07 and none beyond 2 on ideal Gaussian tracks; 40-90 % beyond 2 on
/// fast pans whose centre walks 0.6-1.2 cm/frame).
inline constexpr double kRotationResidualRatio = 2.0;

/// One candidate of the focal profile (SolverOptions::focal_sweep).
struct FocalProfilePoint {
  double start_px = 0.0;          ///< the focal the solve started from
  double focal_px = 0.0;          ///< the focal it ended with (= start_px unless refined)
  bool refined = false;           ///< the focal was refined in the final adjustment
  double median_reproj_px = 0.0;  ///< over every observation of a map point in a solved frame
  int solved_frames = 0;          ///< 0: the solve with this focal failed
};

struct PairFocal {
  int frame_a = 0, frame_b = 0;
  double focal_px = 0.0;
  bool observable = false;
  bool coherent = false;
  bool homography = false;  ///< the pair fitted a homography better (rotation, plane, no motion)
};

/// How the solve ended (Solver::status). Names in toString: "ok", "too-few-features", ...
enum class SolverStatus {
  kOk,
  kTooFewFeatures,  ///< not enough tracks to relate frames
  kNoMotion,        ///< the camera does not move enough to see parallax
  kRotationOnly,    ///< tripod: rotation and focal solved, depth unknown
  kPlanarScene,     ///< a single plane and the focal unknown: F is undefined
  kInitFailed,      ///< no candidate pair gave a valid two-view reconstruction
  /// A reconstruction (general or tripod) that leaves more than 1 - min_solved_fraction of the
  /// frames unsolved: `frames()` says which and why (SolvedFrame::unsolved), the message names
  /// the unsolved ranges.
  kPartial,
  /// Every frame solved, but the final adjustment determines the camera centres poorly
  /// (SolverOptions::max_centre_sd_steps): the rotations and the focal stand, the path does
  /// not. The message gives the measured figure.
  kTrajectoryUncertain,
  /// Key frames: the views registered (at least min_solved_fraction), but some pairs of them
  /// are contradicted by their own matches (SolverSummary::contradicted_pairs,
  /// Solver::checkViewPairs): the poses near those views are likely wrong. The message names
  /// the worst pairs.
  kInconsistent,
};
const char* toString(SolverStatus s);

/// The camera motion the calibration pairs show: "general", "rotation-or-plane" (at least 80 %
/// of the pairs fit a homography better), "rotation-only" (solved as a tripod).
enum class MotionClass { kGeneral, kRotationOrPlane, kRotationOnly };
const char* toString(MotionClass m);

/// Where the focal comes from: "given", "self-calibrated" (F pairs, paper §5.2, or the
/// rotation homographies), "fallback" (neither: the focal profile or the field of view).
enum class FocalSource { kGiven, kSelfCalibrated, kFallback };
const char* toString(FocalSource s);

/// How a fallback focal was chosen: "" (none), "profile" (a clear minimum of the focal profile),
/// "converged" (no clear minimum, but the profile's refined solves from starts far apart ended on
/// one focal: the whole adjustment observes it), "profile-flat" (the profile's best, no clear
/// minimum: a guess), "field-of-view" (fallback_focal_widths).
enum class FocalFallback { kNone, kProfile, kConverged, kProfileFlat, kFieldOfView };
const char* toString(FocalFallback f);

/// The solve's figures (Ceres-style Summary): status, intrinsics in use, where the focal came
/// from, the motion class and the initial pair.
struct SolverSummary {
  SolverStatus status = SolverStatus::kOk;
  std::string message;  ///< why the solve stopped or is partial ("" when ok)
  double focal_px = 0.0;
  double aspect = 1.0;  ///< fy / fx
  double cx = 0.0, cy = 0.0;
  double k1 = 0.0, k2 = 0.0;
  FocalSource focal_source = FocalSource::kGiven;
  bool focal_observable = true;
  FocalFallback focal_fallback = FocalFallback::kNone;
  MotionClass motion = MotionClass::kGeneral;
  int frames = 0;
  int solved_frames = 0;
  int initial_pair_a = -1, initial_pair_b = -1;  ///< -1: no initial pair
  /// RMS over the final adjustment's cameras of the centres' standard deviations, in percent of
  /// the solved path's length (Solver::assessCentres); negative: not measured (a tripod, a
  /// failed solve, or max_centre_sd_steps 0).
  double centre_sd_percent = -1.0;
  /// The same RMS in mean frame-to-frame steps of the path (the figure max_centre_sd_steps
  /// limits); negative: not measured.
  double centre_sd_steps = -1.0;
  double path_length = 0.0;  ///< of the solved centres in frame order (world units)
  /// The tripod solve's rotation-only adjustment (Solver::refineTripod): RMS reprojection error
  /// before and after, its iterations, and whether it modelled each row's time (rolling shutter).
  /// tripod_iterations < 0: the adjustment did not run or was not kept.
  double tripod_rms_before_px = 0.0;
  double tripod_rms_after_px = 0.0;
  int tripod_iterations = -1;
  bool tripod_rows_modelled = false;
  /// SolverOptions::estimate_readout: the tripod adjustment's readout estimate and its standard
  /// error (frame intervals; negative: not estimated), and whether it was kept.
  /// The short frame pairs fit rotations but the tripod test refused the widest windows
  /// (checkRotationModel): a walking camera, or a rolling shutter's shear on a fast pan.
  bool rotation_refused = false;
  double tripod_readout_frames = -1.0;
  double tripod_readout_std_error = 0.0;
  bool tripod_readout_applied = false;
  /// Key frames (SolverOptions::keyframe_pair_check_min_inliers): the pairs of solved views
  /// checked against their own matches (-1: not checked, a video solve or the check off), and
  /// those the matches contradict (worst first).
  int view_pairs_checked = -1;
  std::vector<ViewPairContradiction> contradicted_pairs;
  DistortionTrial distortion_trial;  ///< SolverOptions::detect_distortion
};

/// The 3D tracker of the paper (§5, Figure 2) with bundle adjustment beyond it. Stages, in order:
/// `calibrate` (focal given or self-calibrated over many pairs, paper §5.2), `initialize` (the
/// best-scoring initial pair among several candidates: F, E, cheirality, triangulation, §5.3),
/// `registerFrames` (every frame by PnP-RANSAC on the map, §5.4, keyframes by measured parallax,
/// new tracks triangulated at keyframes, windowed bundle adjustment), `finalize` (global bundle
/// adjustment over keyframes with the focal and distortion when requested, then every frame's
/// pose refined on the final map). A pure rotation ends in a tripod solve (rotation and focal;
/// depth unknown). Each stage returns false when the solve cannot go on; `status()` says why.
///
/// Sources by concern: solver.cpp (calibration, initial pair, final adjustment),
/// solver_registration.cpp (registration, keyframes, triangulation, bundle adjustment),
/// solver_focal_profile.cpp (focal profile), solver_tripod.cpp (tripod solve),
/// solver_keyframes.cpp (key-frame mode), solver_coverage.cpp (unsolved causes, partial status).
class Solver {
 public:
  using Status = SolverStatus;

  Solver(const TrackTable& tracks, int width, int height, const SolverOptions& options);

  /// The tracks as exposed by a rolling shutter (SolverOptions::readout_frames), when the
  /// solver's tracks were moved to the middle-row times: same tracks, same dense indices. The
  /// tripod solve's adjustment then models each row's time on them. Must outlive the solver.
  void setExposedTracks(const TrackTable* tracks) { exposed_tracks_ = tracks; }

  bool calibrate();
  /// Stage 1 for a focal given in the options when the clip's calibration checks already passed
  /// elsewhere (the focal profile's probes, solving a subsampled copy of the clip): the focal is
  /// taken as given, the motion as general (the profile only runs on general motion).
  void calibrateAsGiven();
  bool initialize();
  bool registerFrames();
  bool finalize();

  [[nodiscard]] Status status() const { return status_; }
  /// Status, intrinsics, focal source, motion and initial pair as they stand after the last stage.
  [[nodiscard]] SolverSummary summary() const;
  /// The tripod test (checkRotationModel) on the solver's tracks, without a solve: epitrack-solve
  /// --readout auto searches the readout that makes a fast pan's tracks a rotation.
  [[nodiscard]] RotationCheck rotationCheck() const { return checkRotationModel(); }
  [[nodiscard]] const std::vector<SolvedFrame>& frames() const { return frames_; }
  [[nodiscard]] const std::vector<MapPoint>& points() const { return points_; }
  [[nodiscard]] const std::vector<PairFocal>& pairFocals() const { return pair_focals_; }
  /// The focal profile when F did not observe the focal (empty otherwise), in evaluation order.
  [[nodiscard]] const std::vector<FocalProfilePoint>& focalProfile() const { return profile_; }
  /// Median reprojection error (pixels) of every observation of a valid map point in a solved
  /// frame, inliers or not (the profile's score).
  [[nodiscard]] double medianReprojectionAll() const;
  [[nodiscard]] int solvedFrames() const;
  /// Mean and median reprojection error over every inlier observation of a solved frame.
  void reprojectionStats(double& mean_px, double& median_px) const;

 private:
  [[nodiscard]] Eigen::Vector2d normalized(const TrackObservation& o) const;
  /// The observation in pixels without the lens distortion (K times normalized(o)), the
  /// coordinates of the pixel-space fits (F, H, displacements); the pixel itself when there is
  /// no distortion or no focal yet.
  [[nodiscard]] Eigen::Vector2d undistortedPixel(const TrackObservation& o) const;
  bool tryPair(int a, int b, double& score, PoseCw& pose_b, std::vector<int>& tracks,
               std::vector<Eigen::Vector3d>& X) const;
  /// PnP-RANSAC on the map (paper §5.4): at least min_inliers inliers, and this fraction of the
  /// frame's map points (key frames accept a smaller one: short descriptor tracks carry more
  /// wrong points).
  bool registerFrame(int f, int min_inliers = 12, double min_inlier_ratio = 0.5);
  bool registerBestViews();
  void reregisterWithLens();
  struct RegisteredState;
  bool registerByRelativePose(int f, int reference);
  int placeFromRelativePose(int f, int reference, const PoseCw& rel, PoseCw& placed,
                            int& seen) const;
  void initialCandidatesAll(const std::function<void(int, int)>& consider) const;
  // initialize()'s stages: the rotation test, the search for a two-view start, the tripod or
  // wide-window fallback, and the map seeded from the pair found.
  struct InitialPair;
  /// Under homographies everywhere: whether they are rotations of one focal (which then becomes
  /// the self-calibrated focal when none is known).
  bool rotationsCoherent();
  void considerPair(int a, int b, InitialPair& best) const;
  void searchInitialPairs(InitialPair& best) const;
  /// False when initialize() stops: a tripod solve, or no wide window with a 3D start.
  bool startFromRotation(InitialPair& best);
  void seedMap(const InitialPair& best);
  bool shouldBeKeyframe(int f) const;
  void addKeyframe(int f);
  int triangulateNewTracks(int f);
  /// `measure_centres` (a global adjustment): also each adjusted camera's centre uncertainty
  /// (SolvedFrame::centre_sd, for assessCentres).
  void adjust(bool global, bool measure_centres = false);
  /// What the global adjustments change: the state detect_distortion puts back.
  struct AdjustedState {
    std::vector<SolvedFrame> frames;
    std::vector<MapPoint> points;
    double f = 0.0, k1 = 0.0, k2 = 0.0, cut_px = 0.0, huber_px = 0.0;
  };
  [[nodiscard]] AdjustedState adjustedState() const;
  void restore(const AdjustedState& s);
  void adjustDetectingDistortion(bool measure_centres);
  bool tryDistortion(bool global);
  void adjustTryingDistortion(bool global);
  [[nodiscard]] bool distortionTrialDue() const;
  [[nodiscard]] double adjustedMedianReprojectionPx() const;
  [[nodiscard]] double distortionMaxDisplacementPx(double k1, double k2) const;
  bool tripodSolve();
  /// The rotation-only adjustment of the tripod solve (SolverOptions::tripod_adjustment).
  void refineTripod();
  struct TripodProblem;  // the adjustment's rotations, directions and observations
  RotationAdjustmentSummary adjustTripod(RotationAdjuster& adjuster, TripodProblem& p,
                                         double readout_frames, RotationAdjustmentOptions ro,
                                         BaIntrinsics& k) const;
  void keepTripodAdjustment(const TripodProblem& p, const std::vector<int>& frame_of_camera,
                            const BaIntrinsics& k, const RotationAdjustmentSummary& r,
                            bool rows_modelled);
  /// SolverOptions::estimate_readout: the readout that fits the tripod adjustment best.
  void estimateTripodReadout(RotationAdjuster& adjuster, const TripodProblem& start,
                             const std::vector<int>& frame_of_camera,
                             const RotationAdjustmentOptions& ro, double initial_readout);
  void directionsAndObservations(const TrackTable& tracks, const std::vector<int>& camera_of_frame,
                                 const std::vector<Eigen::Matrix3d>& rotations,
                                 std::vector<Eigen::Vector3d>& directions,
                                 std::vector<RotationObservation>& observations) const;
  /// The rotation model tested over windows spanning as many frames as 30 tracks persist, each
  /// judged by GRIC with the noise scale measured on its own tracks (RotationCheck).
  [[nodiscard]] RotationCheck checkRotationModel() const;
  /// The last frame after `a` that still shares `min_common` tracks with it (-1: none).
  [[nodiscard]] int farthestPartner(int a, int min_common) const;
  /// Sets every frame's UnsolvedCause, then turns kOk / kRotationOnly into kPartial (with a
  /// message naming the unsolved ranges) when too few frames are solved.
  void assessCoverage();
  /// The centres' uncertainty relative to the path (SolverSummary::centre_sd_percent, _steps)
  /// and, when it exceeds max_centre_sd_steps, kOk turned into kTrajectoryUncertain with a message.
  void assessCentres();
  /// Key frames: every solved pair with enough matches checked against the solve's relative
  /// pose (SolverOptions::keyframe_pair_check_min_inliers); fills contradicted_pairs_.
  void checkViewPairs();
  /// The normalized coordinates of the tracks frames a and b share (n_a[i] and n_b[i] one
  /// track), in frame a's order.
  void normalizedMatches(int a, int b, std::vector<Eigen::Vector2d>& n_a,
                         std::vector<Eigen::Vector2d>& n_b) const;
  /// Fills profile_ and sets f_ to the profile's minimum (SolverOptions::focal_sweep).
  void sweepFocal();
  [[nodiscard]] FocalProfilePoint probeFocal(const TrackTable& tracks, double focal,
                                             bool refine) const;
  void computeErrors();
  int commonTracks(int a, int b, std::vector<Eigen::Vector2d>* x1,
                   std::vector<Eigen::Vector2d>* x2) const;

  const TrackTable& tracks_;
  const TrackTable* exposed_tracks_ = nullptr;  // setExposedTracks
  int width_, height_;
  SolverOptions options_;
  double f_ = 0.0, cx_ = 0.0, cy_ = 0.0, k1_ = 0.0, k2_ = 0.0, aspect_ = 1.0;
  FocalSource focal_source_ = FocalSource::kGiven;
  bool focal_observable_ = true;
  MotionClass motion_ = MotionClass::kGeneral;
  Status status_ = Status::kOk;
  std::string message_;
  std::vector<SolvedFrame> frames_;
  std::vector<MapPoint> points_;
  std::vector<int> point_of_track_;  // -1: none
  std::vector<int> keyframes_;       // in insertion order
  std::vector<PairFocal> pair_focals_;
  std::vector<Eigen::Matrix3d> homographies_;  // of the calibration pairs (tripod solve)
  int init_a_ = -1, init_b_ = -1;
  bool tripod_ = false;
  double tripod_rms_before_px_ = 0.0;  // the rotation-only adjustment's RMS (0: not run)
  double tripod_rms_after_px_ = 0.0;
  int tripod_iterations_ = -1;  // -1: not run or not kept
  bool tripod_rows_modelled_ = false;
  double tripod_readout_frames_ = -1.0;  // SolverOptions::estimate_readout (-1: not estimated)
  double tripod_readout_std_error_ = 0.0;
  bool tripod_readout_applied_ = false;
  bool rotation_refused_ = false;  // SolverSummary::rotation_refused
  int view_pairs_checked_ = -1;    // SolverSummary::view_pairs_checked
  std::vector<ViewPairContradiction> contradicted_pairs_;
  bool sweep_pending_ = false;
  std::vector<int> final_cameras_;  // extra cameras of the final adjustments (final_extra_frames)
  bool refine_fallback_focal_ = false;  // the profile found a clear minimum: polish it in BA
  std::vector<FocalProfilePoint> profile_;
  FocalFallback focal_fallback_ = FocalFallback::kNone;
  // Robust cut and Huber threshold (pixels) of the last global adjustment; 0: none yet.
  double robust_cut_px_ = 0.0;
  double robust_huber_px_ = 0.0;
  int distortion_terms_ = 0;  // k1 (1), k1 and k2 (2) refined by the global adjustments
  DistortionTrial distortion_trial_;
  double centre_sd_percent_ = -1.0;
  double centre_sd_steps_ = -1.0;
  double path_length_ = 0.0;
};

}  // namespace epitrack

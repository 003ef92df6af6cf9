#include "algo/sfm/solver.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>

#include <Eigen/LU>
#include <Eigen/SVD>

#include "algo/geometry/essential.hpp"
#include "algo/geometry/essential_five_point.hpp"
#include "algo/geometry/fundamental.hpp"
#include "algo/geometry/homography.hpp"
#include "algo/geometry/pnp.hpp"
#include "algo/geometry/triangulation.hpp"
#include "algo/geometry/two_view_model_selection.hpp"
#include "algo/geometry/undistort.hpp"
#include "algo/math/median.hpp"
#include "algo/sfm/ba_camera_pose.hpp"
#include "algo/sfm/bundle_adjustment.hpp"
#include "algo/sfm/reprojection.hpp"
#include "algo/sfm/two_view_initialization.hpp"

namespace epitrack {

const char* toString(SolverStatus s) {
  switch (s) {
    case Solver::Status::kOk:
      return "ok";
    case Solver::Status::kTooFewFeatures:
      return "too-few-features";
    case Solver::Status::kNoMotion:
      return "no-motion";
    case Solver::Status::kRotationOnly:
      return "rotation-only";
    case Solver::Status::kPlanarScene:
      return "planar-scene";
    case Solver::Status::kInitFailed:
      return "initialization-failed";
    case Solver::Status::kPartial:
      return "partial";
    case Solver::Status::kTrajectoryUncertain:
      return "trajectory-uncertain";
    case Solver::Status::kInconsistent:
      return "inconsistent";
  }
  return "unknown";
}

const char* toString(MotionClass m) {
  switch (m) {
    case MotionClass::kGeneral:
      return "general";
    case MotionClass::kRotationOrPlane:
      return "rotation-or-plane";
    case MotionClass::kRotationOnly:
      return "rotation-only";
  }
  return "unknown";
}

const char* toString(FocalSource s) {
  switch (s) {
    case FocalSource::kGiven:
      return "given";
    case FocalSource::kSelfCalibrated:
      return "self-calibrated";
    case FocalSource::kFallback:
      return "fallback";
  }
  return "unknown";
}

const char* toString(FocalFallback f) {
  switch (f) {
    case FocalFallback::kNone:
      return "";
    case FocalFallback::kProfile:
      return "profile";
    case FocalFallback::kConverged:
      return "converged";
    case FocalFallback::kProfileFlat:
      return "profile-flat";
    case FocalFallback::kFieldOfView:
      return "field-of-view";
  }
  return "unknown";
}

namespace {

// Displacement statistic for pair selection: the 80th percentile of the track displacements, so
// forward motion (where the centre barely moves) counts its moving periphery.
double displacement(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b) {
  std::vector<double> d(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) d[i] = (a[i] - b[i]).norm();
  if (d.empty()) return 0.0;
  auto it = d.begin() + static_cast<std::ptrdiff_t>(d.size() * 8 / 10);
  std::nth_element(d.begin(), it, d.end());
  return *it;
}

// The upper median of a copy (the callers' vectors are theirs to keep).
double median(std::vector<double> v) { return upperMedian(v); }

}  // namespace

Solver::Solver(const TrackTable& tracks, int width, int height, const SolverOptions& options)
    : tracks_(tracks), width_(width), height_(height), options_(options) {
  cx_ = options.has_principal_point ? options.cx : (width - 1) * 0.5;
  cy_ = options.has_principal_point ? options.cy : (height - 1) * 0.5;
  aspect_ = options.aspect > 0.0 ? options.aspect : 1.0;
  k1_ = options.k1;
  k2_ = options.k2;
  distortion_terms_ = options.refine_distortion;
  frames_.assign(static_cast<std::size_t>(tracks.frameCount()), SolvedFrame{});
  point_of_track_.assign(static_cast<std::size_t>(tracks.trackCount()), -1);
  points_.reserve(static_cast<std::size_t>(tracks.trackCount()));
}

Eigen::Vector2d Solver::normalized(const TrackObservation& o) const {
  Eigen::Vector2d d((o.x - cx_) / f_, (o.y - cy_) / (f_ * aspect_));
  // Invert x_d = x_u (1 + k1 r^2 + k2 r^4) (Newton on the radius: the fixed-point iteration
  // diverges near the corners of a wide-angle lens, k1 = -0.28).
  return undistortNormalized(k1_, k2_, d);
}

Eigen::Vector2d Solver::undistortedPixel(const TrackObservation& o) const {
  if ((k1_ == 0.0 && k2_ == 0.0) || !(f_ > 0.0)) return {o.x, o.y};
  const Eigen::Vector2d n = normalized(o);
  return {cx_ + f_ * n.x(), cy_ + f_ * aspect_ * n.y()};
}

int Solver::commonTracks(int a, int b, std::vector<Eigen::Vector2d>* x1,
                         std::vector<Eigen::Vector2d>* x2) const {
  if (x1 != nullptr) x1->clear();
  if (x2 != nullptr) x2->clear();
  int n = 0;
  for (const auto& o : tracks_.frame(a)) {
    const TrackObservation* ob = tracks_.find(o.track, b);
    if (ob == nullptr) continue;
    ++n;
    if (x1 != nullptr) x1->push_back(undistortedPixel(o));
    if (x2 != nullptr) x2->push_back(undistortedPixel(*ob));
  }
  return n;
}

void Solver::calibrateAsGiven() {
  f_ = options_.focal_px;
  focal_source_ = FocalSource::kGiven;
  focal_observable_ = true;
}

SolverSummary Solver::summary() const {
  SolverSummary s;
  s.status = status_;
  s.message = message_;
  s.focal_px = f_;
  s.aspect = aspect_;
  s.cx = cx_;
  s.cy = cy_;
  s.k1 = k1_;
  s.k2 = k2_;
  s.focal_source = focal_source_;
  s.focal_observable = focal_observable_;
  s.focal_fallback = focal_fallback_;
  s.motion = motion_;
  s.frames = tracks_.frameCount();
  s.solved_frames = solvedFrames();
  s.initial_pair_a = init_a_;
  s.initial_pair_b = init_b_;
  s.centre_sd_percent = centre_sd_percent_;
  s.centre_sd_steps = centre_sd_steps_;
  s.path_length = path_length_;
  s.tripod_rms_before_px = tripod_rms_before_px_;
  s.tripod_rms_after_px = tripod_rms_after_px_;
  s.tripod_iterations = tripod_iterations_;
  s.tripod_rows_modelled = tripod_rows_modelled_;
  s.tripod_readout_frames = tripod_readout_frames_;
  s.tripod_readout_std_error = tripod_readout_std_error_;
  s.tripod_readout_applied = tripod_readout_applied_;
  s.rotation_refused = rotation_refused_;
  s.view_pairs_checked = view_pairs_checked_;
  s.distortion_trial = distortion_trial_;
  s.contradicted_pairs = contradicted_pairs_;
  return s;
}

int Solver::solvedFrames() const {
  int n = 0;
  for (const auto& f : frames_) n += f.solved ? 1 : 0;
  return n;
}

// ---------------------------------------------------------------------------------------------
// Stage 1: focal length (paper §5.2).

bool Solver::calibrate() {
  const int n = tracks_.frameCount();
  int max_obs = 0;
  for (int f = 0; f < n; ++f)
    max_obs = std::max(max_obs, static_cast<int>(tracks_.frame(f).size()));
  if (n < 2 || max_obs < 8) {
    status_ = Status::kTooFewFeatures;
    message_ = "fewer than 8 tracked features: nothing to reconstruct";
    return false;
  }
  // A given lens is taken out of the calibration pairs' F and H (undistortedPixel needs the
  // focal): through k1 = -0.1 a pan's homographies are not rotations, and the tripod was refused.
  if (options_.focal_px > 0.0) f_ = options_.focal_px;
  FundamentalRansac fr(max_obs);
  HomographyRansac hr(max_obs);
  FundamentalOptions fo;
  fo.ransac.seed = options_.seed;
  std::vector<Eigen::Vector2d> x1, x2;
  std::vector<Eigen::Matrix3d> Fs;
  std::vector<int> f_pair_index;
  // Pairs (i, j): j the first frame after i whose common tracks moved by a median of 8 % of the
  // width (enough parallax to condition F), stepping i so that about 40 pairs cover the clip.
  // Forward motion moves the central tracks little: when no later frame reaches 8 %, the frame
  // of largest displacement still makes a pair if it reaches kMinPairMotion.
  constexpr double kTargetMotion = 0.08, kMinPairMotion = 0.03;
  const int step = std::max(1, n / 40);
  bool any_motion = false;
  int longest_span = 0;  // frames over which 30 tracks persisted
  for (int i = 0; i + 1 < n; i += step) {
    int j = -1, best_k = -1;
    double best_d = 0.0;
    for (int k = i + 1; k < n; ++k) {
      const int c = commonTracks(i, k, &x1, &x2);
      if (c < 30) break;
      longest_span = std::max(longest_span, k - i);
      const double d = displacement(x1, x2);
      if (d > best_d) {
        best_d = d;
        best_k = k;
      }
      if (d >= kTargetMotion * width_) {
        j = k;
        break;
      }
    }
    if (j < 0 && best_d >= kMinPairMotion * width_) j = best_k;
    if (j < 0) continue;
    any_motion = true;
    commonTracks(i, j, &x1, &x2);
    const auto r = estimateFocalFromMatches(x1, x2, width_, height_, fr, hr, 0.5, fo);
    PairFocal p;
    p.frame_a = i;
    p.frame_b = j;
    p.homography = r.model == PairModel::kHomography;
    if (r.model == PairModel::kFailed) continue;
    if (p.homography) homographies_.push_back(r.H);
    if (r.model == PairModel::kFundamental) {
      Fs.push_back(r.F);
      f_pair_index.push_back(static_cast<int>(pair_focals_.size()));
    }
    pair_focals_.push_back(p);
  }
  int homography_pairs = 0;
  for (const auto& p : pair_focals_) homography_pairs += p.homography ? 1 : 0;
  if (!any_motion && longest_span < std::min(3, n - 1)) {
    status_ = Status::kTooFewFeatures;
    message_ = "features are not tracked from frame to frame (fewer than 30 tracks survive " +
               std::to_string(std::min(3, n - 1)) +
               " frames): noise, heavy blur, cuts or a frame rate too low for the motion";
    return false;
  }
  if (!any_motion) {
    status_ = Status::kNoMotion;
    message_ =
        "the tracks never move by 3 % of the image width (80th percentile): no parallax to "
        "reconstruct from";
    return false;
  }
  if (!pair_focals_.empty() && homography_pairs * 10 >= static_cast<int>(pair_focals_.size()) * 8)
    motion_ = MotionClass::kRotationOrPlane;

  if (options_.focal_px > 0.0) {
    f_ = options_.focal_px;
    focal_source_ = FocalSource::kGiven;
    focal_observable_ = true;
    return true;
  }
  std::vector<FocalPairEstimate> per(Fs.size());
  const auto r = calibrateFocalMultiPair(Fs, width_, height_, per);
  for (std::size_t k = 0; k < Fs.size(); ++k) {
    auto& p = pair_focals_[static_cast<std::size_t>(f_pair_index[k])];
    p.focal_px = per[k].focal_px;
    p.observable = per[k].observable;
    p.coherent = per[k].coherent;
  }
  if (r.observable) {
    f_ = r.focal_px;
    focal_source_ = FocalSource::kSelfCalibrated;
    focal_observable_ = true;
  } else {
    f_ = options_.fallback_focal_widths * std::max(width_, height_);
    focal_source_ = FocalSource::kFallback;
    focal_observable_ = false;
    focal_fallback_ = FocalFallback::kFieldOfView;
    sweep_pending_ = options_.focal_sweep;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Stage 2: initial pair (paper §5.3), chosen among candidates by a score.

bool Solver::tryPair(int a, int b, double& score, PoseCw& pose_b, std::vector<int>& tracks,
                     std::vector<Eigen::Vector3d>& X) const {
  std::vector<Eigen::Vector2d> x1, x2, n1, n2;
  std::vector<int> ids;
  for (const auto& o : tracks_.frame(a)) {
    const TrackObservation* ob = tracks_.find(o.track, b);
    if (ob == nullptr) continue;
    x1.push_back(undistortedPixel(o));
    x2.push_back(undistortedPixel(*ob));
    n1.push_back(normalized(o));
    n2.push_back(normalized(*ob));
    ids.push_back(o.track);
  }
  if (x1.size() < 30) return false;
  FundamentalRansac fr(static_cast<int>(x1.size()));
  HomographyRansac hr(static_cast<int>(x1.size()));
  FundamentalOptions fo;
  fo.ransac.seed = options_.seed;
  FundamentalResult f;
  if (fr.estimate(x1, x2, fo, f) != FundamentalRansac::Status::kOk) return false;
  HomographyResult h;
  HomographyOptions ho;
  ho.ransac.seed = options_.seed;
  const bool have_h = hr.estimate(x1, x2, ho, h) == HomographyRansac::Status::kOk;
  double gric_ratio = 1.0;
  if (have_h) {
    const auto sel = selectTwoViewModel(f.F, h.H, x1, x2, 0.5, f.mask, h.mask);
    // With the focal known, a homography-like pair may still initialise (a plane seen with
    // translation); a pure rotation will fail the parallax test below.
    gric_ratio = sel.gric_h / std::max(1.0, sel.gric_f);
  }
  Eigen::Matrix3d K;
  K << f_, 0, cx_, 0, f_ * aspect_, cy_, 0, 0, 1;
  TwoViewOptions tv;
  tv.focal_px = f_;
  tv.min_point_parallax_deg = options_.min_point_parallax_deg;
  tv.reproj_threshold_px = options_.reproj_threshold_px;
  PoseCw pose;
  std::vector<Eigen::Vector3d> X_all(n1.size());
  std::vector<int> accepted(n1.size());
  std::vector<double> parallax(n1.size());
  int count = 0;
  if (reconstructTwoView(f.F, K, n1, n2, f.mask, tv, pose, X_all, accepted, parallax, count) !=
      TwoViewStatus::kOk)
    return false;
  parallax.resize(static_cast<std::size_t>(count));
  tracks.clear();
  X.clear();
  for (int g = 0; g < count; ++g) {
    const auto i = static_cast<std::size_t>(accepted[static_cast<std::size_t>(g)]);
    tracks.push_back(ids[i]);
    X.push_back(X_all[i]);
  }
  if (tracks.size() < 30) return false;
  const double med_parallax = median(parallax);
  // Score: well-triangulated points, weighted by the median parallax up to 8 degrees (more
  // parallax conditions depth better) and discounted when a homography explains the pair.
  score = static_cast<double>(tracks.size()) * std::min(med_parallax, 8.0) *
          std::clamp(gric_ratio, 0.5, 1.0);
  pose_b = pose;
  return true;
}

// The best two-view start found so far, and the scratch of the pair being tried.
struct Solver::InitialPair {
  double score = 0.0;
  int a = -1, b = -1;
  PoseCw pose;
  std::vector<int> tracks, scratch_tracks;
  std::vector<Eigen::Vector3d> X, scratch_X;
};

bool Solver::initialize() {
  const bool rotation_coherent = rotationsCoherent();
  // Homographies that are not rotations: a single plane (or a scene so distant it acts as one).
  // Any focal then explains the views equally well (paper §5.2 needs F), so a solve with a guessed
  // focal would be silently distorted: say so instead.
  if (motion_ == MotionClass::kRotationOrPlane && !rotation_coherent && options_.focal_px <= 0.0 &&
      !focal_observable_) {
    status_ = Status::kPlanarScene;
    message_ =
        "every frame pair fits a homography that is not a rotation (a single plane, scenery so "
        "distant it acts as one, or too little parallax between the frames, as in slow forward "
        "motion): the focal length cannot be self-calibrated; give --focal or --intrinsics";
    return false;
  }
  if (sweep_pending_ && !focal_observable_) sweepFocal();
  InitialPair best;
  searchInitialPairs(best);
  // Nothing with parallax, but rotations everywhere: a tripod, or a pan too fast for the short
  // pairs to show the parallax (startFromRotation decides).
  if (best.score <= 0.0 && rotation_coherent && !startFromRotation(best)) return false;
  if (best.score <= 0.0) {
    status_ = motion_ == MotionClass::kRotationOrPlane ? Status::kPlanarScene : Status::kInitFailed;
    message_ = status_ == Status::kPlanarScene
                   ? "the frames are related by homographies (a single plane without a given "
                     "focal, or no translation): no 3D reconstruction"
                   : "no pair of frames gave a valid two-view reconstruction";
    return false;
  }
  seedMap(best);
  return true;
}

bool Solver::rotationsCoherent() {
  // Homographies everywhere: a rotating camera if the homographies are rotations for one focal,
  // otherwise a plane or a distant scene. The rotation focal then seeds the search for an
  // initial pair (a distant scene with a short baseline still has parallax over longer gaps);
  // only when no pair has parallax is the clip solved as a tripod.
  if (motion_ != MotionClass::kRotationOrPlane || homographies_.empty()) return false;
  std::vector<double> fs;
  for (const auto& H : homographies_) {
    const auto e = estimateFocalFromRotation(H, width_, height_);
    if (e.observable) fs.push_back(e.focal_px);
  }
  const double rotation_focal = median(fs);
  int coherent = 0;
  for (const double v : fs) coherent += std::abs(v / rotation_focal - 1.0) < 0.05 ? 1 : 0;
  const bool focal_fits =
      options_.focal_px <= 0.0 || std::abs(rotation_focal / options_.focal_px - 1.0) < 0.1;
  const bool rotation_coherent =
      coherent * 2 > static_cast<int>(homographies_.size()) && focal_fits;
  if (rotation_coherent && options_.focal_px <= 0.0 && !focal_observable_) {
    f_ = rotation_focal;
    focal_source_ = FocalSource::kSelfCalibrated;
    focal_observable_ = true;
  }
  return rotation_coherent;
}

void Solver::considerPair(int a, int b, InitialPair& best) const {
  double score = 0.0;
  PoseCw pose;
  if (tryPair(a, b, score, pose, best.scratch_tracks, best.scratch_X) && score > best.score) {
    best.score = score;
    best.pose = pose;
    best.tracks = best.scratch_tracks;
    best.X = best.scratch_X;
    best.a = a;
    best.b = b;
  }
}

void Solver::searchInitialPairs(InitialPair& best) const {
  // Candidate first frames spread over the first fifth of the clip, candidate partners at several
  // gaps measured by parallax (median displacement 10-40 % of the width).
  const int n = tracks_.frameCount();
  std::vector<Eigen::Vector2d> x1, x2;
  const int a_span = options_.keyframe_collection ? -1 : std::max(1, n / 5);
  const int a_step = std::max(1, a_span / 6);
  if (options_.keyframe_collection)
    initialCandidatesAll([&](int a, int b) { considerPair(a, b, best); });
  for (int a = 0; a < n && a <= a_span; a += a_step) {
    const double targets[] = {0.04, 0.08, 0.14, 0.24};
    int t = 0, last_tried = -1, widest = -1;
    double widest_d = 0.0;
    const auto consider = [&](int b) {
      last_tried = b;
      considerPair(a, b, best);
    };
    for (int b = a + 1; b < n && t < 4; ++b) {
      const int c = commonTracks(a, b, &x1, &x2);
      if (c < 30) break;
      const double d = displacement(x1, x2);
      if (d > widest_d) {
        widest_d = d;
        widest = b;
      }
      if (d < targets[t] * width_) continue;
      ++t;
      consider(b);
    }
    // Short or forward motions may not reach every target: the widest baseline is a candidate.
    if (t < 4 && widest > 0 && widest != last_tried && widest_d >= 0.02 * width_) consider(widest);
  }
}

bool Solver::startFromRotation(InitialPair& best) {
  // Short pairs that all fit rotations do not make a tripod: a fast pan crosses the image in a
  // few frames, too soon for a walking camera's parallax to show. The rotation is accepted only
  // when it explains the tracks to their noise over the widest windows (checkRotationModel);
  // otherwise those windows are the initial pair's candidates. (Not the other way round: under a
  // pure rotation F is degenerate, and a wrong relative pose from it can triangulate 30 points
  // with a degree of "parallax" between long-lived tracks.)
  const RotationCheck rotation = checkRotationModel();
  rotation_refused_ = !rotation.holds;
  if (rotation.holds) {
    if (!tripodSolve()) {  // a failed tripod solve is a failed start, never "ok"
      status_ = Status::kInitFailed;
      message_ =
          "the frames are related by rotations, but the tripod solve found no focal or no "
          "frame with 8 tracks";
    }
    return false;
  }
  const int n = tracks_.frameCount();
  const int wide_step = std::max(1, n / 30);
  for (int a = 0; a + 1 < n; a += wide_step) {
    const int b = farthestPartner(a, kRotationWindowTracks);
    if (b < a + 2) continue;
    for (const int partner : {b, (a + b + 1) / 2}) considerPair(a, partner, best);
  }
  if (best.score > 0.0) return true;
  char text[320];
  std::snprintf(text, sizeof(text),
                "the short frame pairs fit rotations, but over the widest windows the tracks "
                "do not (homography residual %.3f px against noise %.3f px, %d of %d windows "
                "beyond %.1fx): the camera moves, and no pair of frames has the parallax for "
                "a 3D start",
                rotation.residual_px, rotation.noise_px, rotation.parallax_windows,
                rotation.windows, kRotationResidualRatio);
  status_ = Status::kInitFailed;
  message_ = text;
  return false;
}

void Solver::seedMap(const InitialPair& best) {
  motion_ = MotionClass::kGeneral;
  init_a_ = best.a;
  init_b_ = best.b;
  auto& fa = frames_[static_cast<std::size_t>(init_a_)];
  auto& fb = frames_[static_cast<std::size_t>(init_b_)];
  fa.solved = fb.solved = true;
  fa.pose = PoseCw{};
  fb.pose = best.pose;
  for (std::size_t i = 0; i < best.tracks.size(); ++i) {
    MapPoint p;
    p.X = best.X[i];
    p.track = best.tracks[i];
    p.valid = true;
    point_of_track_[static_cast<std::size_t>(p.track)] = static_cast<int>(points_.size());
    points_.push_back(p);
  }
  addKeyframe(init_a_);
  addKeyframe(init_b_);
  adjustTryingDistortion(true);
}

// A registration to return to: what the global adjustments change, and the map's bookkeeping.
struct Solver::RegisteredState {
  AdjustedState adjusted;
  std::vector<int> point_of_track, keyframes;
  int init_a = -1, init_b = -1;
};

// SolverOptions::keyframe_lens_reregistration: the views registered again from a new initial
// pair, the lens the first registration ended with held as its start (and refined by the global
// adjustments as before). Kept when it registers no fewer views with a lower median
// reprojection error; otherwise the first registration stands.
void Solver::reregisterWithLens() {
  RegisteredState first;
  first.adjusted = adjustedState();
  first.point_of_track = point_of_track_;
  first.keyframes = keyframes_;
  first.init_a = init_a_;
  first.init_b = init_b_;
  const int first_views = solvedFrames();
  DistortionTrial& t = distortion_trial_;
  t.reregistered = true;
  t.first_registration_median_px = medianReprojectionAll();
  for (auto& fr : frames_) fr = SolvedFrame{};
  points_.clear();
  std::fill(point_of_track_.begin(), point_of_track_.end(), -1);
  keyframes_.clear();
  InitialPair best;
  searchInitialPairs(best);
  if (best.score > 0.0) {
    seedMap(best);
    registerBestViews();
  }
  t.reregistration_median_px =
      best.score > 0.0 ? medianReprojectionAll() : std::numeric_limits<double>::infinity();
  t.reregistration_kept = best.score > 0.0 && solvedFrames() >= first_views &&
                          t.reregistration_median_px < t.first_registration_median_px;
  if (t.reregistration_kept) return;
  restore(first.adjusted);
  point_of_track_ = first.point_of_track;
  keyframes_ = first.keyframes;
  init_a_ = first.init_a;
  init_b_ = first.init_b;
}

// ---------------------------------------------------------------------------------------------
// Stage 4: global adjustment, then every frame on the final map.

bool Solver::finalize() {
  if (tripod_) return true;
  // Solved frames between the keyframes join the final adjustments as cameras, evenly spread:
  // keyframes keep the incremental solve cheap, and the final adjustment gets more of each
  // track's observations (SolverOptions::final_extra_frames).
  final_cameras_.clear();
  if (options_.final_extra_frames > 0 && !options_.keyframe_collection) {
    std::vector<int> others;
    for (int f = 0; f < tracks_.frameCount(); ++f) {
      const auto& fr = frames_[static_cast<std::size_t>(f)];
      if (fr.solved && !fr.keyframe) others.push_back(f);
    }
    const std::size_t m =
        std::min(others.size(), static_cast<std::size_t>(options_.final_extra_frames));
    for (std::size_t k = 0; k < m; ++k)
      final_cameras_.push_back(others[(2 * k + 1) * others.size() / (2 * m)]);
  }
  // Twice: the second pass measures the robust scale on the adjusted map's residuals.
  // The last of them also measures how well it determines the camera centres (assessCentres).
  const bool measure = options_.max_centre_sd_steps > 0.0;
  const bool refine_distortion = distortion_terms_ > 0;
  if (!refine_distortion && options_.detect_distortion && k1_ == 0.0 && k2_ == 0.0) {
    adjustDetectingDistortion(measure);
  } else {
    adjust(true);
    adjust(true, measure && !refine_distortion);
    if (refine_distortion) adjust(true, measure);  // distortion changes the normalized points
  }
  // Every frame (keyframes included) re-resected on the final points: PnP from scratch when the
  // refined pose would not fit (recovers frames missed while the map was young).
  std::vector<uint8_t> adjusted(frames_.size(), 0);
  for (const int f : final_cameras_) adjusted[static_cast<std::size_t>(f)] = 1;
  for (int f = 0; f < tracks_.frameCount(); ++f) {
    auto& fr = frames_[static_cast<std::size_t>(f)];
    if (fr.keyframe || adjusted[static_cast<std::size_t>(f)]) continue;
    const bool was = fr.solved;
    const PoseCw before = fr.pose;
    fr.solved = false;
    if (!registerFrame(f) && was) {
      fr.solved = true;
      fr.pose = before;
    }
  }
  computeErrors();
  assessCoverage();
  assessCentres();
  if (options_.keyframe_collection) checkViewPairs();
  return solvedFrames() > 0;
}

// The median reprojection error (px) of the observations of map points in the frames the global
// adjustments refine (keyframes and final_cameras_), with the current intrinsics.
double Solver::adjustedMedianReprojectionPx() const {
  std::vector<double> e;
  const auto collect = [&](int f) {
    const auto& fr = frames_[static_cast<std::size_t>(f)];
    if (!fr.solved) return;
    for (const auto& o : tracks_.frame(f)) {
      const int p = point_of_track_[static_cast<std::size_t>(o.track)];
      if (p < 0 || !points_[static_cast<std::size_t>(p)].valid) continue;
      double px = 0.0;
      if (reprojectionErrorPx(fr.pose, points_[static_cast<std::size_t>(p)].X, normalized(o), f_,
                              px))
        e.push_back(px);
    }
  };
  for (const int f : keyframes_) collect(f);
  for (const int f : final_cameras_) collect(f);
  return e.empty() ? 0.0 : upperMedian(e);
}

// The largest displacement (px) that radial distortion k1, k2 gives a pixel of the image: over
// the undistorted radii from the centre to the farthest corner, |k1 r^2 + k2 r^4| r f.
double Solver::distortionMaxDisplacementPx(double k1, double k2) const {
  const double dx = std::max(cx_, (width_ - 1) - cx_) / f_;
  const double dy = std::max(cy_, (height_ - 1) - cy_) / (f_ * aspect_);
  const double r_max = std::sqrt(dx * dx + dy * dy);
  double worst = 0.0;
  constexpr int kSteps = 64;
  for (int i = 1; i <= kSteps; ++i) {
    const double r = r_max * i / kSteps;
    const double r2 = r * r;
    worst = std::max(worst, std::abs(k1 * r2 + k2 * r2 * r2) * r * f_);
  }
  return worst;
}

Solver::AdjustedState Solver::adjustedState() const {
  return {frames_, points_, f_, k1_, k2_, robust_cut_px_, robust_huber_px_};
}

void Solver::restore(const AdjustedState& s) {
  frames_ = s.frames;
  points_ = s.points;
  f_ = s.f;
  k1_ = s.k1;
  k2_ = s.k2;
  robust_cut_px_ = s.cut_px;
  robust_huber_px_ = s.huber_px;
}

// SolverOptions::detect_distortion: the final adjustments of a pinhole camera and, from the same
// start, of one with k1 and k2, compared after the first of each (tryDistortion). The lens is
// kept, and adjusted as refine_distortion = 2 would (three adjustments), when it shows;
// otherwise the pinhole adjustments go on from their first, as without the option (bit for bit).
// The start is the incremental solve's: after the pinhole's final adjustments an unmodelled lens
// has bent the focal and the map further (k1 = -0.2: focal +42 %), a worse start for k1, k2.
void Solver::adjustDetectingDistortion(bool measure_centres) {
  if (tryDistortion(true)) {
    adjust(true);
    adjust(true, measure_centres);
    return;
  }
  adjust(true, measure_centres);
}

// One global adjustment as a pinhole and, from the same start, one with k1 and k2 free. The lens
// is kept (distortion_terms_ = 2 from here on) when its k1, k2 move some pixel by
// detect_distortion_min_px and lower the median reprojection error of the adjusted cameras by
// detect_distortion_min_drop. Otherwise the state is what adjust(global) alone leaves, bit for
// bit: the pinhole's global adjustment's, or the start's adjusted by adjust(false). Returns
// whether the lens was kept.
bool Solver::tryDistortion(bool global) {
  const AdjustedState start = adjustedState();
  adjust(true);
  DistortionTrial& t = distortion_trial_;
  t.tried = true;
  t.views = solvedFrames();
  t.median_before_px = adjustedMedianReprojectionPx();
  const AdjustedState pinhole = adjustedState();
  restore(start);
  distortion_terms_ = 2;
  adjust(true);
  t.k1 = k1_;
  t.k2 = k2_;
  t.max_displacement_px = distortionMaxDisplacementPx(k1_, k2_);
  t.median_after_px = adjustedMedianReprojectionPx();
  t.detected =
      std::isfinite(t.max_displacement_px) &&
      t.max_displacement_px >= options_.detect_distortion_min_px &&
      t.median_after_px <= (1.0 - options_.detect_distortion_min_drop) * t.median_before_px;
  if (t.detected) return true;
  distortion_terms_ = 0;
  if (global) {
    restore(pinhole);
  } else {
    restore(start);
    adjust(false);
  }
  return false;
}

// An adjustment of the key-frame registration, with the lens trial when it is due
// (distortionTrialDue): the state after it is adjust(global)'s unless a lens is found.
void Solver::adjustTryingDistortion(bool global) {
  if (distortionTrialDue())
    tryDistortion(global);
  else
    adjust(global);
}

// In the key-frame registration, with detect_distortion and no lens yet: a trial
// (tryDistortion) with the adjustment once detect_distortion_min_views views are registered (the
// initial pair's adjustment) and whenever their number has doubled since the last one. A photo
// set's wide view steps put an unmodelled lens's error into every registration (20 views 10
// degrees apart through k1 = -0.15, k2 = 0.03: registered, but the pairs' own matches contradict
// the solve), so the final adjustments' trial comes too late; found at 4 views, the same set
// ends in a wrong focal (-7 %), found with the initial pair it solves as --distortion k1k2 does.
bool Solver::distortionTrialDue() const {
  const int views = solvedFrames();
  return options_.detect_distortion && options_.keyframe_collection && distortion_terms_ == 0 &&
         k1_ == 0.0 && k2_ == 0.0 && views >= options_.detect_distortion_min_views &&
         views >= 2 * distortion_trial_.views;
}

void Solver::computeErrors() {
  for (auto& p : points_) {
    p.observations = 0;
    p.reproj_px = 0.0;
  }
  for (int f = 0; f < tracks_.frameCount(); ++f) {
    auto& fr = frames_[static_cast<std::size_t>(f)];
    if (!fr.solved) continue;
    double sum = 0.0;
    int count = 0;
    for (const auto& o : tracks_.frame(f)) {
      const int p = point_of_track_[static_cast<std::size_t>(o.track)];
      if (p < 0 || !points_[static_cast<std::size_t>(p)].valid) continue;
      auto& mp = points_[static_cast<std::size_t>(p)];
      double e = 0.0;
      if (!reprojectionErrorPx(fr.pose, mp.X, normalized(o), f_, e)) continue;
      if (e > options_.reproj_threshold_px) continue;
      sum += e * e;
      ++count;
      mp.reproj_px += e * e;
      ++mp.observations;
    }
    fr.inliers = count;
    fr.rms_px = count > 0 ? std::sqrt(sum / count) : 0.0;
  }
  for (auto& p : points_)
    p.reproj_px = p.observations > 0 ? std::sqrt(p.reproj_px / p.observations) : 0.0;
}

void Solver::reprojectionStats(double& mean_px, double& median_px) const {
  std::vector<double> e;
  for (int f = 0; f < tracks_.frameCount(); ++f) {
    const auto& fr = frames_[static_cast<std::size_t>(f)];
    if (!fr.solved) continue;
    for (const auto& o : tracks_.frame(f)) {
      const int p = point_of_track_[static_cast<std::size_t>(o.track)];
      if (p < 0 || !points_[static_cast<std::size_t>(p)].valid) continue;
      double v = 0.0;
      if (!reprojectionErrorPx(fr.pose, points_[static_cast<std::size_t>(p)].X, normalized(o), f_,
                               v))
        continue;
      if (v <= options_.reproj_threshold_px) e.push_back(v);
    }
  }
  mean_px =
      e.empty() ? 0.0 : std::accumulate(e.begin(), e.end(), 0.0) / static_cast<double>(e.size());
  median_px = median(e);
}

}  // namespace epitrack

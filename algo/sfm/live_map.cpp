#include "algo/sfm/live_map.hpp"

#include <algorithm>
#include <cmath>

#include "algo/core/assert.hpp"
#include "algo/geometry/triangulation.hpp"
#include "algo/geometry/two_view_model_selection.hpp"
#include "algo/geometry/undistort.hpp"
#include "algo/math/median.hpp"
#include "algo/sfm/ba_camera_pose.hpp"
#include "algo/sfm/reprojection.hpp"
#include "algo/sfm/two_view_initialization.hpp"

namespace epitrack {

namespace {
constexpr double kRadToDeg = 57.29577951308232;

}  // namespace

const char* toString(LiveStatus s) {
  switch (s) {
    case LiveStatus::kInitializing:
      return "initializing";
    case LiveStatus::kTracking:
      return "tracking";
    case LiveStatus::kLost:
      return "lost";
  }
  return "unknown";
}

const char* toString(LiveInitStage s) {
  switch (s) {
    case LiveInitStage::kNone:
      return "none";
    case LiveInitStage::kCalibrating:
      return "calibrating-focal";
    case LiveInitStage::kNewReference:
      return "new-reference";
    case LiveInitStage::kTooFewTracks:
      return "too-few-tracks";
    case LiveInitStage::kTooLittleMotion:
      return "too-little-motion";
    case LiveInitStage::kNoTwoViewGeometry:
      return "no-two-view-geometry";
    case LiveInitStage::kTooFewPoints:
      return "too-few-points";
    case LiveInitStage::kTooLittleParallax:
      return "too-little-parallax";
  }
  return "unknown";
}

LiveMap::LiveMap(const LiveMapOptions& options, const CameraIntrinsics& intrinsics)
    : options_(options),
      K_(intrinsics),
      fundamental_(std::max(8, options.max_features)),
      pnp_(std::max(4, options.max_features)),
      ba_(options.ba_window + options.ba_fixed, options.max_points,
          (options.ba_window + options.ba_fixed) * options.max_features,
          options.readout_frames > 0.0 ? BaCapacity::kRollingShutter : BaCapacity::kGlobalShutter),
      homography_(std::max(8, options.max_features)),
      essential_(std::max(8, options.max_features)) {
  EPITRACK_ASSERT(options.max_features > 0 && options.max_points > 0);
  EPITRACK_ASSERT(options.max_keyframes >= 2 && options.ba_window >= 2);
  EPITRACK_ASSERT(options.ba_window + options.ba_fixed <= options.max_keyframes);
  const auto nf = static_cast<std::size_t>(options.max_features);
  const auto np = static_cast<std::size_t>(options.max_points);
  const auto nk = static_cast<std::size_t>(options.max_keyframes);
  const auto nba = static_cast<std::size_t>(options.ba_window + options.ba_fixed);
  sorted_features_.resize(nf);
  records_.resize(nf);
  records_next_.resize(nf);
  points_.resize(np);
  free_points_.resize(np);
  keyframes_.resize(nk);
  kf_obs_.resize(nk * nf);
  x1_.resize(nf);
  x2_.resize(nf);
  n1_.resize(nf);
  n2_.resize(nf);
  X_.resize(nf);
  if (options.readout_frames > 0.0) {
    shutter_ = RollingShutter::fromReadout(options.readout_frames, intrinsics.height,
                                           0.5 * (intrinsics.height - 1));
    rs_X_.resize(nf);
    rs_px_.resize(nf);
    ba_motions_.resize(static_cast<std::size_t>(options.ba_window + options.ba_fixed));
  }
  record_of_match_.resize(nf);
  accepted_.resize(nf);
  scratch_.resize(nf);
  robust_mask_.resize(nf);
  ba_cameras_.resize(nba);
  ba_fixed_.resize(nba);
  ba_kf_seq_.resize(nba);
  ba_points_.resize(np);
  ba_point_index_.resize(np);
  ba_slot_of_point_.assign(np, -1);
  ba_obs_.resize(nba * nf);
  if (options.self_calibrate) {
    EPITRACK_ASSERT(options.calib_references >= 1 && options.calib_max_pairs >= 1);
    const auto nr = static_cast<std::size_t>(options.calib_references);
    calib_refs_.resize(nr);
    calib_ids_.resize(nr * nf);
    calib_px_.resize(nr * nf);
    calib_F_.resize(static_cast<std::size_t>(options.calib_max_pairs));
    calib_per_pair_.resize(static_cast<std::size_t>(options.calib_max_pairs));
    state_ = State::kCalibrating;
  }
  reset();
}

std::size_t LiveMap::reservedBytes() const {
  std::size_t b = 0;
  b += sorted_features_.capacity() * sizeof(TrackedFeature);
  b += (records_.capacity() + records_next_.capacity()) * sizeof(TrackRecord);
  b += points_.capacity() * sizeof(MapPointSlot) + free_points_.capacity() * sizeof(int);
  b += keyframes_.capacity() * sizeof(Keyframe) + kf_obs_.capacity() * sizeof(KeyframeObservation);
  b +=
      (x1_.capacity() + x2_.capacity() + n1_.capacity() + n2_.capacity()) * sizeof(Eigen::Vector2d);
  b += X_.capacity() * sizeof(Eigen::Vector3d) +
       (record_of_match_.capacity() + accepted_.capacity()) * sizeof(int);
  b += scratch_.capacity() * sizeof(double) + robust_mask_.capacity();
  b += ba_cameras_.capacity() * sizeof(BaCamera) + ba_fixed_.capacity() +
       ba_kf_seq_.capacity() * sizeof(int64_t);
  b += ba_points_.capacity() * sizeof(Eigen::Vector3d) + ba_point_index_.capacity() * sizeof(int) +
       ba_slot_of_point_.capacity() * sizeof(int) + ba_obs_.capacity() * sizeof(BaObservation);
  b += calib_refs_.capacity() * sizeof(CalibReference) + calib_ids_.capacity() * sizeof(int32_t) +
       calib_px_.capacity() * sizeof(Eigen::Vector2d) +
       calib_F_.capacity() * sizeof(Eigen::Matrix3d) +
       calib_per_pair_.capacity() * sizeof(FocalPairEstimate);
  return b;
}

void LiveMap::reset() {
  if (state_ != State::kCalibrating) state_ = State::kInitializing;
  motion_ = RollingShutterMotion{};
  ref_frame_ = -1;
  for (int i = 0; i < record_count_; ++i) {
    auto& r = records_[static_cast<std::size_t>(i)];
    r.point = -1;
    r.first_kf = -1;
    r.has_ref = false;
    r.outlier_frames = 0;
  }
  for (auto& p : points_) p = MapPointSlot{};
  free_count_ = options_.max_points;
  for (int i = 0; i < free_count_; ++i)
    free_points_[static_cast<std::size_t>(i)] = options_.max_points - 1 - i;
  points_in_use_ = 0;
  kf_first_seq_ = kf_next_seq_;
  frames_since_kf_ = 0;
  robust_sigma_px_ = 0.0;  // a new map measures its own residual scale
}

Eigen::Vector2d LiveMap::normalize(double x, double y) const { return undistortPixel(K_, x, y, 8); }

LiveMap::Keyframe* LiveMap::keyframe(int64_t seq) {
  if (seq < kf_first_seq_ || seq >= kf_next_seq_) return nullptr;
  return &keyframes_[static_cast<std::size_t>(seq % options_.max_keyframes)];
}

LiveMap::KeyframeObservation* LiveMap::keyframeObservations(int64_t seq) {
  return &kf_obs_[static_cast<std::size_t>(seq % options_.max_keyframes) *
                  static_cast<std::size_t>(options_.max_features)];
}

double LiveMap::median(std::span<double> values) { return upperMedian(values); }

// ---------------------------------------------------------------------------------------------
// Track bookkeeping: the tracker's ids only grow and a lost id never returns, so the records stay
// sorted by id and one merge per frame keeps those still tracked and appends the new ones.

void LiveMap::mergeTracks(std::span<const TrackedFeature> features) {
  const std::size_t n = std::min(features.size(), sorted_features_.size());
  std::copy(features.begin(), features.begin() + static_cast<std::ptrdiff_t>(n),
            sorted_features_.begin());
  std::sort(sorted_features_.begin(), sorted_features_.begin() + static_cast<std::ptrdiff_t>(n),
            [](const TrackedFeature& a, const TrackedFeature& b) { return a.id < b.id; });
  int out = 0;
  int r = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const TrackedFeature& f = sorted_features_[i];
    // Records of tracks that ended: their points lose their track.
    while (r < record_count_ && records_[static_cast<std::size_t>(r)].id < f.id) {
      const int p = records_[static_cast<std::size_t>(r)].point;
      if (p >= 0) points_[static_cast<std::size_t>(p)].attached = false;
      ++r;
    }
    TrackRecord& dst = records_next_[static_cast<std::size_t>(out++)];
    if (r < record_count_ && records_[static_cast<std::size_t>(r)].id == f.id) {
      dst = records_[static_cast<std::size_t>(r)];
      ++r;
    } else {
      dst = TrackRecord{};
      dst.id = f.id;
    }
    dst.px = Eigen::Vector2d(f.x, f.y);
    dst.n = normalize(f.x, f.y);
    dst.inlier = false;
  }
  for (; r < record_count_; ++r) {
    const int p = records_[static_cast<std::size_t>(r)].point;
    if (p >= 0) points_[static_cast<std::size_t>(p)].attached = false;
  }
  records_.swap(records_next_);
  record_count_ = out;
}

// ---------------------------------------------------------------------------------------------
// Per frame.

LiveFrameResult LiveMap::process(std::span<const TrackedFeature> features) {
  LiveFrameResult result;
  mergeTracks(features);
  result.init.tracks_alive = record_count_;
  if (state_ == State::kCalibrating) {
    result.status = LiveStatus::kInitializing;
    result.init.stage = LiveInitStage::kCalibrating;
    result.calibrated = calibrateStep();
    result.init.pairs = static_cast<int>(
        std::min<int64_t>(calib_pairs_total_, static_cast<int64_t>(options_.calib_max_pairs)));
    if (result.calibrated) state_ = State::kInitializing;  // the map starts from the next frame
  } else if (state_ == State::kInitializing) {
    result.status = LiveStatus::kInitializing;
    if (tryInitialize(result)) {
      state_ = State::kTracking;
      result.status = LiveStatus::kTracking;
      result.initialized = true;
      result.init.stage = LiveInitStage::kNone;
    }
  } else if (trackFrame(result)) {
    result.status = LiveStatus::kTracking;
  } else {
    // Tracking lost: the map restarts with this frame as the new reference.
    result.status = LiveStatus::kLost;
    reset();
    setReference();
  }
  result.points = points_in_use_;
  ++frame_;
  return result;
}

void LiveMap::setReference() {
  ref_frame_ = frame_;
  for (int i = 0; i < record_count_; ++i) {
    auto& r = records_[static_cast<std::size_t>(i)];
    r.has_ref = true;
    r.ref_n = r.n;
    r.ref_px = r.px;
  }
}

// ---------------------------------------------------------------------------------------------
// Focal self-calibration (paper §5.2), causal: up to calib_references reference frames are
// followed at once (a new one every calib_reference_interval frames); a reference whose tracks
// have moved by calib_pair_displacement closes a pair: F and H by RANSAC, GRIC model selection,
// and an F pair (general motion, 3D scene) joins the ring of F matrices. From calib_min_pairs on,
// the pairs' cost curves are minimised jointly (calibrateFocalMultiPair); an observable focal ends
// the calibration. Pixels are used as they come: without intrinsics there is no distortion model.

bool LiveMap::calibrateStep() {
  const auto nf = static_cast<std::size_t>(options_.max_features);
  const int nr = options_.calib_references;
  // Start a new reference when a slot is free and the interval has passed.
  int64_t newest = -1;
  int free_slot = -1;
  for (int k = 0; k < nr; ++k) {
    const auto& ref = calib_refs_[static_cast<std::size_t>(k)];
    if (ref.frame < 0) {
      if (free_slot < 0) free_slot = k;
    } else {
      newest = std::max(newest, ref.frame);
    }
  }
  if (free_slot >= 0 && (newest < 0 || frame_ - newest >= options_.calib_reference_interval)) {
    auto& ref = calib_refs_[static_cast<std::size_t>(free_slot)];
    ref.frame = frame_;
    ref.count = record_count_;
    const std::size_t base = static_cast<std::size_t>(free_slot) * nf;
    for (int i = 0; i < record_count_; ++i) {
      calib_ids_[base + static_cast<std::size_t>(i)] = records_[static_cast<std::size_t>(i)].id;
      calib_px_[base + static_cast<std::size_t>(i)] = records_[static_cast<std::size_t>(i)].px;
    }
  }
  bool added = false;
  for (int k = 0; k < nr; ++k) {
    auto& ref = calib_refs_[static_cast<std::size_t>(k)];
    if (ref.frame < 0 || ref.frame == frame_) continue;
    // Common tracks: both lists are sorted by id.
    const std::size_t base = static_cast<std::size_t>(k) * nf;
    int common = 0;
    int a = 0;
    for (int i = 0; i < record_count_ && a < ref.count; ++i) {
      const auto& r = records_[static_cast<std::size_t>(i)];
      while (a < ref.count && calib_ids_[base + static_cast<std::size_t>(a)] < r.id) ++a;
      if (a < ref.count && calib_ids_[base + static_cast<std::size_t>(a)] == r.id) {
        const auto c = static_cast<std::size_t>(common++);
        x1_[c] = calib_px_[base + static_cast<std::size_t>(a)];
        x2_[c] = r.px;
        scratch_[c] = (x2_[c] - x1_[c]).norm();
      }
    }
    if (common < options_.init_min_tracks) {  // the reference faded out before moving enough
      ref.frame = -1;
      continue;
    }
    const double disp =
        median(std::span<double>(scratch_.data(), static_cast<std::size_t>(common)));
    if (disp < options_.calib_pair_displacement * K_.width) continue;
    ref.frame = -1;  // the pair is closed either way
    FundamentalOptions fo;
    fo.ransac.seed = options_.seed + static_cast<uint64_t>(frame_);
    const auto nc = static_cast<std::size_t>(common);
    const auto r =
        estimateFocalFromMatches(std::span<const Eigen::Vector2d>(x1_.data(), nc),
                                 std::span<const Eigen::Vector2d>(x2_.data(), nc), K_.width,
                                 K_.height, fundamental_, homography_, 0.5, fo);
    if (r.model != PairModel::kFundamental) continue;
    calib_F_[static_cast<std::size_t>(calib_pairs_total_ % options_.calib_max_pairs)] = r.F;
    ++calib_pairs_total_;
    added = true;
  }
  if (frame_ >= options_.calib_max_frames) {
    // Critical or too little motion so far (the focal is not observable): go on with a guess
    // rather than never tracking; the device reports the focal source.
    const double f = options_.fallback_focal_widths * std::max(K_.width, K_.height);
    K_ = CameraIntrinsics::centered(K_.width, K_.height, f);
    calib_fallback_ = true;
    ref_frame_ = -1;
    return true;
  }
  if (!added || calib_pairs_total_ < options_.calib_min_pairs) return false;
  const auto n = static_cast<std::size_t>(
      std::min<int64_t>(calib_pairs_total_, static_cast<int64_t>(options_.calib_max_pairs)));
  const auto c =
      calibrateFocalMultiPair(std::span<const Eigen::Matrix3d>(calib_F_.data(), n), K_.width,
                              K_.height, std::span<FocalPairEstimate>(calib_per_pair_.data(), n));
  if (!c.observable || c.coherent_pairs < options_.calib_min_pairs) return false;
  K_.fx = c.focal_px;
  K_.fy = c.focal_px;
  K_.cx = 0.5 * (K_.width - 1);
  K_.cy = 0.5 * (K_.height - 1);
  K_.k1 = 0.0;
  K_.k2 = 0.0;
  calib_pairs_used_ = static_cast<int>(n);
  ref_frame_ = -1;
  return true;
}

// ---------------------------------------------------------------------------------------------
// Initialisation from two views (paper §5.1-5.3).

// A plane (a floor, a wall, a table top filling the view) does not define F: every F of a
// two-parameter family fits the matches, RANSAC returns one at random, and E = K^T F K gives a
// wrong relative pose that the map then keeps, consistently and silently (a rendered floor gave
// 18 degrees of rotation for 3). So the pair's model is selected first (GRIC, as the offline
// solver): where H explains the matches, the relative pose comes from the five-point E-RANSAC on
// the normalized matches instead, which the known intrinsics make well-posed for a plane too
// (Nister 2004); a pure rotation then fails the parallax test and the map keeps waiting.
// `F`/`mask` are replaced by the essential matrix's F = K^-T E K^-1 and inliers. False: no model.
bool LiveMap::initialPairModel(std::span<const Eigen::Vector2d> x1,
                               std::span<const Eigen::Vector2d> x2,
                               std::span<const Eigen::Vector2d> n1,
                               std::span<const Eigen::Vector2d> n2, const Eigen::Matrix3d& K,
                               const FundamentalResult& fr, Eigen::Matrix3d& F,
                               std::span<const uint8_t>& mask) {
  HomographyOptions ho;
  ho.ransac.seed = options_.seed + static_cast<uint64_t>(frame_);
  HomographyResult hr;
  if (homography_.estimate(x1, x2, ho, hr) != HomographyRansac::Status::kOk) return true;
  const auto sel = selectTwoViewModel(fr.F, hr.H, x1, x2, 0.5, fr.mask, hr.mask);
  if (sel.model == TwoViewModel::kFundamental) return true;
  EssentialRansacOptions eo;
  eo.focal_px = K_.fx;
  eo.ransac.seed = options_.seed + static_cast<uint64_t>(frame_);
  EssentialRansacResult er;
  if (essential_.estimate(n1, n2, eo, er) != EssentialRansac::Status::kOk) return false;
  if (er.inliers < options_.init_min_points) return false;
  const Eigen::Matrix3d K_inv = K.inverse();
  F = K_inv.transpose() * er.E * K_inv;
  mask = er.mask;
  return true;
}

bool LiveMap::tryInitialize(LiveFrameResult& result) {
  LiveInitProgress& progress = result.init;
  if (ref_frame_ < 0 || frame_ - ref_frame_ > options_.init_max_gap) {
    setReference();
    progress.stage = LiveInitStage::kNewReference;
    progress.reference_frame = ref_frame_;
    return false;
  }
  progress.reference_frame = ref_frame_;
  int common = 0;
  for (int i = 0; i < record_count_; ++i) {
    const auto& r = records_[static_cast<std::size_t>(i)];
    if (!r.has_ref) continue;
    const auto c = static_cast<std::size_t>(common);
    // F is estimated on undistorted pixels (normalized coordinates through K).
    x1_[c] = Eigen::Vector2d(K_.fx * r.ref_n.x() + K_.cx, K_.fy * r.ref_n.y() + K_.cy);
    x2_[c] = Eigen::Vector2d(K_.fx * r.n.x() + K_.cx, K_.fy * r.n.y() + K_.cy);
    n1_[c] = r.ref_n;
    n2_[c] = r.n;
    scratch_[c] = (x2_[c] - x1_[c]).norm();
    record_of_match_[c] = i;
    ++common;
  }
  result.map_matches = 0;
  progress.common_tracks = common;
  if (common < options_.init_min_tracks) {
    // The reference faded out: this frame becomes the new one.
    setReference();
    progress.stage = LiveInitStage::kTooFewTracks;
    return false;
  }
  const double disp = median(std::span<double>(scratch_.data(), static_cast<std::size_t>(common)));
  progress.displacement_px = disp;
  progress.stage = LiveInitStage::kTooLittleMotion;
  if (disp < options_.init_min_displacement * K_.width) return false;
  progress.stage = LiveInitStage::kNoTwoViewGeometry;

  const auto nc = static_cast<std::size_t>(common);
  const std::span<const Eigen::Vector2d> x1(x1_.data(), nc), x2(x2_.data(), nc);
  const std::span<const Eigen::Vector2d> n1(n1_.data(), nc), n2(n2_.data(), nc);
  FundamentalOptions fo;
  fo.ransac.seed = options_.seed + static_cast<uint64_t>(frame_);
  FundamentalResult fr;
  if (fundamental_.estimate(x1, x2, fo, fr) != FundamentalRansac::Status::kOk) return false;
  if (fr.inliers < options_.init_min_points) return false;
  Eigen::Matrix3d K;
  K << K_.fx, 0, K_.cx, 0, K_.fy, K_.cy, 0, 0, 1;
  Eigen::Matrix3d F = fr.F;
  std::span<const uint8_t> mask = fr.mask;
  if (!initialPairModel(x1, x2, n1, n2, K, fr, F, mask)) return false;
  TwoViewOptions tv;
  tv.focal_px = K_.fx;
  tv.min_point_parallax_deg = options_.min_point_parallax_deg;
  tv.reproj_threshold_px = options_.reproj_threshold_px;
  PoseCw pose;
  int good = 0;
  if (reconstructTwoView(F, K, n1, n2, mask, tv, pose, std::span(X_.data(), nc),
                         std::span(accepted_.data(), nc), std::span(scratch_.data(), nc),
                         good) != TwoViewStatus::kOk)
    return false;
  progress.points = good;
  progress.stage = LiveInitStage::kTooFewPoints;
  if (good < options_.init_min_points) return false;
  const double med_parallax =
      median(std::span<double>(scratch_.data(), static_cast<std::size_t>(good)));
  progress.parallax_deg = med_parallax;
  progress.stage = LiveInitStage::kTooLittleParallax;
  if (med_parallax < options_.init_min_parallax_deg) return false;

  // Accept: keyframe A is the reference (identity), keyframe B this frame.
  const int64_t kf_a = addKeyframe(PoseCw{}, good);
  keyframe(kf_a)->frame = ref_frame_;
  const int64_t kf_b = addKeyframe(pose, good);
  for (int g = 0; g < good; ++g) {
    const auto i = static_cast<std::size_t>(accepted_[static_cast<std::size_t>(g)]);
    const int p = allocatePoint(X_[i]);
    if (p < 0) break;
    auto& rec = records_[static_cast<std::size_t>(record_of_match_[i])];
    rec.point = p;
    points_[static_cast<std::size_t>(p)].attached = true;
    addObservation(kf_a, p, rec.ref_px);
    addObservation(kf_b, p, rec.px);
  }
  // Tracks without a point keep their first sighting for later triangulation.
  for (int i = 0; i < record_count_; ++i) {
    auto& r = records_[static_cast<std::size_t>(i)];
    if (r.point >= 0) continue;
    if (r.has_ref) {
      r.first_kf = kf_a;
      r.first_n = r.ref_n;
      r.first_px = r.ref_px;
    } else {
      r.first_kf = kf_b;
      r.first_n = r.n;
      r.first_px = r.px;
    }
  }
  for (int i = 0; i < record_count_; ++i) records_[static_cast<std::size_t>(i)].has_ref = false;
  ref_frame_ = -1;
  adjustWindow();
  result.pose = keyframe(kf_b)->pose;
  result.inliers = good;
  result.map_matches = good;
  result.keyframe = true;
  return true;
}

// ---------------------------------------------------------------------------------------------
// Tracking: resection on the map (paper §5.4), keyframes, new points, windowed adjustment.

int LiveMap::predictTracks(const PoseCw& pose, std::span<TrackPrediction> out) const {
  if (state_ != State::kTracking) return 0;
  const double max_x = static_cast<double>(K_.width - 1);
  const double max_y = static_cast<double>(K_.height - 1);
  int n = 0;
  for (int i = 0; i < record_count_ && static_cast<std::size_t>(n) < out.size(); ++i) {
    const auto& r = records_[static_cast<std::size_t>(i)];
    if (r.point < 0 || !points_[static_cast<std::size_t>(r.point)].valid) continue;
    const Eigen::Vector3d X_c = pose.toCamera(points_[static_cast<std::size_t>(r.point)].X);
    if (!(X_c.z() > 0.0)) continue;
    const Eigen::Vector2d px = distortToPixel(K_, X_c.hnormalized());
    if (!(px.x() >= 0.0 && px.y() >= 0.0 && px.x() <= max_x && px.y() <= max_y)) continue;
    out[static_cast<std::size_t>(n++)] =
        TrackPrediction{r.id, static_cast<float>(px.x()), static_cast<float>(px.y())};
  }
  return n;
}

bool LiveMap::trackFrame(LiveFrameResult& result) {
  int m = 0;
  for (int i = 0; i < record_count_; ++i) {
    const auto& r = records_[static_cast<std::size_t>(i)];
    if (r.point < 0 || !points_[static_cast<std::size_t>(r.point)].valid) continue;
    X_[static_cast<std::size_t>(m)] = points_[static_cast<std::size_t>(r.point)].X;
    n1_[static_cast<std::size_t>(m)] = r.n;
    record_of_match_[static_cast<std::size_t>(m)] = i;
    ++m;
  }
  result.map_matches = m;
  if (m < options_.min_pnp_inliers) return false;
  PnpOptions po;
  po.focal_px = K_.fx;
  po.ransac.threshold = options_.reproj_threshold_px;
  po.ransac.seed = options_.seed + static_cast<uint64_t>(frame_);
  po.refine_options.huber_px = options_.huber_px;
  PnpResult pr;
  const auto nm = static_cast<std::size_t>(m);
  if (pnp_.estimate(std::span<const Eigen::Vector3d>(X_.data(), nm),
                    std::span<const Eigen::Vector2d>(n1_.data(), nm), po,
                    pr) != PnpRansac::Status::kOk)
    return false;
  if (pr.inliers < options_.min_pnp_inliers || pr.inliers * 2 < m) return false;
  for (std::size_t j = 0; j < nm; ++j) {
    auto& r = records_[static_cast<std::size_t>(record_of_match_[j])];
    if (pr.mask[j]) {
      r.inlier = true;
      r.outlier_frames = 0;
    } else if (++r.outlier_frames >= options_.max_outlier_frames) {
      // The track drifted off its point (or the point is wrong): part them.
      auto& p = points_[static_cast<std::size_t>(r.point)];
      p.attached = false;
      p.valid = false;
      r.point = -1;
      r.first_kf = -1;
      r.outlier_frames = 0;
    }
  }
  if (options_.outlier_sigmas > 0.0) robustRefine(nm, pr);
  if (shutter_.line_delay > 0.0) refineRollingShutter(nm, pr);
  result.pose = pr.pose;
  result.inliers = pr.inliers;
  ++frames_since_kf_;
  if (needKeyframe(pr.pose, pr.inliers)) {
    const int64_t kf = addKeyframe(pr.pose, pr.inliers);
    for (int i = 0; i < record_count_; ++i) {
      const auto& r = records_[static_cast<std::size_t>(i)];
      if (r.point >= 0 && r.inlier) addObservation(kf, r.point, r.px);
    }
    triangulateNew(kf);
    adjustWindow();
    collectGarbage();
    result.pose = keyframe(kf)->pose;
    result.keyframe = true;
  }
  return true;
}

void LiveMap::robustRefine(std::size_t matches, PnpResult& pr) {
  // The residual scale of this frame's inliers (Rayleigh: median |e| = 1.1774 sigma), smoothed
  // over frames; the pose is refined again on the matches within outlier_sigmas of it with a
  // Huber threshold of huber_sigmas (as the offline solver's final poses, Solver::registerFrame).
  int n = 0;
  for (std::size_t j = 0; j < matches; ++j) {
    if (!pr.mask[j]) continue;
    double e = 0.0;
    if (!reprojectionErrorPx(pr.pose, X_[j], n1_[j], K_.fx, e)) continue;
    scratch_[static_cast<std::size_t>(n++)] = e;
  }
  if (n < options_.min_pnp_inliers) return;
  const double sigma = median(std::span<double>(scratch_.data(), static_cast<std::size_t>(n))) /
                       kRayleighMedianPerSigma;
  robust_sigma_px_ = robust_sigma_px_ > 0.0 ? 0.8 * robust_sigma_px_ + 0.2 * sigma : sigma;
  const double cut =
      std::min(options_.reproj_threshold_px,
               std::max(options_.min_outlier_px, options_.outlier_sigmas * robust_sigma_px_));
  int kept = 0;
  for (std::size_t j = 0; j < matches; ++j) {
    double e = 0.0;
    const bool keep =
        pr.mask[j] && reprojectionErrorPx(pr.pose, X_[j], n1_[j], K_.fx, e) && e <= cut;
    robust_mask_[j] = keep ? 1 : 0;
    kept += keep ? 1 : 0;
  }
  if (kept < options_.min_pnp_inliers) return;
  PoseRefineOptions ro;
  ro.focal_px = K_.fx;
  ro.huber_px = std::min(options_.huber_px, std::max(0.5 * options_.min_outlier_px,
                                                     options_.huber_sigmas * robust_sigma_px_));
  refinePose(std::span<const Eigen::Vector3d>(X_.data(), matches),
             std::span<const Eigen::Vector2d>(n1_.data(), matches),
             std::span<const uint8_t>(robust_mask_.data(), matches), ro, pr.pose);
}

void LiveMap::refineRollingShutter(std::size_t matches, PnpResult& pr) {
  // The middle-row pose and the motion over the readout, on the PnP inliers in pixels (each
  // point is seen on its own row); the Huber weights take care of the few bad ones.
  std::size_t n = 0;
  for (std::size_t j = 0; j < matches; ++j) {
    if (!pr.mask[j]) continue;
    rs_X_[n] = X_[j];
    rs_px_[n] = records_[static_cast<std::size_t>(record_of_match_[j])].px;
    ++n;
  }
  if (static_cast<int>(n) < options_.min_pnp_inliers) return;
  PoseCw pose = pr.pose;
  RollingShutterMotion motion = motion_;  // the last frame's: the motion changes slowly
  RollingShutterResectionOptions ro;
  ro.huber_px = options_.huber_px;
  const auto r = refineRollingShutterPose(
      K_, shutter_, std::span<const Eigen::Vector3d>(rs_X_.data(), n),
      std::span<const Eigen::Vector2d>(rs_px_.data(), n), pose, motion, ro);
  if (!(r.rms_px <= options_.reproj_threshold_px) || !pose.R_cw.allFinite() ||
      !pose.t_cw.allFinite() || !motion.angular.allFinite() || !motion.linear.allFinite())
    return;
  pr.pose = pose;
  motion_ = motion;
}

bool LiveMap::needKeyframe(const PoseCw& pose, int inliers) {
  const Keyframe* last = keyframe(kf_next_seq_ - 1);
  if (last == nullptr) return true;
  if (frames_since_kf_ >= options_.keyframe_max_gap) return true;
  // A young map (few keyframes) is weak: keyframes come densely until it has matured.
  if (keyframeCount() < options_.young_map_keyframes &&
      frames_since_kf_ >= options_.young_map_keyframe_gap)
    return true;
  if (static_cast<double>(inliers) <
      options_.keyframe_min_tracked * static_cast<double>(last->inliers))
    return true;
  // Median parallax of the inlier points between the last keyframe's centre and this one.
  const Eigen::Vector3d c0 = last->pose.centre();
  const Eigen::Vector3d c1 = pose.centre();
  int n = 0;
  for (int i = 0; i < record_count_; ++i) {
    const auto& r = records_[static_cast<std::size_t>(i)];
    if (!r.inlier) continue;
    const Eigen::Vector3d& X = points_[static_cast<std::size_t>(r.point)].X;
    const double c = (X - c0).normalized().dot((X - c1).normalized());
    scratch_[static_cast<std::size_t>(n++)] = std::acos(std::clamp(c, -1.0, 1.0)) * kRadToDeg;
  }
  return median(std::span<double>(scratch_.data(), static_cast<std::size_t>(n))) >=
         options_.keyframe_parallax_deg;
}

int64_t LiveMap::addKeyframe(const PoseCw& pose, int inliers) {
  if (kf_next_seq_ - kf_first_seq_ >= options_.max_keyframes) ++kf_first_seq_;  // ring: evict
  const int64_t seq = kf_next_seq_++;
  Keyframe& kf = keyframes_[static_cast<std::size_t>(seq % options_.max_keyframes)];
  kf.seq = seq;
  kf.frame = frame_;
  kf.pose = pose;
  kf.motion = motion_;
  kf.obs_count = 0;
  kf.inliers = inliers;
  frames_since_kf_ = 0;
  return seq;
}

void LiveMap::addObservation(int64_t kf_seq, int point, const Eigen::Vector2d& px) {
  Keyframe* kf = keyframe(kf_seq);
  if (kf == nullptr || kf->obs_count >= options_.max_features) return;
  keyframeObservations(kf_seq)[kf->obs_count++] = {point, px};
  auto& p = points_[static_cast<std::size_t>(point)];
  p.last_kf = std::max(p.last_kf, kf_seq);
}

int LiveMap::allocatePoint(const Eigen::Vector3d& X) {
  if (free_count_ == 0) return -1;  // full: no growth
  const int p = free_points_[static_cast<std::size_t>(--free_count_)];
  auto& slot = points_[static_cast<std::size_t>(p)];
  slot = MapPointSlot{};
  slot.X = X;
  slot.used = true;
  slot.valid = true;
  ++points_in_use_;
  return p;
}

void LiveMap::collectGarbage() {
  // A point no live track refers to and no kept keyframe observes is gone for good.
  for (int i = 0; i < options_.max_points; ++i) {
    auto& p = points_[static_cast<std::size_t>(i)];
    if (!p.used || p.attached || p.last_kf >= kf_first_seq_) continue;
    p = MapPointSlot{};
    free_points_[static_cast<std::size_t>(free_count_++)] = i;
    --points_in_use_;
  }
}

int LiveMap::triangulateNew(int64_t kf_seq) {
  TriangulationOptions to;
  to.focal_px = K_.fx;
  to.min_parallax_deg = options_.min_point_parallax_deg;
  to.max_reproj_px = options_.reproj_threshold_px;
  const PoseCw current = keyframe(kf_seq)->pose;
  int added = 0;
  for (int i = 0; i < record_count_; ++i) {
    auto& r = records_[static_cast<std::size_t>(i)];
    if (r.point >= 0) continue;
    const Keyframe* first = r.first_kf >= 0 ? keyframe(r.first_kf) : nullptr;
    if (first == nullptr) {  // new track, or its first keyframe left the ring: start here
      r.first_kf = kf_seq;
      r.first_n = r.n;
      r.first_px = r.px;
      continue;
    }
    if (r.first_kf == kf_seq) continue;
    const PoseCw poses[2] = {first->pose, current};
    const Eigen::Vector2d obs[2] = {r.first_n, r.n};
    const auto t = triangulatePoint(poses, obs, to);
    if (t.status != TriangulationStatus::kOk) continue;
    const int p = allocatePoint(t.X);
    if (p < 0) break;
    r.point = p;
    points_[static_cast<std::size_t>(p)].attached = true;
    addObservation(r.first_kf, p, r.first_px);
    addObservation(kf_seq, p, r.px);
    ++added;
  }
  return added;
}

void LiveMap::restoreScale(int n_cams, int n_pts) {
  // One fixed camera (the last of the adjustment): scale the free cameras and the points about
  // its centre so the distance to the nearest free camera is what it was before the adjustment.
  const auto fixed = static_cast<std::size_t>(n_cams - 1);
  const Eigen::Vector3d c_fixed = fromBa(ba_cameras_[fixed]).centre();
  const Eigen::Vector3d c_before = keyframe(ba_kf_seq_[fixed - 1])->pose.centre();
  const Eigen::Vector3d c_after = fromBa(ba_cameras_[fixed - 1]).centre();
  const double before = (c_before - c_fixed).norm();
  const double after = (c_after - c_fixed).norm();
  if (!(after > 1e-12) || !std::isfinite(before / after)) return;
  const double s = before / after;
  for (std::size_t c = 0; c < fixed; ++c) {
    auto& cam = ba_cameras_[c];
    const Eigen::Vector3d centre = c_fixed + s * (fromBa(cam).centre() - c_fixed);
    cam.t_cw = -cam.R_cw * centre;
  }
  for (int i = 0; i < n_pts; ++i) {
    auto& X = ba_points_[static_cast<std::size_t>(i)];
    X = c_fixed + s * (X - c_fixed);
  }
}

void LiveMap::adjustWindow() {
  // Cameras: the newest ba_window keyframes free, up to ba_fixed older ones fixed (the gauge);
  // with no older keyframe, the oldest of the window is fixed.
  const int64_t newest = kf_next_seq_ - 1;
  const int64_t total = kf_next_seq_ - kf_first_seq_;
  const int n_cams = static_cast<int>(
      std::min<int64_t>(total, static_cast<int64_t>(options_.ba_window + options_.ba_fixed)));
  if (n_cams < 2) return;
  // Gauge: a monocular map is defined up to a similarity. With two or more fixed cameras the
  // adjustment cannot move it; with one (the two-view start) the scale is free, so it is restored
  // afterwards (otherwise every adjustment lets it wander and the poses already sent jump).
  const int n_free = std::min(options_.ba_window, std::max(1, n_cams - 2));
  for (int c = 0; c < n_free; ++c) ba_kf_seq_[static_cast<std::size_t>(c)] = newest - c;
  // Fixed cameras: the keyframe just before the window, then the older ones spread evenly back
  // to the oldest of the ring. Keyframes come densely (every frame while the map is young), so
  // the newest ones alone span a short baseline; the old ones observe the same points from far
  // away and pin their depths (the long baseline is what makes a point accurate).
  const int n_fixed = n_cams - n_free;
  const int64_t older = total - n_free;  // keyframes before the window, n_fixed <= older
  for (int k = 0; k < n_fixed; ++k) {
    // back 0: the keyframe just before the window, older - 1: the oldest of the ring.
    const int64_t back =
        n_fixed > 1 ? (static_cast<int64_t>(k) * (older - 1) + (n_fixed - 1) / 2) / (n_fixed - 1)
                    : 0;
    ba_kf_seq_[static_cast<std::size_t>(n_free + k)] = newest - n_free - back;
  }
  for (int c = 0; c < n_cams; ++c) {
    ba_cameras_[static_cast<std::size_t>(c)] =
        toBa(keyframe(ba_kf_seq_[static_cast<std::size_t>(c)])->pose);
    ba_fixed_[static_cast<std::size_t>(c)] = c < n_free ? 0 : 1;
  }
  // Points observed by the free cameras.
  int n_pts = 0;
  for (int c = 0; c < n_free; ++c) {
    const int64_t seq = ba_kf_seq_[static_cast<std::size_t>(c)];
    const KeyframeObservation* obs = keyframeObservations(seq);
    const int count = keyframe(seq)->obs_count;
    for (int j = 0; j < count; ++j) {
      const int p = obs[j].point;
      const auto& mp = points_[static_cast<std::size_t>(p)];
      if (!mp.valid || ba_slot_of_point_[static_cast<std::size_t>(p)] >= 0) continue;
      ba_slot_of_point_[static_cast<std::size_t>(p)] = n_pts;
      ba_points_[static_cast<std::size_t>(n_pts)] = mp.X;
      ba_point_index_[static_cast<std::size_t>(n_pts)] = p;
      ++n_pts;
    }
  }
  // Observations of those points in every camera, gross outliers left out. Once tracked frames
  // have measured the residual scale (robustRefine), the Huber threshold follows it; a cut at
  // outlier_sigmas here was tried and bent the live orbit (ATE 0.00012 -> 0.00017, seed 1).
  const double cut = 4.0 * options_.reproj_threshold_px;
  double huber = options_.huber_px;
  if (options_.huber_sigmas > 0.0 && robust_sigma_px_ > 0.0) {
    huber = std::min(
        huber, std::max(0.5 * options_.min_outlier_px, options_.huber_sigmas * robust_sigma_px_));
  }
  const BaIntrinsics k{K_.fx, K_.fy / K_.fx, K_.cx, K_.cy, K_.k1, K_.k2};
  int n_obs = 0;
  for (int c = 0; c < n_cams; ++c) {
    const int64_t seq = ba_kf_seq_[static_cast<std::size_t>(c)];
    const KeyframeObservation* obs = keyframeObservations(seq);
    const int count = keyframe(seq)->obs_count;
    for (int j = 0; j < count; ++j) {
      const int slot = ba_slot_of_point_[static_cast<std::size_t>(obs[j].point)];
      if (slot < 0) continue;
      Eigen::Vector2d uv;
      if (!BundleAdjuster::project(ba_cameras_[static_cast<std::size_t>(c)], k,
                                   ba_points_[static_cast<std::size_t>(slot)], uv))
        continue;
      if ((uv - obs[j].px).norm() > cut) continue;
      ba_obs_[static_cast<std::size_t>(n_obs++)] = {c, slot, obs[j].px};
    }
  }
  if (n_obs >= 20) {
    BundleAdjustmentOptions bo;
    bo.huber_px = huber;
    bo.max_iterations = options_.ba_iterations;
    BaIntrinsics kk = k;
    // With a rolling shutter the keyframes' motions join the adjustment (an empty span: the
    // global-shutter adjustment, bit for bit).
    const std::size_t n_motions = shutter_.line_delay > 0.0 ? static_cast<std::size_t>(n_cams) : 0;
    for (std::size_t c = 0; c < n_motions; ++c) ba_motions_[c] = keyframe(ba_kf_seq_[c])->motion;
    const auto summary = ba_.solve(
        std::span<BaCamera>(ba_cameras_.data(), static_cast<std::size_t>(n_cams)),
        std::span<const uint8_t>(ba_fixed_.data(), static_cast<std::size_t>(n_cams)),
        std::span<Eigen::Vector3d>(ba_points_.data(), static_cast<std::size_t>(n_pts)), {},
        std::span<const BaObservation>(ba_obs_.data(), static_cast<std::size_t>(n_obs)), kk, bo,
        shutter_, std::span<RollingShutterMotion>(ba_motions_.data(), n_motions));
    const bool ok = summary.status == BundleAdjustmentSummary::Status::kConverged ||
                    summary.status == BundleAdjustmentSummary::Status::kMaxIterations;
    if (ok && n_cams - n_free == 1) restoreScale(n_cams, n_pts);
    if (ok) {
      for (int c = 0; c < n_free; ++c) {
        const auto& cam = ba_cameras_[static_cast<std::size_t>(c)];
        if (cam.R_cw.allFinite() && cam.t_cw.allFinite())
          keyframe(ba_kf_seq_[static_cast<std::size_t>(c)])->pose = fromBa(cam);
        if (static_cast<std::size_t>(c) < n_motions) {
          const auto& m = ba_motions_[static_cast<std::size_t>(c)];
          if (m.angular.allFinite() && m.linear.allFinite())
            keyframe(ba_kf_seq_[static_cast<std::size_t>(c)])->motion = m;
        }
      }
      for (int s = 0; s < n_pts; ++s) {
        const auto& X = ba_points_[static_cast<std::size_t>(s)];
        if (X.allFinite())
          points_[static_cast<std::size_t>(ba_point_index_[static_cast<std::size_t>(s)])].X = X;
      }
    }
  }
  for (int s = 0; s < n_pts; ++s)
    ba_slot_of_point_[static_cast<std::size_t>(ba_point_index_[static_cast<std::size_t>(s)])] = -1;
}

}  // namespace epitrack

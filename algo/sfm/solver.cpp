#include "algo/sfm/solver.hpp"

#include <algorithm>
#include <cmath>
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
#include "algo/math/median.hpp"
#include "algo/sfm/ba_camera_pose.hpp"
#include "algo/sfm/bundle_adjustment.hpp"
#include "algo/sfm/reprojection.hpp"

namespace epitrack {

const char* toString(Solver::Status s) {
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
  }
  return "unknown";
}

const char* toString(UnsolvedCause c) {
  switch (c) {
    case UnsolvedCause::kNone:
      return "solved";
    case UnsolvedCause::kTracksLost:
      return "tracks-lost";
    case UnsolvedCause::kNotConnected:
      return "not-connected";
    case UnsolvedCause::kTooLittleParallax:
      return "too-little-parallax";
    case UnsolvedCause::kResectionFailed:
      return "resection-failed";
    case UnsolvedCause::kNoReconstruction:
      return "no-reconstruction";
  }
  return "unknown";
}

const char* describe(UnsolvedCause c) {
  switch (c) {
    case UnsolvedCause::kNone:
      return "solved";
    case UnsolvedCause::kTracksLost:
      return "tracks lost: too few tracked features for a pose, or under a quarter of a solved "
             "frame's (blank or blurred view, a cut)";
    case UnsolvedCause::kNotConnected:
      return "not connected: its tracks reach no solved frame";
    case UnsolvedCause::kTooLittleParallax:
      return "too little parallax: tracks shared with solved frames, too few of them became 3D "
             "points";
    case UnsolvedCause::kResectionFailed:
      return "resection failed: 3D points in view, but no pose fits enough of them";
    case UnsolvedCause::kNoReconstruction:
      return "no reconstruction: the solve failed before any frame was solved";
  }
  return "unknown";
}

std::vector<FrameRange> frameRanges(const std::vector<SolvedFrame>& frames) {
  std::vector<FrameRange> ranges;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const bool solved = frames[i].solved;
    const UnsolvedCause cause = solved ? UnsolvedCause::kNone : frames[i].unsolved;
    if (!ranges.empty() && ranges.back().solved == solved && ranges.back().cause == cause &&
        ranges.back().last + 1 == static_cast<int>(i)) {
      ranges.back().last = static_cast<int>(i);
      continue;
    }
    ranges.push_back({static_cast<int>(i), static_cast<int>(i), solved, cause});
  }
  return ranges;
}

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

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
  frames_.assign(static_cast<std::size_t>(tracks.frameCount()), SolvedFrame{});
  point_of_track_.assign(static_cast<std::size_t>(tracks.trackCount()), -1);
  points_.reserve(static_cast<std::size_t>(tracks.trackCount()));
}

Eigen::Vector2d Solver::normalized(const TrackObservation& o) const {
  Eigen::Vector2d d((o.x - cx_) / f_, (o.y - cy_) / (f_ * aspect_));
  if (k1_ == 0.0 && k2_ == 0.0) return d;
  // Invert x_d = x_u (1 + k1 r^2 + k2 r^4) by fixed-point iteration (converges for the mild
  // distortion of ordinary lenses).
  Eigen::Vector2d u = d;
  for (int i = 0; i < 10; ++i) {
    const double r2 = u.squaredNorm();
    u = d / (1.0 + k1_ * r2 + k2_ * r2 * r2);
  }
  return u;
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
    if (x1 != nullptr) x1->emplace_back(o.x, o.y);
    if (x2 != nullptr) x2->emplace_back(ob->x, ob->y);
  }
  return n;
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
    motion_ = "rotation-or-plane";

  if (options_.focal_px > 0.0) {
    f_ = options_.focal_px;
    focal_source_ = "given";
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
    focal_source_ = "self-calibrated";
    focal_observable_ = true;
  } else {
    f_ = options_.fallback_focal_widths * std::max(width_, height_);
    focal_source_ = "fallback";
    focal_observable_ = false;
    focal_fallback_ = "field-of-view";
    sweep_pending_ = options_.focal_sweep;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Focal profile: when F cannot observe the focal, the reprojection error of whole solves can.
// The paper's self-calibration (§5.2) uses pairs of views; an orbit whose optical axes meet in a
// point is critical for it, but over many views a 3D scene seen with the wrong focal does not
// fit: the median reprojection error of the whole solve has a minimum at the true focal
// (measured on the exact orbit: 0.03 px at 600 px against 0.12-0.45 px at 400-850 px).

FocalProfilePoint Solver::probeFocal(const TrackTable& tracks, double focal, bool refine) const {
  SolverOptions o = options_;
  o.focal_px = focal;
  o.refine_given_focal = refine;
  o.focal_sweep = false;
  Solver probe(tracks, width_, height_, o);
  FocalProfilePoint p;
  p.start_px = focal;
  p.focal_px = focal;
  p.refined = refine;
  // The calibration stage's checks passed on the whole clip and its pairs only serve the focal
  // and the motion class (general, or the sweep would not run): start at the initial pair.
  probe.f_ = focal;
  probe.focal_source_ = "given";
  probe.focal_observable_ = true;
  if (probe.initialize() && probe.registerFrames() && probe.finalize()) {
    p.solved_frames = probe.solvedFrames();
    p.median_reproj_px = probe.medianReprojectionAll();
    p.focal_px = probe.focal();
  }
  return p;
}

void Solver::sweepFocal() {
  sweep_pending_ = false;
  // The probes solve every k-th frame only (at most kProbeFrames frames): the profile is a
  // property of the scene and the motion, not of the frame rate, and the final solve refines
  // the focal on every frame.
  constexpr int kProbeFrames = 60;
  const int n = tracks_.frameCount();
  const int k_sub = std::max(1, (n + kProbeFrames - 1) / kProbeFrames);
  TrackTable sub;
  sub.reserve((n + k_sub - 1) / k_sub,
              tracks_.observations().size() / static_cast<std::size_t>(k_sub) + 1);
  for (int f = 0; f < n; f += k_sub)
    for (const auto& o : tracks_.frame(f)) sub.add(f / k_sub, tracks_.trackId(o.track), o.x, o.y);
  sub.setFrameCount((n + k_sub - 1) / k_sub);
  sub.finalize();
  const auto probeFocal = [&](double focal, bool refine) {
    return this->probeFocal(sub, focal, refine);
  };
  // 1. Basins: whole solves started from a 90 to an 18 degree horizontal field of view, a
  // factor 1.25 apart, each refining the focal in its final adjustment (a start in the basin of
  // the true focal ends there, however narrow the valley; a far start may end in another
  // solution, e.g. the depth-reversed one).
  const double base = std::max(width_, height_);
  double k = 0.5;
  for (int i = 0; i < 9; ++i, k *= 1.25) profile_.push_back(probeFocal(k * base, true));
  int most_solved = 0;
  for (const auto& p : profile_) most_solved = std::max(most_solved, p.solved_frames);
  if (most_solved == 0) return;  // nothing solves: keep the field-of-view fallback
  // Score: the median error, penalised for frames left unsolved (a wrong focal loses frames).
  const auto score = [&](const FocalProfilePoint& p) {
    if (p.solved_frames == 0) return std::numeric_limits<double>::infinity();
    const double r = static_cast<double>(most_solved) / static_cast<double>(p.solved_frames);
    return p.median_reproj_px * r * r;
  };
  const auto bestOf = [&](std::size_t from) {
    std::size_t b = from;
    for (std::size_t i = from; i < profile_.size(); ++i)
      if (score(profile_[i]) < score(profile_[b])) b = i;
    return b;
  };
  const std::size_t basin = bestOf(0);
  const double fb = profile_[basin].focal_px;
  // 2. The profile itself (focal held) around the basin's focal: a parabola in log(focal)
  // through 3 % steps, and the sharpness of the minimum at +-10 %.
  const std::size_t fine = profile_.size();
  constexpr double kFine = 0.03;
  profile_.push_back(probeFocal(fb * (1.0 - kFine), false));
  profile_.push_back(probeFocal(fb, false));
  profile_.push_back(probeFocal(fb * (1.0 + kFine), false));
  const double ym = score(profile_[fine]), y0 = score(profile_[fine + 1]),
               yp = score(profile_[fine + 2]);
  const double h = std::log1p(kFine);
  const double den = ym - 2.0 * y0 + yp;
  if (den > 0.0 && std::isfinite(den)) {
    const double dx = std::clamp(0.5 * h * (ym - yp) / den, -2.0 * h, 2.0 * h);
    profile_.push_back(probeFocal(fb * std::exp(dx), false));
  }
  const std::size_t best = bestOf(fine);
  f_ = profile_[best].focal_px;
  const FocalProfilePoint lo = probeFocal(f_ / 1.1, false);
  const FocalProfilePoint hi = probeFocal(f_ * 1.1, false);
  profile_.push_back(lo);
  profile_.push_back(hi);
  // Clear: 10 % either way costs at least 5 % of median error.
  const bool clear =
      score(lo) >= 1.05 * score(profile_[best]) && score(hi) >= 1.05 * score(profile_[best]);
  focal_fallback_ = clear ? "profile" : "profile-flat";
  refine_fallback_focal_ = clear;
}

double Solver::medianReprojectionAll() const {
  std::vector<double> e;
  for (int f = 0; f < tracks_.frameCount(); ++f) {
    const auto& fr = frames_[static_cast<std::size_t>(f)];
    if (!fr.solved) continue;
    for (const auto& o : tracks_.frame(f)) {
      const int p = point_of_track_[static_cast<std::size_t>(o.track)];
      if (p < 0 || !points_[static_cast<std::size_t>(p)].valid) continue;
      double error = 0.0;  // +inf behind the camera
      reprojectionErrorPx(fr.pose, points_[static_cast<std::size_t>(p)].X, normalized(o), f_,
                          error);
      e.push_back(error);
    }
  }
  return e.empty() ? std::numeric_limits<double>::infinity() : median(std::move(e));
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
    x1.emplace_back(o.x, o.y);
    x2.emplace_back(ob->x, ob->y);
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
  // Distortion is applied through `normalized`; E from F in pixels ignores it (refined below).
  const Eigen::Matrix3d E = essentialFromFundamental(f.F, K, K);
  RelativePoseResult rp;
  if (!recoverRelativePose(E, n1, n2, f.mask, rp)) return false;
  if (rp.second_best * 10 > rp.in_front * 7) return false;  // ambiguous cheirality
  PoseCw pose = rp.pose;
  refineRelativePose(n1, n2, f.mask, f_, pose);
  TriangulationOptions to;
  to.focal_px = f_;
  to.min_parallax_deg = options_.min_point_parallax_deg;
  to.max_reproj_px = options_.reproj_threshold_px;
  const PoseCw poses[2] = {PoseCw{}, pose};
  tracks.clear();
  X.clear();
  std::vector<double> parallax;
  for (std::size_t i = 0; i < n1.size(); ++i) {
    if (!f.mask[i]) continue;
    const Eigen::Vector2d obs[2] = {n1[i], n2[i]};
    const auto t = triangulatePoint(poses, obs, to);
    if (t.status != TriangulationStatus::kOk) continue;
    tracks.push_back(ids[i]);
    X.push_back(t.X);
    parallax.push_back(t.parallax_deg);
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

bool Solver::initialize() {
  const int n = tracks_.frameCount();
  // Homographies everywhere: a rotating camera if the homographies are rotations for one focal,
  // otherwise a plane or a distant scene. The rotation focal then seeds the search for an
  // initial pair (a distant scene with a short baseline still has parallax over longer gaps);
  // only when no pair has parallax is the clip solved as a tripod.
  bool rotation_coherent = false;
  double rotation_focal = 0.0;
  if (motion_ == "rotation-or-plane" && !homographies_.empty()) {
    std::vector<double> fs;
    for (const auto& H : homographies_) {
      const auto e = estimateFocalFromRotation(H, width_, height_);
      if (e.observable) fs.push_back(e.focal_px);
    }
    rotation_focal = median(fs);
    int coherent = 0;
    for (const double v : fs) coherent += std::abs(v / rotation_focal - 1.0) < 0.05 ? 1 : 0;
    const bool focal_fits =
        options_.focal_px <= 0.0 || std::abs(rotation_focal / options_.focal_px - 1.0) < 0.1;
    rotation_coherent = coherent * 2 > static_cast<int>(homographies_.size()) && focal_fits;
    if (rotation_coherent && options_.focal_px <= 0.0 && !focal_observable_) {
      f_ = rotation_focal;
      focal_source_ = "self-calibrated";
      focal_observable_ = true;
    }
  }
  // Homographies that are not rotations: a single plane (or a scene so distant it acts as one).
  // Any focal then explains the views equally well (paper §5.2 needs F), so a solve with a guessed
  // focal would be silently distorted: say so instead.
  if (motion_ == "rotation-or-plane" && !rotation_coherent && options_.focal_px <= 0.0 &&
      !focal_observable_) {
    status_ = Status::kPlanarScene;
    message_ =
        "the scene is a single plane (every frame pair fits a homography that is not a "
        "rotation): the focal length cannot be self-calibrated; give --focal or --intrinsics";
    return false;
  }
  if (sweep_pending_ && !focal_observable_) sweepFocal();
  // Candidate first frames spread over the first fifth of the clip, candidate partners at several
  // gaps measured by parallax (median displacement 10-40 % of the width).
  double best_score = 0.0;
  PoseCw best_pose;
  std::vector<int> best_tracks, tr;
  std::vector<Eigen::Vector3d> best_X, X;
  std::vector<Eigen::Vector2d> x1, x2;
  const int a_span = options_.keyframe_collection ? -1 : std::max(1, n / 5);
  const int a_step = std::max(1, a_span / 6);
  if (options_.keyframe_collection) {
    initialCandidatesAll([&](int a, int b) {
      double score = 0.0;
      PoseCw pose;
      if (tryPair(a, b, score, pose, tr, X) && score > best_score) {
        best_score = score;
        best_pose = pose;
        best_tracks = tr;
        best_X = X;
        init_a_ = a;
        init_b_ = b;
      }
    });
  }
  for (int a = 0; a < n && a <= a_span; a += a_step) {
    const double targets[] = {0.04, 0.08, 0.14, 0.24};
    int t = 0, last_tried = -1, widest = -1;
    double widest_d = 0.0;
    const auto consider = [&](int b) {
      last_tried = b;
      double score = 0.0;
      PoseCw pose;
      if (tryPair(a, b, score, pose, tr, X) && score > best_score) {
        best_score = score;
        best_pose = pose;
        best_tracks = tr;
        best_X = X;
        init_a_ = a;
        init_b_ = b;
      }
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
  if (best_score <= 0.0 && rotation_coherent) {
    tripodSolve();
    return false;
  }
  if (best_score <= 0.0) {
    status_ = motion_ == "rotation-or-plane" ? Status::kPlanarScene : Status::kInitFailed;
    message_ = status_ == Status::kPlanarScene
                   ? "the frames are related by homographies (a single plane without a given "
                     "focal, or no translation): no 3D reconstruction"
                   : "no pair of frames gave a valid two-view reconstruction";
    return false;
  }
  motion_ = "general";
  auto& fa = frames_[static_cast<std::size_t>(init_a_)];
  auto& fb = frames_[static_cast<std::size_t>(init_b_)];
  fa.solved = fb.solved = true;
  fa.pose = PoseCw{};
  fb.pose = best_pose;
  for (std::size_t i = 0; i < best_tracks.size(); ++i) {
    MapPoint p;
    p.X = best_X[i];
    p.track = best_tracks[i];
    p.valid = true;
    point_of_track_[static_cast<std::size_t>(p.track)] = static_cast<int>(points_.size());
    points_.push_back(p);
  }
  addKeyframe(init_a_);
  addKeyframe(init_b_);
  adjust(true);
  return true;
}

// ---------------------------------------------------------------------------------------------
// Stage 3: every frame by resection (paper §5.4), keyframes, new points, windowed adjustment.

bool Solver::registerFrame(int f, int min_inliers, double min_inlier_ratio) {
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> x;
  for (const auto& o : tracks_.frame(f)) {
    const int p = point_of_track_[static_cast<std::size_t>(o.track)];
    if (p < 0 || !points_[static_cast<std::size_t>(p)].valid) continue;
    X.push_back(points_[static_cast<std::size_t>(p)].X);
    x.push_back(normalized(o));
  }
  if (static_cast<int>(X.size()) < min_inliers) return false;
  PnpRansac pnp(static_cast<int>(X.size()));
  PnpOptions po;
  po.focal_px = f_;
  po.ransac.threshold = options_.reproj_threshold_px;
  po.ransac.seed = options_.seed + static_cast<uint64_t>(f);
  po.refine_options.huber_px = options_.huber_px;
  PnpResult r;
  if (pnp.estimate(X, x, po, r) != PnpRansac::Status::kOk) return false;
  if (r.inliers < min_inliers || r.inliers < min_inlier_ratio * static_cast<double>(X.size()))
    return false;
  if (robust_cut_px_ > 0.0) {
    // After a global adjustment: refine on the observations within its robust cut, with its
    // Huber threshold (the RANSAC threshold and the fixed Huber loss admit biased tracks).
    std::vector<uint8_t> keep(X.size(), 0);
    int kept = 0;
    for (std::size_t i = 0; i < X.size(); ++i) {
      double e = 0.0;
      if (reprojectionErrorPx(r.pose, X[i], x[i], f_, e) && e <= robust_cut_px_) {
        keep[i] = 1;
        ++kept;
      }
    }
    if (kept >= min_inliers) {
      PoseRefineOptions ro;
      ro.focal_px = f_;
      ro.huber_px = robust_huber_px_;
      refinePose(X, x, keep, ro, r.pose);
    }
  }
  auto& fr = frames_[static_cast<std::size_t>(f)];
  fr.solved = true;
  fr.pose = r.pose;
  fr.inliers = r.inliers;
  fr.rms_px = r.rms_px;
  return true;
}

bool Solver::shouldBeKeyframe(int f) const {
  if (keyframes_.empty()) return true;
  // The nearest keyframe in time (the pass may run backwards).
  int kf = keyframes_.front();
  for (const int k : keyframes_)
    if (std::abs(k - f) < std::abs(kf - f)) kf = k;
  if (std::abs(f - kf) >= options_.keyframe_max_gap) return true;
  const Eigen::Vector3d c1 = frames_[static_cast<std::size_t>(f)].pose.centre();
  const Eigen::Vector3d c0 = frames_[static_cast<std::size_t>(kf)].pose.centre();
  std::vector<double> angles;
  int seen_kf = 0, seen_both = 0;
  for (const auto& o : tracks_.frame(kf)) {
    const int p = point_of_track_[static_cast<std::size_t>(o.track)];
    if (p < 0 || !points_[static_cast<std::size_t>(p)].valid) continue;
    ++seen_kf;
    if (tracks_.find(o.track, f) == nullptr) continue;
    ++seen_both;
    const Eigen::Vector3d& X = points_[static_cast<std::size_t>(p)].X;
    const double c = (X - c0).normalized().dot((X - c1).normalized());
    angles.push_back(std::acos(std::clamp(c, -1.0, 1.0)) * kRadToDeg);
  }
  if (seen_both * 10 < seen_kf * 6) return true;  // the map is being lost: add points now
  return median(angles) >= options_.keyframe_parallax_deg;
}

void Solver::addKeyframe(int f) {
  frames_[static_cast<std::size_t>(f)].keyframe = true;
  keyframes_.push_back(f);
}

int Solver::triangulateNewTracks(int f) {
  TriangulationOptions to;
  to.focal_px = f_;
  to.min_parallax_deg = options_.min_point_parallax_deg;
  to.max_reproj_px = options_.reproj_threshold_px;
  std::vector<PoseCw> poses;
  std::vector<Eigen::Vector2d> obs;
  int added = 0;
  for (const auto& o : tracks_.frame(f)) {
    if (point_of_track_[static_cast<std::size_t>(o.track)] >= 0) continue;
    // Solved frames of the track, subsampled evenly (the extremes carry the parallax).
    const auto idx = tracks_.track(o.track);
    std::vector<int> solved;
    for (const int i : idx) {
      const auto& ob = tracks_.observations()[static_cast<std::size_t>(i)];
      if (frames_[static_cast<std::size_t>(ob.frame)].solved) solved.push_back(i);
    }
    if (solved.size() < 2) continue;
    poses.clear();
    obs.clear();
    const std::size_t m =
        std::min<std::size_t>(solved.size(), static_cast<std::size_t>(options_.max_track_views));
    for (std::size_t k = 0; k < m; ++k) {
      const std::size_t pick = m == 1 ? 0 : k * (solved.size() - 1) / (m - 1);
      const auto& ob = tracks_.observations()[static_cast<std::size_t>(solved[pick])];
      poses.push_back(frames_[static_cast<std::size_t>(ob.frame)].pose);
      obs.push_back(normalized(ob));
    }
    const auto t = triangulatePoint(poses, obs, to);
    if (t.status != TriangulationStatus::kOk) continue;
    MapPoint p;
    p.X = t.X;
    p.track = o.track;
    p.valid = true;
    point_of_track_[static_cast<std::size_t>(o.track)] = static_cast<int>(points_.size());
    points_.push_back(p);
    ++added;
  }
  return added;
}

void Solver::adjust(bool global) {
  // Cameras: keyframes (the window, or all), plus fixed keyframes that see the window's points.
  // A global adjustment also takes the final adjustment's extra cameras (final_cameras_).
  std::vector<int> frames_in = keyframes_;
  if (global) frames_in.insert(frames_in.end(), final_cameras_.begin(), final_cameras_.end());
  std::vector<int> free_kf;
  if (global) {
    free_kf = frames_in;
  } else {
    std::vector<int> sorted = keyframes_;
    const std::size_t w =
        std::min<std::size_t>(sorted.size(), static_cast<std::size_t>(options_.ba_window));
    free_kf.assign(keyframes_.end() - static_cast<std::ptrdiff_t>(w), keyframes_.end());
  }
  std::vector<int> cam_of_frame(frames_.size(), -1);
  std::vector<BaCamera> cams;
  std::vector<uint8_t> cam_fixed;
  std::vector<int> cam_frame;
  for (const int f : free_kf) {
    cam_of_frame[static_cast<std::size_t>(f)] = static_cast<int>(cams.size());
    cams.push_back(toBa(frames_[static_cast<std::size_t>(f)].pose));
    cam_fixed.push_back(0);
    cam_frame.push_back(f);
  }
  // Points seen by the free cameras.
  std::vector<int> point_slot(points_.size(), -1);
  std::vector<Eigen::Vector3d> pts;
  std::vector<int> pt_index;
  for (const int f : free_kf) {
    for (const auto& o : tracks_.frame(f)) {
      const int p = point_of_track_[static_cast<std::size_t>(o.track)];
      if (p < 0 || !points_[static_cast<std::size_t>(p)].valid ||
          point_slot[static_cast<std::size_t>(p)] >= 0)
        continue;
      point_slot[static_cast<std::size_t>(p)] = static_cast<int>(pts.size());
      pts.push_back(points_[static_cast<std::size_t>(p)].X);
      pt_index.push_back(p);
    }
  }
  // Observations in every keyframe (fixed keyframes join as fixed cameras); residuals far beyond
  // the inlier threshold are left out (a robust sigma cut was tried and made the orbit worse: the
  // Huber loss already bounds their influence).
  struct Candidate {
    int camera, point;
    Eigen::Vector2d xy;
    double residual;
  };
  std::vector<Candidate> candidates;
  for (const int f : frames_in) {
    for (const auto& o : tracks_.frame(f)) {
      const int p = point_of_track_[static_cast<std::size_t>(o.track)];
      if (p < 0 || point_slot[static_cast<std::size_t>(p)] < 0) continue;
      double e = 0.0;
      if (!reprojectionErrorPx(frames_[static_cast<std::size_t>(f)].pose,
                               points_[static_cast<std::size_t>(p)].X, normalized(o), f_, e))
        continue;
      int c = cam_of_frame[static_cast<std::size_t>(f)];
      if (c < 0) {
        c = static_cast<int>(cams.size());
        cam_of_frame[static_cast<std::size_t>(f)] = c;
        cams.push_back(toBa(frames_[static_cast<std::size_t>(f)].pose));
        cam_fixed.push_back(1);
        cam_frame.push_back(f);
      }
      candidates.push_back(
          {c, point_slot[static_cast<std::size_t>(p)], Eigen::Vector2d(o.x, o.y), e});
    }
  }
  double cut = 4.0 * options_.reproj_threshold_px;
  double huber = options_.huber_px;
  if (global && candidates.size() >= 50 && options_.outlier_sigmas > 0.0) {
    // Robust scale of this clip's residuals (Rayleigh: median |e| = 1.1774 sigma). Windowed
    // adjustments keep the fixed cut: a young map's residuals are not yet representative.
    std::vector<double> e(candidates.size());
    for (std::size_t i = 0; i < candidates.size(); ++i) e[i] = candidates[i].residual;
    const double sigma = median(std::move(e)) / kRayleighMedianPerSigma;
    cut = std::min(cut, std::max(options_.min_outlier_px, options_.outlier_sigmas * sigma));
    if (options_.huber_sigmas > 0.0)
      huber = std::min(options_.huber_px,
                       std::max(0.5 * options_.min_outlier_px, options_.huber_sigmas * sigma));
    robust_cut_px_ = cut;
    robust_huber_px_ = huber;
  }
  std::vector<BaObservation> obs;
  for (const auto& c : candidates)
    if (c.residual <= cut) obs.push_back({c.camera, c.point, c.xy});
  // Gauge: the oldest keyframe fixed; with all free (global), fix the initial pair's first frame.
  bool any_fixed = false;
  for (const auto v : cam_fixed) any_fixed = any_fixed || v != 0;
  if (!any_fixed && !cams.empty()) {
    int c0 = 0;
    for (std::size_t c = 0; c < cam_frame.size(); ++c)
      if (cam_frame[c] == init_a_) c0 = static_cast<int>(c);
    cam_fixed[static_cast<std::size_t>(c0)] = 1;
  }
  if (obs.size() < 20) return;
  BundleAdjuster ba(static_cast<int>(cams.size()), static_cast<int>(pts.size()),
                    static_cast<int>(obs.size()));
  BundleAdjustmentOptions bo;
  bo.huber_px = huber;
  bo.max_iterations = global ? 30 : 8;
  // Global adjustments stop once a step lowers the cost by less than a millionth: on the
  // 340-frame orbit the figures are equal to 5 digits and the final adjustments take 0.28 s
  // instead of 0.59 (the default 1e-10 ran all 30 iterations).
  if (global) bo.function_tolerance = 1e-6;
  bo.refine_focal = global && ((focal_source_ == "self-calibrated") ||
                               (focal_source_ == "given" && options_.refine_given_focal) ||
                               (focal_source_ == "fallback" && refine_fallback_focal_));
  bo.refine_distortion = global ? options_.refine_distortion : 0;
  BaIntrinsics k{f_, aspect_, cx_, cy_, k1_, k2_};
  ba.solve(cams, cam_fixed, pts, {}, obs, k, bo);
  if (!std::isfinite(k.f) || k.f <= 0.0) return;
  f_ = k.f;
  k1_ = k.k1;
  k2_ = k.k2;
  for (std::size_t c = 0; c < cams.size(); ++c)
    if (!cam_fixed[c]) frames_[static_cast<std::size_t>(cam_frame[c])].pose = fromBa(cams[c]);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (pts[i].allFinite()) points_[static_cast<std::size_t>(pt_index[i])].X = pts[i];
  }
}

bool Solver::registerFrames() {
  if (tripod_) return true;
  if (options_.keyframe_collection) return registerBestViews();
  const int n = tracks_.frameCount();
  auto step = [&](int f) {
    if (frames_[static_cast<std::size_t>(f)].solved) return;
    if (!registerFrame(f)) return;
    if (shouldBeKeyframe(f)) {
      addKeyframe(f);
      triangulateNewTracks(f);
      adjust(false);
    }
  };
  // Forward from the initial pair, then backward from it.
  for (int f = init_a_ + 1; f < n; ++f) {
    if (f == init_b_) {
      triangulateNewTracks(f);
      continue;
    }
    step(f);
  }
  for (int f = init_a_ - 1; f >= 0; --f) step(f);
  return true;
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
  adjust(true);
  adjust(true);
  if (options_.refine_distortion > 0) adjust(true);  // distortion changes the normalized points
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
  return solvedFrames() > 0;
}

// ---------------------------------------------------------------------------------------------
// Coverage: why each unsolved frame is unsolved, and whether the solve may be called ok.

void Solver::assessCoverage() {
  const int n = tracks_.frameCount();
  const int solved = solvedFrames();
  // Tracks seen in at least one solved frame: what links a frame to the reconstruction.
  std::vector<uint8_t> seen_solved(static_cast<std::size_t>(tracks_.trackCount()), 0);
  for (int f = 0; f < n; ++f) {
    if (!frames_[static_cast<std::size_t>(f)].solved) continue;
    for (const auto& o : tracks_.frame(f)) seen_solved[static_cast<std::size_t>(o.track)] = 1;
  }
  // Points a pose needs: PnP's minimum (registerFrame), or the tripod's homography minimum.
  const int need = tripod_ ? 8 : options_.keyframe_collection ? options_.keyframe_min_inliers : 12;
  // A frame that keeps less than a quarter of a solved frame's usual tracks has lost them, even
  // when a few remain (tracks coasting onto a blank wall for a few frames).
  std::vector<double> solved_features;
  for (int f = 0; f < n; ++f)
    if (frames_[static_cast<std::size_t>(f)].solved)
      solved_features.push_back(static_cast<double>(tracks_.frame(f).size()));
  const double lost_below = 0.25 * median(std::move(solved_features));
  for (int f = 0; f < n; ++f) {
    auto& fr = frames_[static_cast<std::size_t>(f)];
    if (fr.solved) {
      fr.unsolved = UnsolvedCause::kNone;
      continue;
    }
    if (solved == 0) {
      fr.unsolved = UnsolvedCause::kNoReconstruction;
      continue;
    }
    const int features = static_cast<int>(tracks_.frame(f).size());
    int connected = 0, mapped = 0;
    for (const auto& o : tracks_.frame(f)) {
      connected += seen_solved[static_cast<std::size_t>(o.track)];
      const int p = point_of_track_[static_cast<std::size_t>(o.track)];
      mapped += p >= 0 && points_[static_cast<std::size_t>(p)].valid ? 1 : 0;
    }
    if (features < need || features < lost_below)
      fr.unsolved = UnsolvedCause::kTracksLost;
    else if (connected < need)
      fr.unsolved = UnsolvedCause::kNotConnected;
    else if (tripod_ || mapped >= need)
      fr.unsolved = UnsolvedCause::kResectionFailed;
    else
      fr.unsolved = UnsolvedCause::kTooLittleParallax;
  }
  if (status_ != Status::kOk && status_ != Status::kRotationOnly) return;
  if (n == 0 || static_cast<double>(solved) >= options_.min_solved_fraction * n) return;
  // Partial: name the unsolved ranges, the longest first (a key-frame set can have many).
  std::vector<FrameRange> gaps;
  for (const auto& r : frameRanges(frames_))
    if (!r.solved) gaps.push_back(r);
  std::stable_sort(gaps.begin(), gaps.end(), [](const FrameRange& a, const FrameRange& b) {
    return a.last - a.first > b.last - b.first;
  });
  constexpr std::size_t kNamed = 6;
  std::string text = (tripod_ ? "tripod solve (rotation only), " : "") + std::to_string(solved) +
                     " of " + std::to_string(n) +
                     (options_.keyframe_collection ? " views registered" : " frames solved") +
                     "; unsolved:";
  for (std::size_t i = 0; i < gaps.size() && i < kNamed; ++i) {
    const auto& g = gaps[i];
    text += (i == 0 ? " " : "; ") + std::to_string(g.first) +
            (g.last > g.first ? "-" + std::to_string(g.last) : std::string()) + " (" +
            describe(g.cause) + ")";
  }
  if (gaps.size() > kNamed)
    text += "; and " + std::to_string(gaps.size() - kNamed) + " more unsolved ranges";
  status_ = Status::kPartial;
  message_ = text;
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

// ---------------------------------------------------------------------------------------------
// Tripod solve: a rotating camera (Hartley 1997): focal from the rotation homographies, each
// frame's rotation from its homography to a reference frame, every centre at the origin.

bool Solver::tripodSolve() {
  const int n = tracks_.frameCount();
  if (options_.focal_px > 0.0) {
    f_ = options_.focal_px;
  } else {
    std::vector<double> fs;
    for (const auto& H : homographies_) {
      const auto e = estimateFocalFromRotation(H, width_, height_);
      if (e.observable) fs.push_back(e.focal_px);
    }
    if (fs.empty()) return false;
    f_ = median(fs);
    focal_source_ = "self-calibrated";
    focal_observable_ = true;
  }
  Eigen::Matrix3d K;
  K << f_, 0, cx_, 0, f_ * aspect_, cy_, 0, 0, 1;
  const Eigen::Matrix3d Kinv = K.inverse();
  int max_obs = 0;
  for (int f = 0; f < n; ++f)
    max_obs = std::max(max_obs, static_cast<int>(tracks_.frame(f).size()));
  HomographyRansac hr(std::max(8, max_obs));
  std::vector<Eigen::Vector2d> x1, x2;
  int ref = 0;
  Eigen::Matrix3d R_ref = Eigen::Matrix3d::Identity();  // R_cw of the reference frame
  frames_[0].solved = tracks_.frame(0).size() >= 8;
  int solved = 0;
  for (int f = 0; f < n; ++f) {
    if (f == ref) {
      frames_[static_cast<std::size_t>(f)].solved = true;
      frames_[static_cast<std::size_t>(f)].pose.R_cw = R_ref;
      ++solved;
      continue;
    }
    if (commonTracks(ref, f, &x1, &x2) < 20) {
      // Re-anchor on the previous solved frame.
      if (f - 1 != ref && frames_[static_cast<std::size_t>(f - 1)].solved) {
        ref = f - 1;
        R_ref = frames_[static_cast<std::size_t>(ref)].pose.R_cw;
        commonTracks(ref, f, &x1, &x2);
      }
      if (x1.size() < 8) continue;
    }
    HomographyResult h;
    if (hr.estimate(x1, x2, {}, h) != HomographyRansac::Status::kOk) continue;
    // x_f ~ K R_f R_ref^T K^-1 x_ref.
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(Kinv * h.H * K,
                                          Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
    if (R.determinant() < 0) R = -R;
    auto& fr = frames_[static_cast<std::size_t>(f)];
    fr.solved = true;
    fr.pose.R_cw = R * R_ref;
    fr.pose.t_cw.setZero();
    fr.rms_px = h.rms_transfer_px;
    fr.inliers = h.inliers;
    ++solved;
  }
  tripod_ = true;
  motion_ = "rotation-only";
  status_ = Status::kRotationOnly;
  message_ = "the camera only rotates (tripod): rotation and focal solved, depth unknown";
  assessCoverage();
  return solved > 0;
}

// ---------------------------------------------------------------------------------------------
// Key frames (SolverOptions::keyframe_collection): initial pair over the whole clip, next best
// view registration.

void Solver::initialCandidatesAll(const std::function<void(int, int)>& consider) const {
  // Every frame with each of its next keyframe_pair_gap frames that shares 30 tracks with it.
  const int n = tracks_.frameCount();
  for (int a = 0; a + 1 < n; ++a) {
    for (int b = a + 1; b < n && b <= a + options_.keyframe_pair_gap; ++b) {
      if (commonTracks(a, b, nullptr, nullptr) < 30) continue;
      consider(a, b);
    }
  }
}

bool Solver::registerByRelativePose(int f, int reference) {
  // Correspondences between the solved reference and f.
  std::vector<Eigen::Vector2d> n_ref, n_f;
  for (const auto& o : tracks_.frame(reference)) {
    const TrackObservation* of = tracks_.find(o.track, f);
    if (of == nullptr) continue;
    n_ref.push_back(normalized(o));
    n_f.push_back(normalized(*of));
  }
  if (static_cast<int>(n_ref.size()) < options_.keyframe_min_pair_inliers) return false;
  EssentialRansac er(static_cast<int>(n_ref.size()));
  EssentialRansacOptions eo;
  eo.ransac.threshold = options_.reproj_threshold_px;
  eo.ransac.seed = options_.seed + 7919u * static_cast<uint64_t>(f);
  eo.focal_px = f_;
  EssentialRansacResult e;
  if (er.estimate(n_ref, n_f, eo, e) != EssentialRansac::Status::kOk ||
      e.inliers < options_.keyframe_min_pair_inliers ||
      2 * e.inliers < static_cast<int>(n_ref.size()))
    return false;
  const std::vector<uint8_t> mask(e.mask.begin(), e.mask.end());
  RelativePoseResult rp;
  if (!recoverRelativePose(e.E, n_ref, n_f, mask, rp)) return false;
  if (rp.second_best * 10 > rp.in_front * 7) return false;  // ambiguous cheirality
  PoseCw rel = rp.pose;
  refineRelativePose(n_ref, n_f, mask, f_, rel);
  // Pose of f: R = R_rel R_ref, t = R_rel t_ref + lambda t_rel; lambda from the map points f sees.
  const PoseCw& ref = frames_[static_cast<std::size_t>(reference)].pose;
  PoseCw pose;
  pose.R_cw = rel.R_cw * ref.R_cw;
  const Eigen::Vector3d t0 = rel.R_cw * ref.t_cw;
  const Eigen::Vector3d b = rel.t_cw.normalized();
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> x;
  std::vector<double> lambdas;
  for (const auto& o : tracks_.frame(f)) {
    const int p = point_of_track_[static_cast<std::size_t>(o.track)];
    if (p < 0 || !points_[static_cast<std::size_t>(p)].valid) continue;
    const Eigen::Vector3d A = pose.R_cw * points_[static_cast<std::size_t>(p)].X + t0;
    const Eigen::Vector3d u = normalized(o).homogeneous();
    // (A + lambda b) parallel to u: lambda minimises |A x u + lambda (b x u)|.
    const Eigen::Vector3d bu = b.cross(u), au = A.cross(u);
    const double den = bu.squaredNorm();
    if (!(den > 1e-12)) continue;
    X.push_back(points_[static_cast<std::size_t>(p)].X);
    x.push_back(normalized(o));
    lambdas.push_back(-au.dot(bu) / den);
  }
  if (static_cast<int>(X.size()) < options_.keyframe_min_scale_points) return false;
  const double t_px = options_.reproj_threshold_px;
  const auto inliersFor = [&](const PoseCw& candidate, std::vector<uint8_t>* keep) {
    int n = 0;
    for (std::size_t i = 0; i < X.size(); ++i) {
      double error = 0.0;
      const bool in = reprojectionErrorPx(candidate, X[i], x[i], f_, error) && error <= t_px;
      n += in ? 1 : 0;
      if (keep != nullptr) (*keep)[i] = in ? 1 : 0;
    }
    return n;
  };
  // Every point's lambda as a hypothesis; the one most points agree with wins (a 1-D RANSAC).
  int best_n = 0;
  double best_lambda = 0.0;
  for (const double l : lambdas) {
    if (!(l > 0.0)) continue;  // the camera moves along +t_rel (cheirality of E)
    PoseCw c = pose;
    c.t_cw = t0 + l * b;
    const int n = inliersFor(c, nullptr);
    if (n > best_n) {
      best_n = n;
      best_lambda = l;
    }
  }
  if (best_n < options_.keyframe_min_scale_points) return false;
  pose.t_cw = t0 + best_lambda * b;
  // Least-squares lambda over the agreeing points (the rotation stays E's: it rests on many more
  // correspondences than the handful of points that fix the distance).
  std::vector<uint8_t> keep(X.size(), 0);
  inliersFor(pose, &keep);
  double num = 0.0, den = 0.0;
  for (std::size_t i = 0; i < X.size(); ++i) {
    if (!keep[i]) continue;
    const Eigen::Vector3d A = pose.R_cw * X[i] + t0;
    const Eigen::Vector3d u = x[i].homogeneous();
    const Eigen::Vector3d bu = b.cross(u), au = A.cross(u);
    num -= au.dot(bu);
    den += bu.squaredNorm();
  }
  if (den > 0.0 && num / den > 0.0) {
    PoseCw c = pose;
    c.t_cw = t0 + (num / den) * b;
    if (inliersFor(c, nullptr) >= best_n) pose = c;
  }
  const PoseCw refined = pose;
  const int n = inliersFor(refined, nullptr);
  if (n < options_.keyframe_min_scale_points ||
      n < options_.keyframe_min_inlier_ratio * static_cast<double>(X.size()))
    return false;
  auto& fr = frames_[static_cast<std::size_t>(f)];
  fr.solved = true;
  fr.pose = refined;
  fr.inliers = n;
  fr.rms_px = 0.0;
  return true;
}

bool Solver::registerBestViews() {
  const int n = tracks_.frameCount();
  triangulateNewTracks(init_b_);
  // Map points each frame sees when it was last tried (a failed frame is tried again only when
  // the map it sees has grown by a quarter, so the loop ends); the solved count when its
  // relative pose was last tried.
  std::vector<int> tried_at(static_cast<std::size_t>(n), -1);
  std::vector<int> relative_tried_at(static_cast<std::size_t>(n), -1);
  const auto visible = [&](int f) {
    int c = 0;
    for (const auto& o : tracks_.frame(f)) {
      const int p = point_of_track_[static_cast<std::size_t>(o.track)];
      c += p >= 0 && points_[static_cast<std::size_t>(p)].valid ? 1 : 0;
    }
    return c;
  };
  int accepted = 0;
  const auto accept = [&](int f) {
    addKeyframe(f);
    triangulateNewTracks(f);
    // Short tracks chain the views weakly: a global adjustment every few frames keeps the early
    // ones from being frozen with their first (least constrained) poses.
    const int every = options_.keyframe_global_every;
    adjust(every > 0 && ++accepted % every == 0);
  };
  for (;;) {
    int best = -1, best_count = 0;
    for (int f = 0; f < n; ++f) {
      if (frames_[static_cast<std::size_t>(f)].solved) continue;
      const int c = visible(f);
      if (c < options_.keyframe_min_inliers) continue;
      if (tried_at[static_cast<std::size_t>(f)] >= 0 &&
          c * 4 < tried_at[static_cast<std::size_t>(f)] * 5)
        continue;
      if (c > best_count) {
        best_count = c;
        best = f;
      }
    }
    if (best >= 0) {
      tried_at[static_cast<std::size_t>(best)] = best_count;
      const bool reg =
          registerFrame(best, options_.keyframe_min_inliers, options_.keyframe_min_inlier_ratio);
      if (reg) accept(best);
      continue;
    }
    if (!options_.keyframe_relative_pose) break;
    // No frame left for PnP: the unsolved frame sharing most tracks with a solved one, from its
    // relative pose to that frame.
    const int solved = solvedFrames();
    int rel = -1, rel_ref = -1, rel_common = 0;
    for (int f = 0; f < n; ++f) {
      if (frames_[static_cast<std::size_t>(f)].solved ||
          relative_tried_at[static_cast<std::size_t>(f)] == solved)
        continue;
      for (int r = 0; r < n; ++r) {
        if (!frames_[static_cast<std::size_t>(r)].solved) continue;
        const int c = commonTracks(r, f, nullptr, nullptr);
        if (c > rel_common) {
          rel_common = c;
          rel = f;
          rel_ref = r;
        }
      }
    }
    if (rel < 0 || rel_common < options_.keyframe_min_pair_inliers) break;
    relative_tried_at[static_cast<std::size_t>(rel)] = solved;
    const bool ok = registerByRelativePose(rel, rel_ref);
    if (ok) accept(rel);
  }
  return true;
}

}  // namespace epitrack

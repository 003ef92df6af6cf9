// Solver, stage 3: every frame by resection, keyframes, new points, windowed bundle adjustment.
#include "algo/sfm/solver.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "algo/geometry/pnp.hpp"
#include "algo/geometry/triangulation.hpp"
#include "algo/math/median.hpp"
#include "algo/sfm/ba_camera_pose.hpp"
#include "algo/sfm/bundle_adjustment.hpp"
#include "algo/sfm/reprojection.hpp"

namespace epitrack {

namespace {
constexpr double kRadToDeg = 180.0 / M_PI;
}  // namespace

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
  return upperMedian(angles) >= options_.keyframe_parallax_deg;
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

void Solver::adjust(bool global, bool measure_centres) {
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
    const double sigma = upperMedian(e) / kRayleighMedianPerSigma;
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
  if (global) bo.function_tolerance = options_.final_function_tolerance;
  bo.refine_focal =
      global && ((focal_source_ == FocalSource::kSelfCalibrated) ||
                 (focal_source_ == FocalSource::kGiven && options_.refine_given_focal) ||
                 (focal_source_ == FocalSource::kFallback && refine_fallback_focal_));
  bo.refine_distortion = global ? distortion_terms_ : 0;
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
  if (global && measure_centres) {
    std::vector<double> sd(cams.size(), 0.0);
    if (ba.centreStandardDeviations(cams, cam_fixed, pts, {}, obs, k, bo, sd))
      for (std::size_t c = 0; c < cams.size(); ++c)
        frames_[static_cast<std::size_t>(cam_frame[c])].centre_sd = sd[c];
  }
}

bool Solver::registerFrames() {
  if (tripod_) return true;
  if (options_.keyframe_collection) {
    registerBestViews();
    if (options_.keyframe_lens_reregistration && distortion_terms_ > 0 && options_.k1 == 0.0 &&
        options_.k2 == 0.0)
      reregisterWithLens();
    return true;
  }
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

}  // namespace epitrack

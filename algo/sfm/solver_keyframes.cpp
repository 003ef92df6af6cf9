// Solver: the key-frame mode (SolverOptions::keyframe_collection).
#include "algo/sfm/solver.hpp"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <vector>

#include "algo/geometry/determined_relative_pose.hpp"
#include "algo/geometry/essential.hpp"
#include "algo/geometry/essential_five_point.hpp"
#include "algo/sfm/reprojection.hpp"

namespace epitrack {

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
  normalizedMatches(reference, f, n_ref, n_f);
  if (static_cast<int>(n_ref.size()) < options_.keyframe_min_pair_inliers) return false;
  EssentialRansacOptions eo;
  eo.ransac.threshold = options_.reproj_threshold_px;
  eo.ransac.seed = options_.seed + 7919u * static_cast<uint64_t>(f);
  eo.focal_px = f_;
  // The pose must be one the matches determine (algo/geometry/determined_relative_pose.hpp):
  // a rotation that moves with the RANSAC seed is left for PnP.
  RelativePoseHypothesis e;
  if (!relativePoseOverSeeds(n_ref, n_f, eo, options_.keyframe_relative_pose_trials, e) ||
      e.rotation_spread_deg > options_.keyframe_max_rotation_spread_deg ||
      e.inliers < options_.keyframe_min_pair_inliers ||
      2 * e.inliers < static_cast<int>(n_ref.size()))
    return false;
  if (e.relative.second_best * 10 > e.relative.in_front * 7) return false;  // ambiguous cheirality
  PoseCw rel = e.relative.pose;
  refineRelativePose(n_ref, n_f, e.mask, f_, rel);
  PoseCw pose;
  int seen = 0;
  const int n = placeFromRelativePose(f, reference, rel, pose, seen);
  if (n < options_.keyframe_min_scale_points ||
      n < options_.keyframe_min_inlier_ratio * static_cast<double>(seen))
    return false;
  auto& fr = frames_[static_cast<std::size_t>(f)];
  fr.solved = true;
  fr.pose = pose;
  fr.inliers = n;
  fr.rms_px = 0.0;
  return true;
}

// Frame f placed from its relative pose `rel` to the solved `reference`: rotation and direction
// of travel from `rel`, the distance from the map points f sees. The map points that agree, -1
// when too few do; `seen`: the map points f sees.
int Solver::placeFromRelativePose(int f, int reference, const PoseCw& rel, PoseCw& placed,
                                  int& seen) const {
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
  seen = static_cast<int>(X.size());
  if (seen < options_.keyframe_min_scale_points) return -1;
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
  if (best_n < options_.keyframe_min_scale_points) return -1;
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
  placed = pose;
  return inliersFor(pose, nullptr);
}

// Every pair of solved views with enough matches, checked against its own images: the solve's
// relative pose E_s = [t]x R must explain about as many of the pair's matches (Sampson distance
// within the RANSAC threshold) as the best E the matches alone give. A registration gone wrong
// (a PnP chain on a plain surface, a relative pose E-RANSAC settled wrongly) leaves the poses on
// either side of it explaining half of their matches or less, while the reprojection errors of
// the map points it kept look fine: the points that disagreed were never triangulated.
void Solver::normalizedMatches(int a, int b, std::vector<Eigen::Vector2d>& n_a,
                               std::vector<Eigen::Vector2d>& n_b) const {
  n_a.clear();
  n_b.clear();
  for (const auto& o : tracks_.frame(a)) {
    const TrackObservation* ob = tracks_.find(o.track, b);
    if (ob == nullptr) continue;
    n_a.push_back(normalized(o));
    n_b.push_back(normalized(*ob));
  }
}

void Solver::checkViewPairs() {
  view_pairs_checked_ = -1;
  contradicted_pairs_.clear();
  const int min_inliers = options_.keyframe_pair_check_min_inliers;
  if (min_inliers <= 0) return;
  view_pairs_checked_ = 0;
  const int n = tracks_.frameCount();
  std::vector<Eigen::Vector2d> n_a, n_b;
  const double threshold = options_.reproj_threshold_px / f_;
  for (int a = 0; a < n; ++a) {
    if (!frames_[static_cast<std::size_t>(a)].solved) continue;
    for (int b = a + 1; b < n; ++b) {
      if (!frames_[static_cast<std::size_t>(b)].solved) continue;
      normalizedMatches(a, b, n_a, n_b);
      if (static_cast<int>(n_a.size()) < min_inliers) continue;
      EssentialRansacOptions eo;
      eo.ransac.threshold = options_.reproj_threshold_px;
      eo.ransac.seed = options_.seed + 7919u * static_cast<uint64_t>(a * n + b);
      eo.focal_px = f_;
      RelativePoseHypothesis best;
      if (!relativePoseOverSeeds(n_a, n_b, eo, 1, best) || best.inliers < min_inliers) continue;
      // The solve's relative pose a -> b: x_b = R x_a + t.
      const PoseCw& pa = frames_[static_cast<std::size_t>(a)].pose;
      const PoseCw& pb = frames_[static_cast<std::size_t>(b)].pose;
      const Eigen::Matrix3d R = pb.R_cw * pa.R_cw.transpose();
      const Eigen::Vector3d t = pb.t_cw - R * pa.t_cw;
      if (!(t.norm() > 0.0)) continue;  // no baseline: E is undefined
      const Eigen::Matrix3d E = skewSymmetric(t.normalized()) * R;
      int explained = 0;
      for (std::size_t i = 0; i < n_a.size(); ++i)
        explained += essentialSampsonSquared(E, n_a[i], n_b[i]) <= threshold * threshold ? 1 : 0;
      ++view_pairs_checked_;
      if (explained >= options_.keyframe_pair_min_support * best.inliers) continue;
      ViewPairContradiction c;
      c.a = a;
      c.b = b;
      c.matches = static_cast<int>(n_a.size());
      c.best_inliers = best.inliers;
      c.solve_inliers = explained;
      contradicted_pairs_.push_back(c);
    }
  }
  // Worst first: the smallest share of the best pose's inliers.
  std::stable_sort(contradicted_pairs_.begin(), contradicted_pairs_.end(),
                   [](const ViewPairContradiction& x, const ViewPairContradiction& y) {
                     return static_cast<int64_t>(x.solve_inliers) * y.best_inliers <
                            static_cast<int64_t>(y.solve_inliers) * x.best_inliers;
                   });
  if (status_ != Status::kOk || contradicted_pairs_.empty()) return;  // partial etc. stand
  const ViewPairContradiction& worst = contradicted_pairs_.front();
  char text[320];
  std::snprintf(text, sizeof(text),
                "%zu of %d pairs of registered views are contradicted by their own matches "
                "(worst: views %d-%d, whose relative pose in the solve explains %d of the %d "
                "matches the pair's own relative pose explains): the poses near them are likely "
                "wrong; summary.json view_pair_check names every pair",
                contradicted_pairs_.size(), view_pairs_checked_, worst.a, worst.b,
                worst.solve_inliers, worst.best_inliers);
  status_ = Status::kInconsistent;
  message_ = text;
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
  int accepted = 0, retry_rounds = 0;
  const auto accept = [&](int f) {
    addKeyframe(f);
    triangulateNewTracks(f);
    // Short tracks chain the views weakly: a global adjustment every few frames keeps the early
    // ones from being frozen with their first (least constrained) poses.
    const int every = options_.keyframe_global_every;
    adjustTryingDistortion(every > 0 && ++accepted % every == 0);
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
    if (rel < 0 || rel_common < options_.keyframe_min_pair_inliers) {
      // Nothing left to try on this map: a global adjustment and every solved view's tracks
      // triangulated again (points refused while their views' poses were young), then every
      // unregistered view is tried once more; at most keyframe_retry_rounds times, and only
      // when the map grew.
      if (retry_rounds >= options_.keyframe_retry_rounds) break;
      ++retry_rounds;
      adjustTryingDistortion(true);
      int added = 0;
      for (int f = 0; f < n; ++f)
        if (frames_[static_cast<std::size_t>(f)].solved) added += triangulateNewTracks(f);
      if (added == 0) break;
      std::fill(tried_at.begin(), tried_at.end(), -1);
      std::fill(relative_tried_at.begin(), relative_tried_at.end(), -1);
      continue;
    }
    relative_tried_at[static_cast<std::size_t>(rel)] = solved;
    const bool ok = registerByRelativePose(rel, rel_ref);
    if (ok) accept(rel);
  }
  return true;
}

}  // namespace epitrack

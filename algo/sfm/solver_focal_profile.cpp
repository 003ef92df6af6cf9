// Solver: the focal profile (SolverOptions::focal_sweep) when F does not observe the focal.
#include "algo/sfm/solver.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <vector>

#include "algo/math/median.hpp"
#include "algo/sfm/reprojection.hpp"

namespace epitrack {
namespace {

// The refined solves of the profile's first step that must end on one focal for it to count as
// observed (of nine), and how close (relative).
constexpr int kMinConvergedBasins = 5;
constexpr double kConvergedSpread = 0.01;
// The converged solves must include starts this far above and below the focal they reach.
constexpr double kConvergedFromAfar = 1.1;

// The focal on which the refined solves `basins` converge, 0 when they do not. A solve that
// refines the focal in its final adjustment and starts 10 % or more away from where it ends
// has been pulled there by the reprojection error of every view; several such solves, from
// above and from below, that end within 1 % of one focal measure it however flat the median
// error is around it (Middlebury templeRing, 47 views whose axes meet near one point: nine
// starts from 320 to 1907 px end in 1514-1522 px, the calibrated 1520.4 px, while the median
// error with the focal held varies by 0.2 % over +-10 %). A critical motion leaves the focal
// free: the solves stay near their starts and do not converge.
double convergedFocal(std::span<const FocalProfilePoint> basins, int most_solved) {
  std::vector<double> ends;
  for (const auto& b : basins)
    if (b.refined && b.solved_frames == most_solved) ends.push_back(b.focal_px);
  if (static_cast<int>(ends.size()) < kMinConvergedBasins) return 0.0;
  const double centre = upperMedian(ends);
  int converged = 0;
  bool from_above = false, from_below = false;
  for (const auto& b : basins) {
    if (!b.refined || b.solved_frames != most_solved ||
        std::abs(b.focal_px / centre - 1.0) > kConvergedSpread)
      continue;
    ++converged;
    from_above = from_above || b.start_px >= centre * kConvergedFromAfar;
    from_below = from_below || b.start_px <= centre / kConvergedFromAfar;
  }
  return converged >= kMinConvergedBasins && from_above && from_below ? centre : 0.0;
}

}  // namespace

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
  o.max_centre_sd_steps = 0.0;             // the profile scores reprojection, not the path
  o.keyframe_lens_reregistration = false;  // the chosen focal's solve registers again
  Solver probe(tracks, width_, height_, o);
  FocalProfilePoint p;
  p.start_px = focal;
  p.focal_px = focal;
  p.refined = refine;
  // The calibration stage's checks passed on the whole clip and its pairs only serve the focal
  // and the motion class (general, or the sweep would not run): start at the initial pair.
  probe.calibrateAsGiven();
  if (probe.initialize() && probe.registerFrames() && probe.finalize()) {
    p.solved_frames = probe.solvedFrames();
    p.median_reproj_px = probe.medianReprojectionAll();
    p.focal_px = probe.summary().focal_px;
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
  constexpr std::size_t kBasins = 9;
  for (std::size_t i = 0; i < kBasins; ++i, k *= 1.25)
    profile_.push_back(probeFocal(k * base, true));
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
  focal_fallback_ = clear ? FocalFallback::kProfile : FocalFallback::kProfileFlat;
  refine_fallback_focal_ = clear;
  if (clear) return;
  const double converged =
      convergedFocal(std::span<const FocalProfilePoint>(profile_.data(), kBasins), most_solved);
  if (converged > 0.0) {
    f_ = converged;
    focal_fallback_ = FocalFallback::kConverged;
    refine_fallback_focal_ = true;
  }
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
  return e.empty() ? std::numeric_limits<double>::infinity() : upperMedian(e);
}

}  // namespace epitrack

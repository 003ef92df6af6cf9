#include "algo/tracking/feature_tracker.hpp"

#include "algo/image/frame_difference.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>

namespace epitrack {
namespace {

ShiTomasiOptions detectorOptions(const FeatureTrackerOptions& o) {
  ShiTomasiOptions d;
  d.max_features = o.max_features;
  d.min_distance = o.min_distance;
  d.min_quality = o.min_quality;
  d.border = o.window / 2 + 3;
  return d;
}

LkOptions lkOptions(const FeatureTrackerOptions& o) {
  LkOptions l;
  l.window = o.window;
  l.levels = o.levels;
  l.max_iterations = o.max_iterations;
  l.epsilon = o.epsilon;
  l.min_eigen = o.min_eigen;
  l.affine = o.affine;
  l.residual_radius = o.residual_radius;
  return l;
}

GlobalMotionOptions motionOptions(const FeatureTrackerOptions& o) {
  GlobalMotionOptions m = o.motion;
  m.max_points = std::max(o.motion_anchors, 0);
  return m;
}

// Stage times are processor time of the process (std::clock): on a shared machine they measure
// the work, not the waiting for a core. The tracker runs on the calling thread only.
using StageClock = std::clock_t;
StageClock stageNow() { return std::clock(); }
double msSince(StageClock t0) {
  return 1000.0 * static_cast<double>(std::clock() - t0) / static_cast<double>(CLOCKS_PER_SEC);
}

}  // namespace

const char* trackLossName(TrackLoss loss) {
  switch (loss) {
    case TrackLoss::kLeftImage:
      return "left-image";
    case TrackLoss::kLowTexture:
      return "low-texture";
    case TrackLoss::kNoConvergence:
      return "no-convergence";
    case TrackLoss::kResidual:
      return "residual";
    case TrackLoss::kForwardBackward:
      return "forward-backward";
    case TrackLoss::kGate:
      return "gate";
    case TrackLoss::kMask:
      return "mask";
    case TrackLoss::kEpipolar:
      return "epipolar";
  }
  return "unknown";
}

FeatureTracker::FeatureTracker(const FeatureTrackerOptions& options, int width, int height)
    : options_(options),
      width_(width),
      height_(height),
      detector_(detectorOptions(options), width, height),
      lk_(lkOptions(options), std::max(options.max_features, 0) + 1),  // + the check's slot
      epipolar_(options.epipolar, std::max(options.max_features, 0)),
      motion_estimator_(motionOptions(options)) {
  options_.max_features = std::max(options_.max_features, 0);
  options_.levels = std::clamp(options_.levels, 0, Pyramid::kMaxLevels - 1);
  if (width > 0 && height > 0) {
    for (Pyramid& p : pyramids_) p.configure(width, height, options_.levels + 1);
  }
  const auto n = static_cast<std::size_t>(options_.max_features);
  tracks_.assign(n, Track{0, 0, 0.0f, 0.0f, 0.0f, 0.0f, false, PatchShape{},
                          KalmanFilterCv(options_.kalman), Candidate{}});
  for (auto* v : {&moved_x_, &moved_y_, &moved_dx_, &moved_dy_, &scratch_dx_, &scratch_dy_}) {
    v->resize(n);
  }
  live_points_.resize(n);
  corners_.resize(n);
  output_.resize(n);
  lost_.resize(n);
  predictions_.resize(n);
  // The finest level on which LK's reach (a quarter of the window, in that level's pixels)
  // covers the prediction radius.
  const double reach = 0.25 * static_cast<double>(options_.window);
  while (prediction_start_level_ < options_.levels &&
         options_.prediction_radius_px >
             reach * static_cast<double>(1 << prediction_start_level_)) {
    ++prediction_start_level_;
  }
  if (options_.redetect_cells > 0 && width > 0 && height > 0) {
    // Cells about square: cols / rows follows the image's aspect.
    const double cells = options_.redetect_cells;
    cell_cols_ =
        std::clamp(static_cast<int>(std::lround(std::sqrt(cells * width / height))), 1, width);
    cell_rows_ = std::clamp(static_cast<int>(std::lround(cells / cell_cols_)), 1, height);
    const int total = cell_cols_ * cell_rows_;
    cell_share_ = (options_.max_features + total - 1) / total;
    for (auto* v : {&cell_count_, &cell_held_, &cell_retry_at_})
      v->assign(static_cast<std::size_t>(total), 0);
    cell_needy_.assign(static_cast<std::size_t>(total), 0);
    regions_.resize(static_cast<std::size_t>(total));
  }
}

void FeatureTracker::detect(ImageView<const uint8_t> mask,
                            std::span<const DetectionRegion> regions) {
  int n_live = 0;
  for (const Track& t : tracks_) {
    if (t.live) live_points_[static_cast<std::size_t>(n_live++)] = Point2f{t.x, t.y};
  }
  const int wanted = options_.max_features - n_live;
  if (wanted <= 0) return;
  int found = 0;
  const Pyramid& pyramid = pyramids_[current_];
  const std::span<const Point2f> live(live_points_.data(), static_cast<std::size_t>(n_live));
  const std::span<Corner> out(corners_.data(), corners_.size());
  if (regions.empty()) {
    detector_.detect(pyramid.level(0), live, mask, wanted, out, found);
  } else {
    detector_.detectInRegions(pyramid.level(0), live, mask, regions, wanted, out, found);
  }
  std::size_t slot = 0;
  for (int i = 0; i < found; ++i) {
    while (slot < tracks_.size() && tracks_[slot].live) ++slot;
    if (slot == tracks_.size()) break;
    const Corner& c = corners_[static_cast<std::size_t>(i)];
    if (lk_.setTemplate(static_cast<int>(slot), pyramid, c.x, c.y) != LkStatus::kTracked) continue;
    Track& t = tracks_[slot];
    t.id = next_id_++;
    t.age = 0;
    t.x = c.x;
    t.y = c.y;
    t.residual = 0.0f;
    t.residual_level = 0.0f;
    t.shape = PatchShape{};
    t.live = true;
    t.kalman.init(c.x, c.y);
    ++live_count_;
    ++stats_.detected;
  }
}

namespace {

/// How far the affine shape A stretches its template: max(s1, 1 / s2) of A's singular values
/// s1 >= s2 (1 for a rotation).
double shapeStretch(const PatchShape& A) {
  const double a = A.a00, b = A.a01, c = A.a10, d = A.a11;
  // Singular values of [a b; c d]: sqrt of the eigenvalues of A^T A.
  const double p = a * a + b * b + c * c + d * d;
  const double det = std::abs(a * d - b * c);
  const double disc = std::sqrt(std::max(p * p - 4.0 * det * det, 0.0));
  const double s1 = std::sqrt(0.5 * (p + disc));
  const double s2 = det / std::max(s1, 1e-12);
  return std::max(s1, 1.0 / std::max(s2, 1e-12));
}

/// Median of values[0, n) (partially reorders them). n > 0.
float medianOf(float* values, int n) {
  const auto mid = values + n / 2;
  std::nth_element(values, mid, values + n);
  return *mid;
}

}  // namespace

void FeatureTracker::neighbourMotion(float x, float y, float& dx, float& dy) {
  dx = 0.0f;
  dy = 0.0f;
  if (moved_count_ == 0) return;
  const float radius =
      static_cast<float>(options_.neighbour_radius) * static_cast<float>(std::max(width_, height_));
  const float r2 = radius * radius;
  int n = 0;
  for (int i = 0; i < moved_count_; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const float ex = moved_x_[k] - x;
    const float ey = moved_y_[k] - y;
    if (ex * ex + ey * ey > r2) continue;
    scratch_dx_[static_cast<std::size_t>(n)] = moved_dx_[k];
    scratch_dy_[static_cast<std::size_t>(n)] = moved_dy_[k];
    ++n;
  }
  if (n >= 3) {
    dx = medianOf(scratch_dx_.data(), n);
    dy = medianOf(scratch_dy_.data(), n);
    return;
  }
  if (!global_ready_) {
    std::copy_n(moved_dx_.begin(), moved_count_, scratch_dx_.begin());
    std::copy_n(moved_dy_.begin(), moved_count_, scratch_dy_.begin());
    global_dx_ = medianOf(scratch_dx_.data(), moved_count_);
    global_dy_ = medianOf(scratch_dy_.data(), moved_count_);
    global_ready_ = true;
  }
  dx = global_dx_;
  dy = global_dy_;
}

bool FeatureTracker::forwardBackward(float x0, float y0, float x, float y, float px, float py) {
  ++stats_.forward_backward_checks;
  const int check_slot = options_.max_features;  // the spare slot
  if (lk_.setTemplate(check_slot, pyramids_[current_], x, y) != LkStatus::kTracked) return false;
  // Start from the mirrored prediction: the backward motion is as hard as the forward one.
  float bx = x - (px - x0);
  float by = y - (py - y0);
  // The start is off by the forward alignment's correction (x - px): the backward alignment
  // starts on the finest level where that is within forward_backward_start_px of the level's
  // pixels (the coarser levels would only walk it to where it already is).
  int start_level = PyramidalLk::kMaxLevels;
  if (options_.forward_backward_start_px > 0.0) {
    const double correction = std::hypot(static_cast<double>(x - px), static_cast<double>(y - py));
    start_level = 0;
    while (start_level < options_.levels &&
           correction >
               options_.forward_backward_start_px * static_cast<double>(1 << start_level)) {
      ++start_level;
    }
  }
  PatchShape shape;
  float residual = 0.0f;
  if (lk_.align(check_slot, pyramids_[1 - current_], bx, by, shape, residual, start_level) !=
      LkStatus::kTracked) {
    return false;
  }
  const float ex = bx - x0;
  const float ey = by - y0;
  return ex * ex + ey * ey <=
         static_cast<float>(options_.forward_backward_px * options_.forward_backward_px);
}

bool FeatureTracker::gateAccepts(const KalmanFilterCv& kalman, double mx, double my, double cx,
                                 double cy) const {
  const auto& P = kalman.covariance();
  const double r2 = kalman.options().measurement_sigma * kalman.options().measurement_sigma;
  const double speed = std::hypot(kalman.vx(), kalman.vy());
  const double widen = options_.gate_speed_fraction * speed;
  const double s00 = P(0, 0) + r2 + widen * widen;
  const double s11 = P(1, 1) + r2 + widen * widen;
  const double s01 = P(0, 1);
  const double det = s00 * s11 - s01 * s01;
  if (!(det > 0.0)) return false;
  const double nx = mx - cx;
  const double ny = my - cy;
  // Squared Mahalanobis distance under the 2x2 innovation covariance (the paper §4.2).
  const double d2 = (s11 * nx * nx - 2.0 * s01 * nx * ny + s00 * ny * ny) / det;
  return d2 <= kalman.options().gate_chi2;
}

void FeatureTracker::setPredictions(std::span<const TrackPrediction> predictions) {
  const std::size_t n = std::min(predictions.size(), predictions_.size());
  std::copy_n(predictions.begin(), n, predictions_.begin());
  const auto end = predictions_.begin() + static_cast<std::ptrdiff_t>(n);
  std::sort(predictions_.begin(), end,
            [](const TrackPrediction& a, const TrackPrediction& b) { return a.id < b.id; });
  prediction_count_ = static_cast<int>(n);
}

const TrackPrediction* FeatureTracker::suppliedPrediction(int32_t id) const {
  const auto end = predictions_.begin() + prediction_count_;
  const auto it =
      std::lower_bound(predictions_.begin(), end, id,
                       [](const TrackPrediction& p, int32_t wanted) { return p.id < wanted; });
  return it != end && it->id == id ? &*it : nullptr;
}

bool FeatureTracker::alignFromSupplied(int slot, const TrackPrediction& p, Candidate& c) {
  c.x = p.x;
  c.y = p.y;
  c.status =
      lk_.align(slot, pyramids_[current_], c.x, c.y, c.shape, c.residual, prediction_start_level_);
  if (c.status != LkStatus::kTracked) return false;
  const double ex = static_cast<double>(c.x) - static_cast<double>(p.x);
  const double ey = static_cast<double>(c.y) - static_cast<double>(p.y);
  return ex * ex + ey * ey <= options_.prediction_radius_px * options_.prediction_radius_px;
}

void FeatureTracker::ownPrediction(const Track& t, bool young, float& px, float& py) {
  if (young) {
    if (!options_.neighbour_prior) return;
    float dx = 0.0f, dy = 0.0f;
    neighbourMotion(t.x, t.y, dx, dy);
    px += dx;
    py += dy;
  } else if (options_.kalman_gate) {
    px = static_cast<float>(t.kalman.x());
    py = static_cast<float>(t.kalman.y());
  } else {
    double gx = t.x, gy = t.y;
    motion_.apply(t.x, t.y, gx, gy);
    px = static_cast<float>(gx);
    py = static_cast<float>(gy);
  }
}

void FeatureTracker::alignOne(std::size_t s, bool young) {
  Track& t = tracks_[s];
  const int slot = static_cast<int>(s);
  const float x0 = t.x;
  const float y0 = t.y;
  // The track's own prediction: an established track's is its Kalman filter's (its own constant
  // velocity plus this frame's global motion, predictAll), a young track's the neighbours' motion.
  float px = x0;
  float py = y0;
  ownPrediction(t, young, px, py);
  Candidate& c = t.candidate;
  c.shape = t.shape;
  c.residual = 0.0f;
  c.supplied = false;
  // A supplied prediction (the live map's) first; where it fails, the track's own.
  const TrackPrediction* supplied = young ? nullptr : suppliedPrediction(t.id);
  if (supplied != nullptr) {
    ++stats_.predicted;
    const long before = lk_.iterations();
    c.supplied = alignFromSupplied(slot, *supplied, c);
    stats_.predicted_iterations += lk_.iterations() - before;
    if (c.supplied) {
      c.predicted_x = supplied->x;
      c.predicted_y = supplied->y;
      return finishAlignment(t, young, x0, y0);
    }
    ++stats_.prediction_fallbacks;
  }
  const Pyramid& pyramid = pyramids_[current_];
  c.x = px;
  c.y = py;
  c.residual = 0.0f;
  c.shape = t.shape;
  c.status = LkStatus::kNoConvergence;
  if (!young && options_.kalman_gate && t.age >= options_.predicted_after) {
    // An established track's Kalman prediction is within a pixel or two: start at
    // `predicted_start_level` instead of the coarsest level, retry from the top on failure.
    c.status =
        lk_.align(slot, pyramid, c.x, c.y, c.shape, c.residual, options_.predicted_start_level);
  }
  if (c.status != LkStatus::kTracked) {
    c.x = px;
    c.y = py;
    c.shape = t.shape;
    c.status = lk_.align(slot, pyramid, c.x, c.y, c.shape, c.residual);
  }
  // The prediction may be what misled it (a jerk the global motion missed): once more from
  // where the track was. Not for a track seen once: its prior is the motion its neighbours were
  // measured with in this frame, and a retry from its last position on the KITTI highway excerpt
  // spent about 1 300 LK iterations per frame (of 8 800) for no more tracks of 5 or 10 frames.
  if (!young && c.status != LkStatus::kTracked && (px != x0 || py != y0)) {
    px = x0;
    py = y0;
    c.x = x0;
    c.y = y0;
    c.shape = t.shape;
    c.status = lk_.align(slot, pyramid, c.x, c.y, c.shape, c.residual);
  }
  c.predicted_x = px;
  c.predicted_y = py;
  finishAlignment(t, young, x0, y0);
}

void FeatureTracker::finishAlignment(Track& t, bool young, float x0, float y0) {
  Candidate& c = t.candidate;
  if (measurement_hook_ != nullptr && c.status == LkStatus::kTracked) {
    measurement_hook_(measurement_hook_context_, t.id, frame_index_, c.x, c.y);
  }
  if (!young && c.status == LkStatus::kTracked) {
    const auto k = static_cast<std::size_t>(moved_count_++);
    moved_x_[k] = x0;
    moved_y_[k] = y0;
    moved_dx_[k] = c.x - x0;
    moved_dy_[k] = c.y - y0;
  }
}

void FeatureTracker::decideOne(std::size_t s, bool young, double residual_scale,
                               ImageView<const uint8_t> mask) {
  Track& t = tracks_[s];
  const Candidate& c = t.candidate;
  auto drop = [&](int& counter, TrackLoss reason) { dropTrack(t, counter, reason); };
  if (c.status != LkStatus::kTracked) {
    ++stats_.lost_lk;
    switch (c.status) {
      case LkStatus::kLeftImage:
        return drop(stats_.lost_left_image, TrackLoss::kLeftImage);
      case LkStatus::kLowTexture:
        return drop(stats_.lost_low_texture, TrackLoss::kLowTexture);
      default:
        return drop(stats_.lost_no_convergence, TrackLoss::kNoConvergence);
    }
  }
  // Thresholds scale with the frame's typical residual (noise, blur, compression of real
  // footage raise every track's residual alike; a clean rendering keeps the fixed ones).
  const double res = static_cast<double>(c.residual);
  const double max_res =
      std::max(options_.max_residual, options_.residual_scale_max * residual_scale);
  const double jump =
      std::max(options_.max_residual_jump, options_.residual_scale_jump * residual_scale);
  const double refresh =
      std::max(options_.refresh_residual, options_.residual_scale_refresh * residual_scale);
  // Too far from the template, or a jump above the track's own level (a young track has none:
  // the jump from zero, or residual_scale_young frame medians): occlusion, or sliding onto other
  // structure.
  const double young_max =
      std::max(options_.max_residual_jump, options_.residual_scale_young * residual_scale);
  if (res > max_res || (young && res > young_max) ||
      (!young && res > static_cast<double>(t.residual_level) + jump)) {
    return drop(stats_.lost_residual, TrackLoss::kResidual);
  }
  // The forward-backward check: every young track (it has no velocity for the gate yet), tracks
  // whose appearance drifted (before their template is refreshed), or every track if asked.
  const double stretch = shapeStretch(c.shape);
  const bool stretched = options_.refresh_stretch > 0.0 && stretch >= options_.refresh_stretch;
  const bool drifted = res > refresh || stretched;
  const bool check =
      options_.forward_backward_px > 0.0 && (young || options_.forward_backward || drifted);
  if (check && !forwardBackward(t.x, t.y, c.x, c.y, c.predicted_x, c.predicted_y)) {
    return drop(stats_.lost_forward_backward, TrackLoss::kForwardBackward);
  }
  if (!mask.empty()) {
    const int mx = std::clamp(static_cast<int>(std::lround(c.x)), 0, width_ - 1);
    const int my = std::clamp(static_cast<int>(std::lround(c.y)), 0, height_ - 1);
    if (mask(mx, my) == 0) return drop(stats_.lost_mask, TrackLoss::kMask);
  }
  if (options_.kalman_gate) {
    // A track seen once has no velocity: its first displacement is judged by the check above.
    if (!young && !c.gate_ok) {
      if (!gate_released_) return drop(stats_.lost_gate, TrackLoss::kGate);
      // The whole frame left the gate: the camera moved in a way the global motion missed. The
      // track's history says nothing about this frame: its filter restarts from the measurement.
      ++stats_.gate_released;
      t.kalman.init(c.x, c.y);
    } else {
      t.kalman.correct(c.x, c.y);
    }
  }
  t.x = c.x;
  t.y = c.y;
  ++t.age;
  t.residual = c.residual;
  t.shape = c.shape;
  t.residual_level = young ? c.residual : 0.7f * t.residual_level + 0.3f * c.residual;
  if (check && ((res > refresh && stretch >= options_.refresh_min_stretch) || stretched)) {
    // Appearance drifted (perspective, scale, light) but the patch still follows the point from
    // the last frame: the check's template (taken here, in this frame) becomes the track's,
    // keeping the track's residual level.
    lk_.copyTemplate(options_.max_features, static_cast<int>(s));
    t.residual = 0.0f;
    t.shape = PatchShape{};
    ++stats_.refreshed;
  }
}

void FeatureTracker::epipolarCheck() {
  const auto t0 = stageNow();
  epipolar_.beginFrame();
  for (std::size_t s = 0; s < tracks_.size(); ++s) {
    const Track& t = tracks_[s];
    if (t.live) epipolar_.observe(static_cast<int>(s), t.id, t.x, t.y);
  }
  if (epipolar_.endFrame() > 0) {
    for (std::size_t s = 0; s < tracks_.size(); ++s) {
      Track& t = tracks_[s];
      if (!t.live || !epipolar_.rejected(static_cast<int>(s))) continue;
      t.live = false;
      --live_count_;
      ++stats_.lost_epipolar;
      lost_[static_cast<std::size_t>(lost_count_++)] =
          LostTrack{t.id, t.x, t.y, t.age, TrackLoss::kEpipolar};
    }
  }
  stats_.epipolar_ms = msSince(t0);
}

void FeatureTracker::anchorPrediction(const Track& t, double& px, double& py) const {
  if (options_.kalman_gate) {
    const double dt = 1.0 + static_cast<double>(skipped_frames_);
    px = static_cast<double>(t.x) + t.kalman.vx() * dt;
    py = static_cast<double>(t.y) + t.kalman.vy() * dt;
  } else {
    last_motion_.apply(static_cast<double>(t.x), static_cast<double>(t.y), px, py);
  }
}

int FeatureTracker::probeAnchors(int per_cell, int skip_first_per_cell) {
  // Anchors: established tracks spread over a 4x4 grid (up to per_cell per cell, in slot order:
  // the oldest tracks first, so the choice is deterministic; the first skip_first_per_cell of
  // each cell were probed by an earlier call). Each is probed through the whole pyramid from its
  // own prediction (a jerk may have moved it far); the probe only measures the camera, the track
  // itself is aligned afterwards like every other.
  constexpr int kGrid = kMotionGrid;
  int in_cell[kGrid * kGrid] = {};
  int probed = 0;
  const int budget = std::min(options_.motion_anchors, per_cell * kGrid * kGrid);
  const Pyramid& pyramid = pyramids_[current_];
  for (std::size_t s = 0; s < tracks_.size() && probed < budget; ++s) {
    const Track& t = tracks_[s];
    if (!t.live || t.age == 0) continue;
    const int cx =
        std::clamp(static_cast<int>(t.x * kGrid / static_cast<float>(width_)), 0, kGrid - 1);
    const int cy =
        std::clamp(static_cast<int>(t.y * kGrid / static_cast<float>(height_)), 0, kGrid - 1);
    int& n = in_cell[cy * kGrid + cx];
    if (n >= per_cell) continue;
    ++n;
    ++probed;
    if (n <= skip_first_per_cell) {
      // Probed in the first round: its correspondence again, in slot order like the others, so
      // that a frame decided on all the anchors fits exactly what one round would have fitted.
      if (first_round_slot_[first_round_next_] == static_cast<int>(s)) {
        const FirstRoundProbe& f = first_round_[first_round_next_++];
        motion_estimator_.add(f.px, f.py, f.qx, f.qy);
      }
      continue;
    }
    double px = static_cast<double>(t.x), py = static_cast<double>(t.y);
    anchorPrediction(t, px, py);
    float qx = static_cast<float>(px), qy = static_cast<float>(py);
    PatchShape shape = t.shape;
    float residual = 0.0f;
    LkStatus status = LkStatus::kNoConvergence;
    // A supplied prediction (the map's) finds the anchor from a fine level; the motion is still
    // measured against the anchor's own prediction (px, py).
    if (const TrackPrediction* supplied = suppliedPrediction(t.id); supplied != nullptr) {
      Candidate probe;
      probe.shape = t.shape;
      if (alignFromSupplied(static_cast<int>(s), *supplied, probe)) {
        status = LkStatus::kTracked;
        qx = probe.x;
        qy = probe.y;
      }
    }
    if (status != LkStatus::kTracked)
      status = lk_.align(static_cast<int>(s), pyramid, qx, qy, shape, residual);
    if (status != LkStatus::kTracked && options_.kalman_gate) {
      // Shake reverses: once more from where the track would be had the camera not kept the
      // last frame's change of velocity.
      double lx = 0.0, ly = 0.0;
      last_motion_.apply(static_cast<double>(t.x), static_cast<double>(t.y), lx, ly);
      const double g = options_.motion_velocity_gain;
      qx = static_cast<float>(px - g * (lx - static_cast<double>(t.x)));
      qy = static_cast<float>(py - g * (ly - static_cast<double>(t.y)));
      shape = t.shape;
      status = lk_.align(static_cast<int>(s), pyramid, qx, qy, shape, residual);
    }
    if (status != LkStatus::kTracked) continue;
    motion_estimator_.add(px, py, qx, qy);
    if (skip_first_per_cell == 0 && first_round_count_ < kMotionGrid * kMotionGrid) {
      first_round_slot_[first_round_count_] = static_cast<int>(s);
      first_round_[first_round_count_++] = FirstRoundProbe{px, py, qx, qy};
    }
  }
  return probed;
}

double FeatureTracker::cornerShift(const SimilarityMotion& m) const {
  double shift = 0.0;
  for (const double x : {0.0, static_cast<double>(width_ - 1)})
    for (const double y : {0.0, static_cast<double>(height_ - 1)}) {
      double mx = x, my = y;
      m.apply(x, y, mx, my);
      shift = std::max(shift, std::hypot(mx - x, my - y));
    }
  return shift;
}

void FeatureTracker::estimateGlobalMotion() {
  motion_estimator_.clear();
  motion_ = SimilarityMotion{};
  if (!options_.global_motion || options_.motion_anchors <= 0) return;
  constexpr int kCells = kMotionGrid * kMotionGrid;
  const int per_cell = (options_.motion_anchors + kCells - 1) / kCells;
  // A first round of one anchor per cell. When it agrees clearly on a motion that moves no image
  // corner by motion_quiet_px or more, the tracks' own velocities predict the frame (smooth
  // motion): the model is the identity (a fit from 16 anchors moved the orbit's p95 over 1 px), and
  // the other anchors are not probed. Anything else (a jerk, parallax, a split vote) probes the
  // rest and decides on all of them, as below.
  const int quick = std::min({per_cell, std::max(options_.motion_quick_per_cell, 0), 1});
  if (quick > 0 && quick < per_cell) {
    first_round_count_ = 0;
    probeAnchors(quick, 0);
    SimilarityMotion quick_fit;
    if (motion_estimator_.estimate(quick_fit) == GlobalMotionEstimator::Status::kOk &&
        static_cast<double>(motion_estimator_.inlierCount()) >=
            options_.motion_clear_majority * static_cast<double>(motion_estimator_.size()) &&
        cornerShift(quick_fit) < options_.motion_quiet_px) {
      stats_.motion_anchors = motion_estimator_.size();
      stats_.motion_inliers = motion_estimator_.inlierCount();
      motion_ = SimilarityMotion{};
      return;
    }
    first_round_slot_[first_round_count_] = -1;  // the end of the list
    first_round_next_ = 0;
    motion_estimator_.clear();
    probeAnchors(per_cell, quick);
  } else {
    probeAnchors(per_cell, 0);
  }
  stats_.motion_anchors = motion_estimator_.size();
  // No consensus (too few anchors, no dominant motion): every track keeps its own constant
  // velocity (with the filter), else the camera keeps the last frame's motion.
  motion_ = options_.kalman_gate ? SimilarityMotion{} : last_motion_;
  SimilarityMotion fitted = motion_;
  if (motion_estimator_.estimate(fitted) != GlobalMotionEstimator::Status::kOk) return;
  stats_.motion_inliers = motion_estimator_.inlierCount();
  // A camera jerk moves most anchors alike, often by more than each track's own filter absorbs.
  // A similarity that only part of them follow is parallax (a turntable, a close object) or
  // independent motion; applied to every track's velocity it would only add noise (templeRing
  // 12-30: ATE 0.083 % -> 0.139 %, the self-calibrated focal 2 % off, with departures of 0.1-3 px
  // that 40-70 % of the anchors followed). So the model is used for a clear majority of the
  // anchors, or for a plain majority when it moves some image corner by motion_min_shift_px (5 px)
  // or more: a jerk the per-track gates could not absorb (4 px let templeRing's parallax through:
  // its self-calibrated focal moved 1.3 % off; 5 px keeps it at 0.33 % and every 5-30 px jerk of
  // the jerked-orbit test).
  const double inlier_fraction =
      static_cast<double>(stats_.motion_inliers) / std::max(stats_.motion_anchors, 1);
  if (inlier_fraction >= options_.motion_clear_majority) {
    motion_ = fitted;
    return;
  }
  if (inlier_fraction < options_.motion_min_inlier_fraction) return;
  if (cornerShift(fitted) >= options_.motion_min_shift_px) motion_ = fitted;
}

void FeatureTracker::predictAll() {
  const double dt = 1.0 + static_cast<double>(skipped_frames_);
  for (Track& t : tracks_) {
    if (!t.live || !options_.kalman_gate) continue;
    // What the camera changed since the last frame is the control input: each filter's own
    // constant velocity (parallax, objects) plus the camera's change, on the position and (by
    // motion_velocity_gain) on the velocity.
    t.kalman.predict(dt);
    double gx = t.kalman.x(), gy = t.kalman.y();
    motion_.apply(t.kalman.x(), t.kalman.y(), gx, gy);
    const double dx = gx - t.kalman.x(), dy = gy - t.kalman.y();
    t.kalman.control(dx, dy, options_.motion_velocity_gain * dx / dt,
                     options_.motion_velocity_gain * dy / dt);
  }
}

void FeatureTracker::redetect(ImageView<const uint8_t> mask) {
  const bool cells = cell_cols_ > 0;
  if (frame_index_ == 0) {
    detect(mask, {});
    frames_since_detect_ = 0;
    stats_.detect_cells = cells ? cell_cols_ * cell_rows_ : 1;
    if (cells) recordSearchedCells(true);
    return;
  }
  if (!redetectDue()) return;
  if (cells) {
    redetectInCells(mask);
    return;
  }
  detect(mask, {});
  frames_since_detect_ = 0;
  stats_.detect_cells = 1;
}

bool FeatureTracker::redetectDue() const {
  const double target = options_.redetect_fraction * options_.max_features;
  const bool below = live_count_ < options_.max_features;
  return live_count_ < target || (below && options_.redetect_interval > 0 &&
                                  frames_since_detect_ >= options_.redetect_interval);
}

void FeatureTracker::countTracksPerCell() {
  std::fill(cell_count_.begin(), cell_count_.end(), 0);
  for (const Track& t : tracks_) {
    if (!t.live) continue;
    // Integer cell arithmetic: the same cell on every platform.
    const int cx = std::clamp(static_cast<int>(t.x) * cell_cols_ / width_, 0, cell_cols_ - 1);
    const int cy = std::clamp(static_cast<int>(t.y) * cell_rows_ / height_, 0, cell_rows_ - 1);
    ++cell_count_[static_cast<std::size_t>(cy * cell_cols_ + cx)];
  }
}

void FeatureTracker::recordSearchedCells(bool all) {
  countTracksPerCell();
  for (std::size_t c = 0; c < cell_count_.size(); ++c) {
    if (!all && cell_needy_[c] == 0) continue;
    cell_held_[c] = cell_count_[c];
    // A cell the search could not fill (little texture, or the frame's budget spent elsewhere)
    // is looked at again after redetect_cell_retry frames, not on every frame.
    cell_retry_at_[c] = frame_index_ + std::max(options_.redetect_cell_retry, 1);
  }
}

int FeatureTracker::needyRegions() {
  int n = 0;
  for (int cy = 0; cy < cell_rows_; ++cy) {
    for (int cx = 0; cx < cell_cols_;) {
      if (cell_needy_[static_cast<std::size_t>(cy * cell_cols_ + cx)] == 0) {
        ++cx;
        continue;
      }
      const int first = cx;
      int deficit = 0;
      for (; cx < cell_cols_ && cell_needy_[static_cast<std::size_t>(cy * cell_cols_ + cx)] != 0;
           ++cx) {
        deficit += cell_share_ - cell_count_[static_cast<std::size_t>(cy * cell_cols_ + cx)];
      }
      const PixelRect area{first * width_ / cell_cols_, cy * height_ / cell_rows_,
                           cx * width_ / cell_cols_, (cy + 1) * height_ / cell_rows_};
      regions_[static_cast<std::size_t>(n++)] =
          DetectionRegion{area, options_.redetect_fill_share ? deficit : -1};
    }
  }
  return n;
}

void FeatureTracker::redetectInCells(ImageView<const uint8_t> mask) {
  countTracksPerCell();
  int needy = 0;
  bool emptied = false;
  for (std::size_t c = 0; c < cell_count_.size(); ++c) {
    const int count = cell_count_[c];
    // Below its share and either lost tracks since its last search or due for a retry.
    const bool wants =
        count < cell_share_ && (count < cell_held_[c] || frame_index_ >= cell_retry_at_[c]);
    cell_needy_[c] = wants ? 1 : 0;
    needy += wants ? 1 : 0;
    emptied = emptied || (count == 0 && cell_held_[c] > 0);
  }
  if (needy == 0 || (frames_since_detect_ < options_.redetect_min_gap && !emptied)) return;
  const int regions = needyRegions();
  detect(mask,
         std::span<const DetectionRegion>(regions_.data(), static_cast<std::size_t>(regions)));
  frames_since_detect_ = 0;
  stats_.detect_cells = needy;
  recordSearchedCells(false);
}

void FeatureTracker::dropTrack(Track& t, int& counter, TrackLoss reason) {
  ++counter;
  t.live = false;
  --live_count_;
  lost_[static_cast<std::size_t>(lost_count_++)] = LostTrack{t.id, t.x, t.y, t.age, reason};
}

void FeatureTracker::publishTracks() {
  output_count_ = 0;
  for (const Track& t : tracks_) {
    if (t.live)
      output_[static_cast<std::size_t>(output_count_++)] = TrackedFeature{t.id, t.x, t.y, t.age};
  }
  stats_.tracked = output_count_;
}

void FeatureTracker::keepRepeatedFrame() {
  // The same picture again: nothing moved, so every track stays where it is and no filter sees
  // the frame (a Kalman update with a zero displacement would halve each track's velocity, and
  // the prediction of the next new frame would miss by half a frame's motion: on KITTI with every
  // frame twice, the live map never initialised). The earlier pyramid stays the reference, so a
  // run of near-equal frames is compared with its first frame, not frame to frame.
  current_ = 1 - current_;
  stats_.repeated = 1;
  // A track is kept only where the picture has texture: the repeat of a featureless frame (a
  // covered lens, a blank wall) must not hold the tracks LK carried onto it for as long as it
  // lasts (a camera that seems to stand still: a silent wrong solve). LK drops them on the next
  // frame that differs; the template test of the spare slot drops them here.
  const int check_slot = options_.max_features;
  for (Track& t : tracks_) {
    if (!t.live ||
        lk_.setTemplate(check_slot, pyramids_[current_], t.x, t.y) != LkStatus::kLowTexture) {
      continue;
    }
    ++stats_.lost_lk;
    dropTrack(t, stats_.lost_low_texture, TrackLoss::kLowTexture);
  }
  publishTracks();
  ++frame_index_;
  skipped_frames_ = 0;
  prediction_count_ = 0;
}

FeatureTracker::Status FeatureTracker::track(ImageView<const uint8_t> frame,
                                             ImageView<const uint8_t> mask) {
  if (pyramids_[0].levelCount() == 0) return Status::kNotConfigured;
  if (frame.width != width_ || frame.height != height_) return Status::kSizeMismatch;
  if (!mask.empty() && !sameSize(mask, frame)) return Status::kSizeMismatch;
  stats_ = FrameStats{};
  lost_count_ = 0;
  current_ = 1 - current_;
  auto t0 = stageNow();
  pyramids_[current_].build(frame);
  stats_.pyramid_ms = msSince(t0);
  if (frame_index_ > 0 && options_.repeat_max_mean_diff_q8 > 0 &&
      framesNearlyEqual(pyramids_[current_].level(0), pyramids_[1 - current_].level(0),
                        options_.repeat_max_mean_diff_q8)) {
    keepRepeatedFrame();
    return Status::kOk;
  }

  if (frame_index_ > 0) {
    lk_.resetCounters();
    t0 = stageNow();
    moved_count_ = 0;
    global_ready_ = false;
    // The camera's motion first (from the anchors), then every track predicted with it.
    estimateGlobalMotion();
    predictAll();
    // Tracks with a velocity first; their motion is the prior of the ones seen once.
    for (std::size_t s = 0; s < tracks_.size(); ++s) {
      if (tracks_[s].live && tracks_[s].age > 0) alignOne(s, false);
    }
    for (std::size_t s = 0; s < tracks_.size(); ++s) {
      if (tracks_[s].live && tracks_[s].age == 0) alignOne(s, true);
    }
    // The frame's typical residual: the median over the aligned tracks.
    int n = 0;
    for (const Track& t : tracks_) {
      if (t.live && t.candidate.status == LkStatus::kTracked) {
        scratch_dx_[static_cast<std::size_t>(n++)] = t.candidate.residual;
      }
    }
    const double residual_scale =
        n > 0 ? static_cast<double>(medianOf(scratch_dx_.data(), n)) : 0.0;
    stats_.residual_median = residual_scale;
    // The gate, judged for every track before the decisions: when most tracks fail it together,
    // that is the camera, not the tracks (gate_released_).
    int judged = 0, failed = 0;
    for (Track& t : tracks_) {
      Candidate& c = t.candidate;
      c.gate_ok = true;
      if (!t.live || t.age == 0 || c.status != LkStatus::kTracked || !options_.kalman_gate) {
        continue;
      }
      // A supplied prediction centres the gate (the filter's covariance still sizes it).
      const double cx = c.supplied ? static_cast<double>(c.predicted_x) : t.kalman.x();
      const double cy = c.supplied ? static_cast<double>(c.predicted_y) : t.kalman.y();
      c.gate_ok = gateAccepts(t.kalman, c.x, c.y, cx, cy);
      ++judged;
      failed += c.gate_ok ? 0 : 1;
    }
    gate_released_ =
        judged >= options_.gate_release_min &&
        static_cast<double>(failed) > options_.gate_release_fraction * static_cast<double>(judged);
    for (std::size_t s = 0; s < tracks_.size(); ++s) {
      if (tracks_[s].live) decideOne(s, tracks_[s].age == 0, residual_scale, mask);
    }
    stats_.lk_ms = msSince(t0);
    stats_.lk_iterations = lk_.iterations();
    if (options_.epipolar_check) epipolarCheck();
  }
  ++frames_since_detect_;
  t0 = stageNow();
  redetect(mask);
  // Only a frame that searched has a detection time (the benchmarks count those as calls).
  stats_.detect_ms = stats_.detect_cells > 0 ? msSince(t0) : 0.0;

  publishTracks();
  double cx = 0.5 * width_, cy = 0.5 * height_;
  motion_.apply(0.5 * width_, 0.5 * height_, cx, cy);
  stats_.motion_dx = cx - 0.5 * width_;
  stats_.motion_dy = cy - 0.5 * height_;
  if (frame_index_ > 0) last_motion_ = motion_;
  ++frame_index_;
  skipped_frames_ = 0;
  prediction_count_ = 0;  // the predictions were for this frame only
  return Status::kOk;
}

}  // namespace epitrack

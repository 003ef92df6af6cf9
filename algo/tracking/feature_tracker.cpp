#include "algo/tracking/feature_tracker.hpp"

#include <algorithm>
#include <cmath>
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
  return l;
}

// Stage times are processor time of the process (std::clock): on a shared machine they measure
// the work, not the waiting for a core. The tracker runs on the calling thread only.
using StageClock = std::clock_t;
StageClock stageNow() { return std::clock(); }
double msSince(StageClock t0) {
  return 1000.0 * static_cast<double>(std::clock() - t0) / static_cast<double>(CLOCKS_PER_SEC);
}

}  // namespace

FeatureTracker::FeatureTracker(const FeatureTrackerOptions& options, int width, int height)
    : options_(options),
      width_(width),
      height_(height),
      detector_(detectorOptions(options), width, height),
      lk_(lkOptions(options), std::max(options.max_features, 0)) {
  options_.max_features = std::max(options_.max_features, 0);
  options_.levels = std::clamp(options_.levels, 0, Pyramid::kMaxLevels - 1);
  if (width > 0 && height > 0) pyramid_.configure(width, height, options_.levels + 1);
  const auto n = static_cast<std::size_t>(options_.max_features);
  tracks_.assign(
      n, Track{0, 0, 0.0f, 0.0f, 0.0f, false, PatchShape{}, KalmanFilterCv(options_.kalman)});
  live_points_.resize(n);
  corners_.resize(n);
  output_.resize(n);
}

void FeatureTracker::detect(ImageView<const uint8_t> mask) {
  int n_live = 0;
  for (const Track& t : tracks_) {
    if (t.live) live_points_[static_cast<std::size_t>(n_live++)] = Point2f{t.x, t.y};
  }
  const int wanted = options_.max_features - n_live;
  if (wanted <= 0) return;
  int found = 0;
  detector_.detect(pyramid_.level(0),
                   std::span<const Point2f>(live_points_.data(), static_cast<std::size_t>(n_live)),
                   mask, wanted, std::span<Corner>(corners_.data(), corners_.size()), found);
  std::size_t slot = 0;
  for (int i = 0; i < found; ++i) {
    while (slot < tracks_.size() && tracks_[slot].live) ++slot;
    if (slot == tracks_.size()) break;
    const Corner& c = corners_[static_cast<std::size_t>(i)];
    if (lk_.setTemplate(static_cast<int>(slot), pyramid_, c.x, c.y) != LkStatus::kTracked) continue;
    Track& t = tracks_[slot];
    t.id = next_id_++;
    t.age = 0;
    t.x = c.x;
    t.y = c.y;
    t.residual = 0.0f;
    t.shape = PatchShape{};
    t.live = true;
    t.kalman.init(c.x, c.y);
    ++live_count_;
    ++stats_.detected;
  }
}

FeatureTracker::Status FeatureTracker::track(ImageView<const uint8_t> frame,
                                             ImageView<const uint8_t> mask) {
  if (pyramid_.levelCount() == 0) return Status::kNotConfigured;
  if (frame.width != width_ || frame.height != height_) return Status::kSizeMismatch;
  if (!mask.empty() && !sameSize(mask, frame)) return Status::kSizeMismatch;
  stats_ = FrameStats{};
  auto t0 = stageNow();
  pyramid_.build(frame);
  stats_.pyramid_ms = msSince(t0);

  if (frame_index_ > 0) {
    lk_.resetCounters();
    double kalman_ms = 0.0;
    t0 = stageNow();
    for (std::size_t s = 0; s < tracks_.size(); ++s) {
      Track& t = tracks_[s];
      if (!t.live) continue;
      float x = t.x;
      float y = t.y;
      if (options_.kalman_gate) {
        t.kalman.predict();
        x = static_cast<float>(t.kalman.x());
        y = static_cast<float>(t.kalman.y());
      }
      float residual = 0.0f;
      PatchShape shape = t.shape;
      LkStatus st = LkStatus::kNoConvergence;
      if (options_.kalman_gate && t.age >= options_.predicted_after) {
        // An established track's Kalman prediction is within a pixel or two: start at
        // `predicted_start_level` instead of the coarsest level, retry from the top on failure.
        st = lk_.align(static_cast<int>(s), pyramid_, x, y, shape, residual,
                       options_.predicted_start_level);
        if (st != LkStatus::kTracked) {
          x = static_cast<float>(t.kalman.x());
          y = static_cast<float>(t.kalman.y());
          shape = t.shape;
        }
      }
      if (st != LkStatus::kTracked) {
        st = lk_.align(static_cast<int>(s), pyramid_, x, y, shape, residual);
      }
      const double res = static_cast<double>(residual);
      bool keep = st == LkStatus::kTracked;
      if (!keep) {
        ++stats_.lost_lk;
        stats_.lost_left_image += st == LkStatus::kLeftImage ? 1 : 0;
        stats_.lost_no_convergence += st == LkStatus::kNoConvergence ? 1 : 0;
        stats_.lost_low_texture += st == LkStatus::kLowTexture ? 1 : 0;
      }
      if (keep && (res > options_.max_residual ||
                   res > static_cast<double>(t.residual) + options_.max_residual_jump)) {
        keep = false;
        ++stats_.lost_residual;
      }
      if (keep && !mask.empty()) {
        const int mx = std::clamp(static_cast<int>(std::lround(x)), 0, width_ - 1);
        const int my = std::clamp(static_cast<int>(std::lround(y)), 0, height_ - 1);
        if (mask(mx, my) == 0) {
          keep = false;
          ++stats_.lost_mask;
        }
      }
      if (keep && options_.kalman_gate) {
        if (t.kalman.accepts(x, y)) {
          t.kalman.correct(x, y);
        } else {
          keep = false;
          ++stats_.lost_gate;
        }
      }
      if (!keep) {
        t.live = false;
        --live_count_;
        continue;
      }
      t.x = x;
      t.y = y;
      ++t.age;
      t.residual = residual;
      t.shape = shape;
      if (res > options_.refresh_residual) {
        // Appearance drifted (perspective change): restart the template here. Costs one
        // re-sampling error, instead of one per frame as frame-to-frame tracking does.
        if (lk_.setTemplate(static_cast<int>(s), pyramid_, x, y) == LkStatus::kTracked) {
          t.residual = 0.0f;
          t.shape = PatchShape{};
          ++stats_.refreshed;
        } else {
          t.live = false;
          --live_count_;
          ++stats_.lost_lk;
        }
      }
    }
    stats_.lk_ms = msSince(t0) - kalman_ms;
    stats_.kalman_ms = kalman_ms;
    stats_.lk_iterations = lk_.iterations();
  }

  ++frames_since_detect_;
  const double target = options_.redetect_fraction * options_.max_features;
  const bool below = live_count_ < options_.max_features;
  if (frame_index_ == 0 || live_count_ < target ||
      (below && options_.redetect_interval > 0 &&
       frames_since_detect_ >= options_.redetect_interval)) {
    t0 = stageNow();
    detect(mask);
    stats_.detect_ms = msSince(t0);
    frames_since_detect_ = 0;
  }

  output_count_ = 0;
  for (const Track& t : tracks_) {
    if (t.live)
      output_[static_cast<std::size_t>(output_count_++)] = TrackedFeature{t.id, t.x, t.y, t.age};
  }
  stats_.tracked = output_count_;
  ++frame_index_;
  return Status::kOk;
}

}  // namespace epitrack

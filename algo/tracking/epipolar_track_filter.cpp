#include "algo/tracking/epipolar_track_filter.hpp"

#include <algorithm>
#include <cmath>

#include "algo/geometry/two_view_model_selection.hpp"

namespace epitrack {
namespace {

/// Median of values[0, n) (partially reorders them). n > 0.
double medianOf(double* values, int n) {
  const auto mid = values + n / 2;
  std::nth_element(values, mid, values + n);
  return *mid;
}

}  // namespace

EpipolarTrackFilter::EpipolarTrackFilter(const EpipolarFilterOptions& options, int capacity)
    : options_(options),
      capacity_(std::max(capacity, 0)),
      window_(std::max(options.window, 2)),
      fundamental_(std::max(capacity, 8)),
      homography_(std::max(capacity, 8)) {
  const auto n = static_cast<std::size_t>(capacity_);
  const auto rows = static_cast<std::size_t>(window_);
  hist_x_.assign(rows * n, 0.0f);
  hist_y_.assign(rows * n, 0.0f);
  hist_id_.assign(rows * n, -1);
  cur_x_.assign(n, 0.0f);
  cur_y_.assign(n, 0.0f);
  cur_id_.assign(n, -1);
  strike_id_.assign(n, -1);
  strikes_.assign(n, 0);
  rejected_.assign(n, 0);
  error_.assign(n, -1.0f);
  x_ref_.resize(n);
  x_cur_.resize(n);
  pair_slot_.resize(n);
  values_.resize(n);
}

void EpipolarTrackFilter::reset() {
  std::fill(hist_id_.begin(), hist_id_.end(), -1);
  std::fill(strike_id_.begin(), strike_id_.end(), -1);
  std::fill(strikes_.begin(), strikes_.end(), 0);
  newest_ = -1;
  filled_ = 0;
  frames_ = 0;
  beginFrame();
}

void EpipolarTrackFilter::beginFrame() {
  std::fill(cur_id_.begin(), cur_id_.end(), -1);
  std::fill(rejected_.begin(), rejected_.end(), 0);
  std::fill(error_.begin(), error_.end(), -1.0f);
  summary_ = EpipolarCheckSummary{};
}

void EpipolarTrackFilter::observe(int slot, int32_t id, float x, float y) {
  if (slot < 0 || slot >= capacity_ || id < 0) return;
  const auto s = static_cast<std::size_t>(slot);
  cur_id_[s] = id;
  cur_x_[s] = x;
  cur_y_[s] = y;
}

std::size_t EpipolarTrackFilter::ringRow(int age) const {
  const int row = ((newest_ - (age - 1)) % window_ + window_) % window_;
  return static_cast<std::size_t>(row) * static_cast<std::size_t>(capacity_);
}

int EpipolarTrackFilter::gather(int age) {
  const std::size_t base = ringRow(age);
  pairs_ = 0;
  for (int slot = 0; slot < capacity_; ++slot) {
    const auto s = static_cast<std::size_t>(slot);
    if (cur_id_[s] < 0 || hist_id_[base + s] != cur_id_[s]) continue;
    const auto k = static_cast<std::size_t>(pairs_++);
    x_ref_[k] = Eigen::Vector2d(hist_x_[base + s], hist_y_[base + s]);
    x_cur_[k] = Eigen::Vector2d(cur_x_[s], cur_y_[s]);
    pair_slot_[k] = slot;
  }
  return pairs_;
}

int EpipolarTrackFilter::chooseReference() {
  // The most recent frame with enough displacement: the shortest span over which the rigid
  // relation separates a sliding track from the scene, with the most tracks still alive. Without
  // one (a slow camera, or an orbit whose tracks near the look-at point barely move), the oldest
  // frame of the window: the longest span, over which a slide has grown the most.
  int oldest = 0;
  for (int age = 1; age <= filled_; ++age) {
    if (gather(age) < std::max(options_.min_tracks, 8)) break;  // older frames share fewer
    oldest = age;
    for (int k = 0; k < pairs_; ++k) {
      const auto u = static_cast<std::size_t>(k);
      values_[u] = (x_cur_[u] - x_ref_[u]).norm();
    }
    const double displacement = medianOf(values_.data(), pairs_);
    summary_.median_displacement_px = displacement;
    if (displacement >= options_.min_displacement_px) return age;
  }
  return summary_.median_displacement_px >= options_.min_span_displacement_px ? oldest : 0;
}

void EpipolarTrackFilter::check(int age) {
  const auto n = static_cast<std::size_t>(pairs_);
  const std::span<const Eigen::Vector2d> x1(x_ref_.data(), n), x2(x_cur_.data(), n);
  const uint64_t seed = options_.seed + 0x9e3779b97f4a7c15ULL * checks_++;
  FundamentalOptions fo;
  fo.refit_rounds = 1;  // the verdict needs the inlier set, not the last digit of F  fo.ransac =
  RansacOptions{options_.ransac_threshold_px, 0.999, 8, options_.ransac_iterations, seed};
  HomographyOptions ho;
  ho.ransac = RansacOptions{options_.ransac_threshold_px, 0.999, 8, options_.ransac_iterations,
                            seed ^ 0x5bd1e995ULL};
  FundamentalResult fr;
  HomographyResult hr;
  const bool f_ok = fundamental_.estimate(x1, x2, fo, fr) == FundamentalRansac::Status::kOk;
  const bool h_ok = homography_.estimate(x1, x2, ho, hr) == HomographyRansac::Status::kOk;
  if (!f_ok && !h_ok) return;
  bool use_h = !f_ok;
  if (f_ok && h_ok) {
    // GRIC with the noise of the F fit (robust scale of its Sampson distances), floored.
    for (std::size_t k = 0; k < n; ++k) values_[k] = std::sqrt(sampsonSquared(fr.F, x1[k], x2[k]));
    const double sigma =
        std::max(options_.gric_min_sigma_px, 1.4826 * medianOf(values_.data(), pairs_));
    use_h = selectTwoViewModel(fr.F, hr.H, x1, x2, sigma, fr.mask, hr.mask).model ==
            TwoViewModel::kHomography;
  }
  for (std::size_t k = 0; k < n; ++k) {
    const double e2 =
        use_h ? homographyTransferSquared(hr.H, x1[k], x2[k]) : sampsonSquared(fr.F, x1[k], x2[k]);
    const double e = std::isfinite(e2) ? std::sqrt(e2) : 1e9;
    error_[static_cast<std::size_t>(pair_slot_[k])] = static_cast<float>(e);
    values_[k] = e;
  }
  const double median = medianOf(values_.data(), pairs_);
  const double threshold = std::max(options_.min_error_px, options_.median_multiple * median);
  summary_.model =
      use_h ? EpipolarCheckSummary::Model::kHomography : EpipolarCheckSummary::Model::kFundamental;
  summary_.reference_age = age;
  summary_.checked = pairs_;
  summary_.inliers = use_h ? hr.inliers : fr.inliers;
  summary_.median_error_px = median;
  summary_.threshold_px = threshold;
  if (static_cast<double>(summary_.inliers) <
      options_.min_inlier_fraction * static_cast<double>(pairs_)) {
    summary_.model = EpipolarCheckSummary::Model::kNone;  // not trusted: no verdict, no strikes
    return;
  }
  for (std::size_t k = 0; k < n; ++k) {
    const auto s = static_cast<std::size_t>(pair_slot_[k]);
    if (strike_id_[s] != cur_id_[s]) {
      strike_id_[s] = cur_id_[s];
      strikes_[s] = 0;
    }
    if (static_cast<double>(error_[s]) > threshold) {
      ++summary_.beyond;
      if (++strikes_[s] >= std::max(options_.consecutive, 1)) {
        rejected_[s] = 1;
        ++summary_.rejected;
      }
    } else {
      strikes_[s] = 0;
    }
  }
}

void EpipolarTrackFilter::record() {
  newest_ = (newest_ + 1) % window_;
  filled_ = std::min(filled_ + 1, window_);
  const std::size_t base = static_cast<std::size_t>(newest_) * static_cast<std::size_t>(capacity_);
  for (int slot = 0; slot < capacity_; ++slot) {
    const auto s = static_cast<std::size_t>(slot);
    // A rejected track leaves the tracker: its slot holds no track in this frame's history.
    hist_id_[base + s] = rejected_[s] != 0 ? -1 : cur_id_[s];
    hist_x_[base + s] = cur_x_[s];
    hist_y_[base + s] = cur_y_[s];
  }
}

int EpipolarTrackFilter::endFrame() {
  // filled_ counts recorded frames; the ring keeps window_ of them (ages 1..filled_).
  const bool due = frames_++ % static_cast<uint64_t>(std::max(options_.interval, 1)) == 0;
  const int age = due && filled_ > 0 ? chooseReference() : 0;
  if (age > 0) {
    gather(age);
    check(age);
  }
  record();
  return summary_.rejected;
}

}  // namespace epitrack

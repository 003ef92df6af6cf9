#include "algo/matching/descriptor_matcher.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

namespace epitrack {

namespace {

constexpr int32_t kNone = -1;
constexpr int32_t kFar = std::numeric_limits<int32_t>::max();

bool passesRatio(int32_t best, int32_t second, double ratio) {
  if (ratio <= 0.0 || ratio >= 1.0 || second == kFar) return true;
  return static_cast<double>(best) < ratio * static_cast<double>(second);
}

}  // namespace

DescriptorMatcher::DescriptorMatcher(int max_features) : max_features_(std::max(1, max_features)) {
  const auto n = static_cast<std::size_t>(max_features_);
  best_of_b_.resize(n);
  best_of_b_dist_.resize(n);
  best_b_of_a_.resize(n);
  best_a_dist_.resize(n);
  second_a_dist_.resize(n);
  seed_dist_.resize(2 * n);
  seed_index_.resize(2 * n);
  disp_x_.resize(2 * n);
  disp_y_.resize(2 * n);
}

void DescriptorMatcher::match(std::span<const Keypoint> ka, std::span<const BinaryDescriptor> da,
                              std::span<const Keypoint> kb, std::span<const BinaryDescriptor> db,
                              const DescriptorMatchOptions& options, std::span<DescriptorMatch> out,
                              int& count) {
  count = 0;
  const int na = static_cast<int>(std::min({ka.size(), da.size(), best_b_of_a_.size()}));
  const int nb = static_cast<int>(std::min({kb.size(), db.size(), best_of_b_.size()}));
  std::fill_n(best_of_b_.begin(), nb, kNone);
  std::fill_n(best_of_b_dist_.begin(), nb, kFar);
  const double r2 = options.max_radius_px * options.max_radius_px;
  for (int i = 0; i < na; ++i) {
    const Keypoint& p = ka[static_cast<std::size_t>(i)];
    const BinaryDescriptor& d = da[static_cast<std::size_t>(i)];
    int32_t best = kFar, second = kFar, best_j = kNone;
    for (int j = 0; j < nb; ++j) {
      const Keypoint& q = kb[static_cast<std::size_t>(j)];
      if (std::abs(p.level - q.level) > options.max_level_diff) continue;
      if (r2 > 0.0) {
        const double dx = static_cast<double>(q.x - p.x);
        const double dy = static_cast<double>(q.y - p.y);
        if (dx * dx + dy * dy > r2) continue;
      }
      const int32_t h = hammingDistance(d, db[static_cast<std::size_t>(j)]);
      if (h < best) {
        second = best;
        best = h;
        best_j = j;
      } else if (h < second) {
        second = h;
      }
      if (h < best_of_b_dist_[static_cast<std::size_t>(j)]) {
        best_of_b_dist_[static_cast<std::size_t>(j)] = h;
        best_of_b_[static_cast<std::size_t>(j)] = i;
      }
    }
    best_b_of_a_[static_cast<std::size_t>(i)] =
        best_j >= 0 && best <= options.max_distance && passesRatio(best, second, options.ratio)
            ? best_j
            : kNone;
    best_a_dist_[static_cast<std::size_t>(i)] = best;
    second_a_dist_[static_cast<std::size_t>(i)] = second;
  }
  for (int i = 0; i < na && count < static_cast<int>(out.size()); ++i) {
    const int32_t j = best_b_of_a_[static_cast<std::size_t>(i)];
    if (j < 0) continue;
    if (options.mutual && best_of_b_[static_cast<std::size_t>(j)] != i) continue;
    out[static_cast<std::size_t>(count++)] =
        DescriptorMatch{i, j, best_a_dist_[static_cast<std::size_t>(i)],
                        second_a_dist_[static_cast<std::size_t>(i)]};
  }
}

void DescriptorMatcher::matchGuided(
    std::span<const Keypoint> ka, std::span<const BinaryDescriptor> da,
    std::span<const Keypoint> kb, std::span<const BinaryDescriptor> db,
    std::span<const uint8_t> used_a, std::span<const uint8_t> used_b, const Eigen::Matrix3d& F,
    const GuidedMatchOptions& options, std::span<DescriptorMatch> out, int& count) {
  const int na = static_cast<int>(std::min({ka.size(), da.size(), best_b_of_a_.size()}));
  const int nb = static_cast<int>(std::min({kb.size(), db.size(), best_of_b_.size()}));
  std::fill_n(best_of_b_.begin(), nb, kNone);
  std::fill_n(best_of_b_dist_.begin(), nb, kFar);
  const double t = options.max_epipolar_px;
  for (int i = 0; i < na; ++i) {
    best_b_of_a_[static_cast<std::size_t>(i)] = kNone;
    if (static_cast<std::size_t>(i) < used_a.size() && used_a[static_cast<std::size_t>(i)])
      continue;
    const Keypoint& p = ka[static_cast<std::size_t>(i)];
    const Eigen::Vector3d l =
        F * Eigen::Vector3d(static_cast<double>(p.x), static_cast<double>(p.y), 1.0);
    const double norm = std::hypot(l.x(), l.y());
    if (!(norm > 0.0)) continue;
    const double band = t * norm;
    const BinaryDescriptor& d = da[static_cast<std::size_t>(i)];
    int32_t best = kFar, second = kFar, best_j = kNone;
    for (int j = 0; j < nb; ++j) {
      if (static_cast<std::size_t>(j) < used_b.size() && used_b[static_cast<std::size_t>(j)])
        continue;
      const Keypoint& q = kb[static_cast<std::size_t>(j)];
      if (std::abs(p.level - q.level) > options.max_level_diff) continue;
      if (std::abs(l.x() * static_cast<double>(q.x) + l.y() * static_cast<double>(q.y) + l.z()) >
          band)
        continue;
      const int32_t h = hammingDistance(d, db[static_cast<std::size_t>(j)]);
      if (h < best) {
        second = best;
        best = h;
        best_j = j;
      } else if (h < second) {
        second = h;
      }
      if (h < best_of_b_dist_[static_cast<std::size_t>(j)]) {
        best_of_b_dist_[static_cast<std::size_t>(j)] = h;
        best_of_b_[static_cast<std::size_t>(j)] = i;
      }
    }
    if (best_j >= 0 && best <= options.max_distance && passesRatio(best, second, options.ratio)) {
      best_b_of_a_[static_cast<std::size_t>(i)] = best_j;
      best_a_dist_[static_cast<std::size_t>(i)] = best;
      second_a_dist_[static_cast<std::size_t>(i)] = second;
    }
  }
  for (int i = 0; i < na && count < static_cast<int>(out.size()); ++i) {
    const int32_t j = best_b_of_a_[static_cast<std::size_t>(i)];
    if (j < 0 || best_of_b_[static_cast<std::size_t>(j)] != i) continue;
    out[static_cast<std::size_t>(count++)] =
        DescriptorMatch{i, j, best_a_dist_[static_cast<std::size_t>(i)],
                        second_a_dist_[static_cast<std::size_t>(i)]};
  }
}

void DescriptorMatcher::matchLocal(std::span<const Keypoint> ka,
                                   std::span<const BinaryDescriptor> da,
                                   std::span<const Keypoint> kb,
                                   std::span<const BinaryDescriptor> db,
                                   std::span<const DescriptorMatch> seeds,
                                   std::span<const uint8_t> used_a, std::span<const uint8_t> used_b,
                                   const Eigen::Matrix3d& F, const LocalMatchOptions& options,
                                   std::span<DescriptorMatch> out, int& count) {
  const int na = static_cast<int>(std::min({ka.size(), da.size(), best_b_of_a_.size()}));
  const int nb = static_cast<int>(std::min({kb.size(), db.size(), best_of_b_.size()}));
  const int ns = static_cast<int>(std::min(seeds.size(), seed_dist_.size()));
  const int k = std::min(options.neighbours, ns);
  if (k <= 0) return;
  std::fill_n(best_of_b_.begin(), nb, kNone);
  std::fill_n(best_of_b_dist_.begin(), nb, kFar);
  for (int i = 0; i < na; ++i) {
    best_b_of_a_[static_cast<std::size_t>(i)] = kNone;
    if (static_cast<std::size_t>(i) < used_a.size() && used_a[static_cast<std::size_t>(i)])
      continue;
    const Keypoint& p = ka[static_cast<std::size_t>(i)];
    // The k nearest seeds (partial selection) and the median of their displacements.
    for (int s = 0; s < ns; ++s) {
      const Keypoint& q = ka[static_cast<std::size_t>(seeds[static_cast<std::size_t>(s)].a)];
      const float dx = q.x - p.x, dy = q.y - p.y;
      seed_dist_[static_cast<std::size_t>(s)] = dx * dx + dy * dy;
      seed_index_[static_cast<std::size_t>(s)] = s;
    }
    std::partial_sort(seed_index_.begin(), seed_index_.begin() + k, seed_index_.begin() + ns,
                      [&](int32_t u, int32_t v) {
                        const float du = seed_dist_[static_cast<std::size_t>(u)];
                        const float dv = seed_dist_[static_cast<std::size_t>(v)];
                        return du < dv || (du == dv && u < v);
                      });
    for (int j = 0; j < k; ++j) {
      const DescriptorMatch& m =
          seeds[static_cast<std::size_t>(seed_index_[static_cast<std::size_t>(j)])];
      disp_x_[static_cast<std::size_t>(j)] =
          kb[static_cast<std::size_t>(m.b)].x - ka[static_cast<std::size_t>(m.a)].x;
      disp_y_[static_cast<std::size_t>(j)] =
          kb[static_cast<std::size_t>(m.b)].y - ka[static_cast<std::size_t>(m.a)].y;
    }
    std::nth_element(disp_x_.begin(), disp_x_.begin() + k / 2, disp_x_.begin() + k);
    std::nth_element(disp_y_.begin(), disp_y_.begin() + k / 2, disp_y_.begin() + k);
    const double mx = static_cast<double>(disp_x_[static_cast<std::size_t>(k / 2)]);
    const double my = static_cast<double>(disp_y_[static_cast<std::size_t>(k / 2)]);
    // Spread: the largest deviation of a neighbour's displacement from the median.
    double spread = 0.0;
    for (int j = 0; j < k; ++j) {
      const DescriptorMatch& m =
          seeds[static_cast<std::size_t>(seed_index_[static_cast<std::size_t>(j)])];
      const double dx = static_cast<double>(kb[static_cast<std::size_t>(m.b)].x -
                                            ka[static_cast<std::size_t>(m.a)].x) -
                        mx;
      const double dy = static_cast<double>(kb[static_cast<std::size_t>(m.b)].y -
                                            ka[static_cast<std::size_t>(m.a)].y) -
                        my;
      spread = std::max(spread, std::hypot(dx, dy));
    }
    const double r =
        std::min(options.max_radius_px, options.radius_px + options.spread_factor * spread);
    const double px = static_cast<double>(p.x) + mx, py = static_cast<double>(p.y) + my;
    const Eigen::Vector3d l =
        F * Eigen::Vector3d(static_cast<double>(p.x), static_cast<double>(p.y), 1.0);
    const double norm = std::hypot(l.x(), l.y());
    if (!(norm > 0.0)) continue;
    const double band = options.max_epipolar_px * norm;
    const BinaryDescriptor& d = da[static_cast<std::size_t>(i)];
    int32_t best = kFar, second = kFar, best_j = kNone;
    for (int j = 0; j < nb; ++j) {
      if (static_cast<std::size_t>(j) < used_b.size() && used_b[static_cast<std::size_t>(j)])
        continue;
      const Keypoint& q = kb[static_cast<std::size_t>(j)];
      if (std::abs(p.level - q.level) > options.max_level_diff) continue;
      const double qx = static_cast<double>(q.x), qy = static_cast<double>(q.y);
      if ((qx - px) * (qx - px) + (qy - py) * (qy - py) > r * r) continue;
      if (std::abs(l.x() * qx + l.y() * qy + l.z()) > band) continue;
      const int32_t h = hammingDistance(d, db[static_cast<std::size_t>(j)]);
      if (h < best) {
        second = best;
        best = h;
        best_j = j;
      } else if (h < second) {
        second = h;
      }
      if (h < best_of_b_dist_[static_cast<std::size_t>(j)]) {
        best_of_b_dist_[static_cast<std::size_t>(j)] = h;
        best_of_b_[static_cast<std::size_t>(j)] = i;
      }
    }
    if (best_j >= 0 && best <= options.max_distance && passesRatio(best, second, options.ratio)) {
      best_b_of_a_[static_cast<std::size_t>(i)] = best_j;
      best_a_dist_[static_cast<std::size_t>(i)] = best;
      second_a_dist_[static_cast<std::size_t>(i)] = second;
    }
  }
  for (int i = 0; i < na && count < static_cast<int>(out.size()); ++i) {
    const int32_t j = best_b_of_a_[static_cast<std::size_t>(i)];
    if (j < 0 || best_of_b_[static_cast<std::size_t>(j)] != i) continue;
    out[static_cast<std::size_t>(count++)] =
        DescriptorMatch{i, j, best_a_dist_[static_cast<std::size_t>(i)],
                        second_a_dist_[static_cast<std::size_t>(i)]};
  }
}

}  // namespace epitrack

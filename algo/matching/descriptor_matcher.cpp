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

}  // namespace epitrack

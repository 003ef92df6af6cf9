#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "algo/matching/feature_extractor.hpp"
#include "algo/matching/oriented_brief.hpp"

namespace epitrack {

/// A putative correspondence between feature `a` of one set and feature `b` of another.
struct DescriptorMatch {
  int32_t a = 0;
  int32_t b = 0;
  int32_t distance = 0;  ///< Hamming distance
  int32_t second = 0;    ///< distance of the second-best candidate (INT32_MAX: none)
};

struct DescriptorMatchOptions {
  int max_distance = 80;     ///< Hamming distance (of 256) above which no match is taken
  double ratio = 0.8;        ///< Lowe's ratio test: best < ratio * second best (0 or >= 1: none)
  bool mutual = true;        ///< a's best in b must have a as its best in a (cross check)
  int max_level_diff = 0;    ///< candidate pairs at most this many pyramid levels apart
  double max_radius_px = 0;  ///< > 0: candidates within this image distance only
};

/// Brute-force nearest-neighbour matching of binary descriptors (Hamming distance, popcount) with
/// Lowe's ratio test (Lowe 2004 §7.1) and a mutual (cross) check. Buffers are sized for
/// `max_features` per set at construction; `match` never allocates.
class DescriptorMatcher {
 public:
  explicit DescriptorMatcher(int max_features);

  /// Matches every feature of set a against set b; `out` receives the accepted matches in order of
  /// a, `count` their number (at most out.size()).
  void match(std::span<const Keypoint> ka, std::span<const BinaryDescriptor> da,
             std::span<const Keypoint> kb, std::span<const BinaryDescriptor> db,
             const DescriptorMatchOptions& options, std::span<DescriptorMatch> out, int& count);

 private:
  int max_features_;
  std::vector<int32_t> best_of_b_;       // best a for each b
  std::vector<int32_t> best_of_b_dist_;  // its distance
  std::vector<int32_t> best_b_of_a_;     // best b for each a (before the mutual check)
  std::vector<int32_t> best_a_dist_;
  std::vector<int32_t> second_a_dist_;
};

}  // namespace epitrack

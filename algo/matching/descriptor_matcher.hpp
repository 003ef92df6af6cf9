#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

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

struct GuidedMatchOptions {
  double max_epipolar_px = 2.0;  ///< candidates within this distance of the epipolar line
  int max_distance = 80;
  double ratio = 0.9;  ///< between the best and the second best candidate on the line
  int max_level_diff = 0;
};

struct LocalMatchOptions {
  int neighbours = 4;           ///< verified matches whose displacement predicts a feature's
  double radius_px = 12.0;      ///< search radius around the prediction ...
  double spread_factor = 1.0;   ///< ... plus this times the neighbours' displacement spread
  double max_radius_px = 40.0;  ///< ... at most
  double max_epipolar_px = 2.0;
  int max_distance = 80;
  double ratio = 0.9;
  int max_level_diff = 0;
};

/// Brute-force nearest-neighbour matching of binary descriptors (Hamming distance, popcount) with
/// Lowe's ratio test (Lowe 2004 §7.1) and a mutual (cross) check, and epipolar-guided matching of
/// the features left over once F is known. Buffers are sized for `max_features` per set at
/// construction; the match calls never allocate.
class DescriptorMatcher {
 public:
  explicit DescriptorMatcher(int max_features);

  /// Matches every feature of set a against set b; `out` receives the accepted matches in order of
  /// a, `count` their number (at most out.size()).
  void match(std::span<const Keypoint> ka, std::span<const BinaryDescriptor> da,
             std::span<const Keypoint> kb, std::span<const BinaryDescriptor> db,
             const DescriptorMatchOptions& options, std::span<DescriptorMatch> out, int& count);

  /// Matches the features of a and b not flagged in `used_a` / `used_b` (1: already matched)
  /// along the epipolar lines of F (x_b^T F x_a = 0, pixels): for each such a, the candidates of
  /// b within `max_epipolar_px` of its line pass the ratio test among themselves, then the
  /// mutual check. Appends to out[count...].
  void matchGuided(std::span<const Keypoint> ka, std::span<const BinaryDescriptor> da,
                   std::span<const Keypoint> kb, std::span<const BinaryDescriptor> db,
                   std::span<const uint8_t> used_a, std::span<const uint8_t> used_b,
                   const Eigen::Matrix3d& F, const GuidedMatchOptions& options,
                   std::span<DescriptorMatch> out, int& count);

  /// Matches the features left over once a set of verified matches (`seeds`, indices into a and
  /// b) is known, by local motion: each unused feature of a is predicted in b by the median
  /// displacement of its `neighbours` nearest seeds (in a), and its candidates are the unused
  /// features of b within the search radius of the prediction and within max_epipolar_px of its
  /// epipolar line (F: x_b^T F x_a = 0). The ratio test runs among those candidates, then the
  /// mutual check. Two constraints across each other leave few candidates, so descriptors only
  /// need to be distinctive locally (the repeated or weak texture the global test rejects).
  /// Appends to out[count...]; `seeds` must hold at least `neighbours` matches.
  void matchLocal(std::span<const Keypoint> ka, std::span<const BinaryDescriptor> da,
                  std::span<const Keypoint> kb, std::span<const BinaryDescriptor> db,
                  std::span<const DescriptorMatch> seeds, std::span<const uint8_t> used_a,
                  std::span<const uint8_t> used_b, const Eigen::Matrix3d& F,
                  const LocalMatchOptions& options, std::span<DescriptorMatch> out, int& count);

 private:
  int max_features_;
  std::vector<int32_t> best_of_b_;       // best a for each b
  std::vector<int32_t> best_of_b_dist_;  // its distance
  std::vector<int32_t> best_b_of_a_;     // best b for each a (before the mutual check)
  std::vector<int32_t> best_a_dist_;
  std::vector<int32_t> second_a_dist_;
  std::vector<float> seed_dist_;  // per seed: squared distance to the feature (scratch)
  std::vector<int32_t> seed_index_;
  std::vector<float> disp_x_, disp_y_;
};

}  // namespace epitrack

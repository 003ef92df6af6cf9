#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/geometry/essential.hpp"
#include "algo/geometry/essential_five_point.hpp"

namespace epitrack {

/// A relative pose from E-RANSAC, with the inliers it rests on.
struct RelativePoseHypothesis {
  RelativePoseResult relative;
  int inliers = 0;
  std::vector<uint8_t> mask;  ///< 1 = inlier of the hypothesis's E
  /// Largest angle (degrees) between this rotation and those of the other seeds' hypotheses with
  /// at least nine tenths of its inliers.
  double rotation_spread_deg = 0.0;
};

/// The relative pose n1 -> n2 (normalized coordinates) from the E-RANSAC hypothesis with the most
/// inliers over `trials` seeds (the first is `options`' own seed), and how far the rotations of
/// the near-best hypotheses spread about it. A pose its matches determine gives one rotation
/// whatever the seed; a near-planar or small patch lets E's rotation trade against its
/// translation, and RANSAC then settles anywhere in a family that explains the matches almost
/// equally (TUM fr3/cabinet key frames 7 -> 6: 6.4 to 16.9 degrees over eight seeds with 73-83
/// inliers each, the truth 17.2; well-determined pairs of the same set agree within 1.5).
/// False when no seed gives a pose. Allocates (an offline, per-view-pair step).
bool relativePoseOverSeeds(std::span<const Eigen::Vector2d> n1, std::span<const Eigen::Vector2d> n2,
                           const EssentialRansacOptions& options, int trials,
                           RelativePoseHypothesis& best);

}  // namespace epitrack

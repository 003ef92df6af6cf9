#pragma once

namespace epitrack {

/// A pair of solved views whose matches a relative pose other than the solve's explains much
/// better (Solver::checkViewPairs): at least one of the two poses (or the block of views each
/// belongs to) is likely wrong, or the pair's matches are dominated by a coherent mismatch.
struct ViewPairContradiction {
  int a = -1, b = -1;     ///< the views (frame indices), a < b
  int matches = 0;        ///< their common tracks
  int best_inliers = 0;   ///< the matches E-RANSAC's best relative pose explains
  int solve_inliers = 0;  ///< the matches the solve's relative pose explains
};

}  // namespace epitrack

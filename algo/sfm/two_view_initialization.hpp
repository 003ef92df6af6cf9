#pragma once

#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "algo/geometry/pose.hpp"

namespace epitrack {

/// Thresholds of the two-view reconstruction (the solver's and the live map's options).
struct TwoViewOptions {
  double focal_px = 0.0;                ///< fx: pose refinement and triangulation in pixels
  double min_point_parallax_deg = 1.0;  ///< a point's two rays must meet at least at this angle
  double reproj_threshold_px = 2.5;     ///< and reproject within this in both views
};

enum class TwoViewStatus {
  kOk,
  kNoPose,     ///< no factorisation of E puts the inliers in front of both cameras
  kAmbiguous,  ///< the runner-up factorisation holds more than 70 % as many points
};
const char* toString(TwoViewStatus s);

/// The initial pair's reconstruction from a fundamental matrix (paper §5.3), shared by the offline
/// Solver and the LiveMap: E = K^T F K, the factorisation that puts most F-inliers in front of
/// both cameras (refused when a second one comes within 70 %: an ambiguous cheirality), the
/// relative pose refined on the inliers, then every inlier triangulated with the parallax and
/// reprojection thresholds.
///
/// Inputs: F and K (pixels), the matches' normalized (undistorted) coordinates `n1`, `n2` and the
/// F-inlier `mask`, all of one size n. Outputs, preallocated by the caller (n entries each, no
/// allocation here): `pose` of the second view (the first is the identity); `X[i]` the point of
/// match i when triangulated; `accepted[0..count)` the triangulated matches in order, and
/// `parallax[0..count)` their parallax in degrees.
TwoViewStatus reconstructTwoView(const Eigen::Matrix3d& F, const Eigen::Matrix3d& K,
                                 std::span<const Eigen::Vector2d> n1,
                                 std::span<const Eigen::Vector2d> n2, std::span<const uint8_t> mask,
                                 const TwoViewOptions& options, PoseCw& pose,
                                 std::span<Eigen::Vector3d> X, std::span<int> accepted,
                                 std::span<double> parallax, int& count);

}  // namespace epitrack

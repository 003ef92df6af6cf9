#pragma once

#include <span>

#include <Eigen/Core>

#include "algo/geometry/pose.hpp"

namespace epitrack {

enum class TriangulationStatus {
  kOk,
  kDegenerate,        ///< fewer than two views, non-finite input or a singular system
  kBehindCamera,      ///< the point is not in front of every observing camera (cheirality)
  kLowParallax,       ///< the rays are nearly parallel: depth is unknown
  kHighReprojection,  ///< the best point still reprojects too far from an observation
};
const char* toString(TriangulationStatus s);

struct TriangulationOptions {
  double min_parallax_deg = 1.0;  ///< largest angle between any two observing rays must reach this
  double max_reproj_px = 2.0;     ///< every observation's reprojection error must stay below this
  double focal_px = 1.0;          ///< converts normalized residuals to pixels for the check
  int refine_iterations = 5;      ///< Gauss-Newton steps on the reprojection error after the DLT
};

struct TriangulationResult {
  Eigen::Vector3d X = Eigen::Vector3d::Zero();
  double max_reproj_px = 0.0;
  double parallax_deg = 0.0;
  TriangulationStatus status = TriangulationStatus::kDegenerate;
};

/// Linear triangulation (the paper §5.3; Hartley & Zisserman §12.2 DLT): the null vector of the
/// stacked x cross (P X) rows of every view, from normalized image coordinates and world-to-camera
/// poses. Returns false when the system is singular or the point is at infinity.
bool triangulateDlt(std::span<const PoseCw> poses, std::span<const Eigen::Vector2d> normalized,
                    Eigen::Vector3d& X);

/// DLT, then Gauss-Newton on the sum of squared reprojection errors (normalized coordinates), then
/// the checks of `options` (cheirality in every view, parallax, reprojection). Never allocates.
TriangulationResult triangulatePoint(std::span<const PoseCw> poses,
                                     std::span<const Eigen::Vector2d> normalized,
                                     const TriangulationOptions& options);

}  // namespace epitrack

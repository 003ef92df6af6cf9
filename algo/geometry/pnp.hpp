#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/geometry/pose.hpp"
#include "algo/robust/ransac.hpp"

namespace epitrack {

struct PoseRefineOptions {
  int max_iterations = 10;
  double huber_px = 1.0;  ///< Huber threshold on the pixel residual (<= 0: plain least squares)
  double focal_px = 1.0;  ///< converts normalized residuals to pixels
};

struct PoseRefineSummary {
  int iterations = 0;
  double initial_rms_px = 0.0;
  double final_rms_px = 0.0;
  bool converged = false;
};

/// Levenberg-Marquardt on SE(3) (paper §5.4 refined beyond the linear method): minimises the
/// Huber-weighted reprojection error of fixed 3D points, updating the pose by a left
/// perturbation x_c <- exp(w) x_c + v. `mask` empty: every match. Returns false when the step is
/// not finite or a point is behind the camera at the start; the pose is then left unchanged.
bool refinePose(std::span<const Eigen::Vector3d> X, std::span<const Eigen::Vector2d> normalized,
                std::span<const uint8_t> mask, const PoseRefineOptions& options, PoseCw& pose,
                PoseRefineSummary* summary = nullptr);

struct PnpOptions {
  RansacOptions ransac{2.0, 0.999, 8, 1000, 3};  ///< threshold: reprojection error in pixels
  double focal_px = 1.0;  ///< normalized -> pixel scale for the threshold and the refinement
  bool refine = true;
  PoseRefineOptions refine_options;
};

struct PnpResult {
  PoseCw pose;
  int inliers = 0;
  int iterations = 0;
  double rms_px = 0.0;            ///< over the inliers after refinement
  std::span<const uint8_t> mask;  ///< owned by the solver
};

/// Robust camera pose from 3D-2D matches: P3P minimal samples in RANSAC (MSAC), the linear
/// six-point resection on all inliers as a cross-check, then `refinePose` on the inliers and a
/// final inlier classification. Buffers are sized for `max_points` at construction; `estimate`
/// never allocates.
class PnpRansac {
 public:
  enum class Status { kOk, kTooFewPoints, kTooManyPoints, kNonFinite, kNoConsensus };
  explicit PnpRansac(int max_points);
  Status estimate(std::span<const Eigen::Vector3d> X, std::span<const Eigen::Vector2d> normalized,
                  const PnpOptions& options, PnpResult& result);

 private:
  int max_points_;
  std::vector<uint8_t> mask_;
};

const char* toString(PnpRansac::Status s);

}  // namespace epitrack

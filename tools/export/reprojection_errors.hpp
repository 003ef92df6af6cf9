#pragma once

// Reprojection errors of a Reconstruction from its own data (intrinsics with k1/k2, poses, points,
// observations), so that summary.json, the COLMAP ERROR column and the report agree with the
// exported model whatever the solver computed internally.

#include "tools/export/reconstruction.hpp"

namespace epitrack::io {

/// Projects a world point into a solved camera with the ARCHITECTURE.md model (pinhole + radial
/// k1, k2 on normalized coordinates). False when the point is not in front of the camera.
bool projectPoint(const CameraIntrinsics& k, const SolvedCamera& camera, const Eigen::Vector3d& X,
                  Eigen::Vector2d& pixel);

/// Projects a world point into a solved camera of `rec`: projectPoint above for a global shutter;
/// with a rolling shutter (Reconstruction::readout_frames > 0) at the row where the point is seen,
/// from the camera's reference-row pose and its motion over the readout
/// (algo/geometry/rolling_shutter.hpp). False when it is behind the camera or no row sees it.
bool projectPoint(const Reconstruction& rec, const SolvedCamera& camera, const Eigen::Vector3d& X,
                  Eigen::Vector2d& pixel);

/// Fills PointObservation::residual_px (pixel distance between the observation and the
/// projection; NaN when the frame is unsolved, the point missing or behind the camera), the mean
/// per solved camera (SolvedCamera::mean_reproj_px, inliers = observations counted), the mean per
/// point (ScenePoint::reproj_px, observations = count) and the overall mean and median
/// (Reconstruction::mean_reproj_px / median_reproj_px), each point projected with the rolling
/// shutter when the reconstruction has one. Observations whose residual exceeds
/// `outlier_px` (> 0), or whose point is behind the camera, are marked PointObservation::outlier
/// and left out of every mean and count and of the COLMAP tracks, their residual still recorded.
void computeReprojectionErrors(Reconstruction& rec, double outlier_px = 0.0);

/// The row-shear test (algo/sfm/row_misfit.hpp) on the residuals computeReprojectionErrors left
/// (outliers out): does the camera model, global or rolling shutter, explain the image rows?
RowMisfit rowMisfitOf(const Reconstruction& rec, const RowMisfitOptions& options = {});

}  // namespace epitrack::io

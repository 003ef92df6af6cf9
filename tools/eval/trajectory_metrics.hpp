#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hal/io/text_formats.hpp"

namespace epitrack::eval {

/// A similarity transform x -> s R x + t.
struct Similarity {
  double s = 1.0;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  [[nodiscard]] Eigen::Vector3d apply(const Eigen::Vector3d& x) const { return s * (R * x) + t; }
};

/// Least-squares similarity mapping `source` onto `target` (Umeyama 1991, "Least-squares
/// estimation of transformation parameters between two point patterns", eqs. 40-42), with the
/// reflection fix. Needs at least 3 non-collinear points for a unique rotation; with fewer, or
/// with a degenerate spread, returns false.
bool umeyamaAlignment(const std::vector<Eigen::Vector3d>& source,
                      const std::vector<Eigen::Vector3d>& target, Similarity& out);

/// As umeyamaAlignment, with the camera orientations breaking near-ties of the rotation:
/// `orientation_sum` is the sum over the matched frames of R_target,i R_source,iᵀ, added to the
/// positions' cross-covariance with a weight of kOrientationTieBreak times its largest singular
/// value. Rotation directions the positions determine keep their least-squares value (to
/// ~1e-4); those they leave (nearly) free — about a straight path (a car, a dolly), about the
/// thin axis of a sideways walk — are taken from the orientations instead of from noise. The
/// scale is then the least-squares scale for that rotation.
bool umeyamaAlignment(const std::vector<Eigen::Vector3d>& source,
                      const std::vector<Eigen::Vector3d>& target,
                      const Eigen::Matrix3d& orientation_sum, Similarity& out);
constexpr double kOrientationTieBreak = 1e-4;

/// The figures of `epitrack-eval` (ARCHITECTURE.md "Commands").
struct TrajectoryMetrics {
  int matched_frames = 0;
  int gt_frames = 0;
  int est_frames = 0;
  double ate_rmse = 0.0;      ///< RMSE of camera centres after the similarity alignment (GT units)
  double ate_rmse_rel = 0.0;  ///< ate_rmse / GT path length over the matched frames
  double ate_max = 0.0;
  double gt_path_length = 0.0;
  double scale = 1.0;             ///< s of the alignment (GT units per estimate unit)
  double rot_err_deg_mean = 0.0;  ///< mean angle of R_gt^T (R_align R_est)
  double rot_err_deg_max = 0.0;
  /// The second alignment: the rotation is the orientations' own best (the chordal mean of
  /// R_gt,i R_est,iᵀ), the scale and translation the centres' least squares for it. On a thin
  /// path (a walk, a dolly) the centres fix the rotation about the path's long axis only through
  /// their narrow spread across it, where millimetres of error tilt it by degrees: when these two
  /// figures are both small, one similarity fits orientations and centres together and a larger
  /// rot_err_deg_mean is the position alignment's. Alone, rot_err_deg_*_orient_aligned is blind
  /// to every orientation turned the same way against the path, which rot_err_deg_* sees.
  double rot_err_deg_mean_orient_aligned = 0.0;
  double rot_err_deg_max_orient_aligned = 0.0;
  double ate_rmse_orient_aligned = 0.0;  ///< GT units, as ate_rmse
  double rpe_trans_rel = 0.0;     ///< sum over consecutive matched pairs of |relative translation
                                  ///< error| / sum of GT steps
  double rpe_rot_deg_mean = 0.0;  ///< mean angle error of the relative rotations
  bool aligned = false;  ///< false when fewer than 3 frames matched or the centres are collinear
};

/// Associates poses by frame index (equal `t` within `max_dt`), aligns the estimate to the ground
/// truth with a similarity, and computes the metrics. Returns false (with `error`) when fewer than
/// two frames match.
bool evaluateTrajectory(const std::vector<hal::TrajectoryEntry>& gt,
                        const std::vector<hal::TrajectoryEntry>& est, double max_dt,
                        TrajectoryMetrics& metrics, std::string& error);

}  // namespace epitrack::eval

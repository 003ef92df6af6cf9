#pragma once

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "algo/geometry/rolling_shutter.hpp"
#include "algo/sfm/bundle_adjustment.hpp"

namespace epitrack {

/// One measurement of the rotation-only adjustment: scene direction `direction` seen by camera
/// `camera` at pixel `xy`.
struct RotationObservation {
  int camera = 0;
  int direction = 0;
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();
};

struct RotationAdjustmentOptions {
  int max_iterations = 30;
  double huber_px = 1.0;  ///< Huber loss threshold in pixels (<= 0: plain least squares)
  bool refine_focal = false;
  double initial_lambda = 1e-4;       ///< Levenberg-Marquardt damping (relative to the diagonal)
  double function_tolerance = 1e-10;  ///< stop when the relative cost decrease falls below
  /// Rolling shutter (line_delay > 0): each row is exposed at its own time and each camera's
  /// rotation over the readout is the trajectory's (the central difference of its neighbours'
  /// rotations, BundleAdjuster::solveTrajectory's smooth-trajectory model without translation).
  /// The row of an observation is the row it was measured on (its y): the measured row differs
  /// from the predicted one by the noise, a line delay of 1/500 frame per row makes that ~1e-3
  /// frame, far below anything the rotations resolve.
  RollingShutter shutter;
};

struct RotationAdjustmentSummary {
  bool converged = false;  ///< a tolerance was met (else the iterations ran out or it failed)
  bool failed = false;     ///< invalid input or the normal equations would not factor
  int iterations = 0;
  double initial_rms_px = 0.0;  ///< RMS reprojection error before and after (plain, not robust)
  double final_rms_px = 0.0;
};

/// The bundle adjustment of a rotating camera (a tripod, Hartley 1997; the nodal pan of a
/// matchmove): every centre at the origin, so a scene point is a direction d (unit vector, two
/// degrees of freedom) and x ~ K R_cw d. Levenberg-Marquardt with the Schur complement on the
/// directions (2x2 blocks); the reduced system (3 per free camera, the focal) is dense. It
/// refines the rotations chained from the pairwise homographies, which drift and take each
/// homography's conditioning (a 20-point overlap at one image edge) as it comes.
/// Rotations are updated on the left, R <- exp([dtheta]x) R. Gauge: at least one camera fixed.
class RotationAdjuster {
 public:
  RotationAdjuster(int max_cameras, int max_directions, int max_observations);

  /// Refines `rotations` (R_cw; except those with fixed[i] != 0), `directions` (world frame,
  /// unit) and, with options.refine_focal, intrinsics.f, in place. `neighbours` (one per camera,
  /// the cameras of the previous and next frame) is needed only with a rolling shutter.
  RotationAdjustmentSummary solve(std::span<Eigen::Matrix3d> rotations,
                                  std::span<const uint8_t> fixed,
                                  std::span<Eigen::Vector3d> directions,
                                  std::span<const RotationObservation> observations,
                                  std::span<const BaTrajectoryNeighbours> neighbours,
                                  BaIntrinsics& intrinsics,
                                  const RotationAdjustmentOptions& options);

 private:
  /// One observation's linearisation: its residual, the Jacobian on the direction's tangent
  /// and on up to kMaxColumns reduced-system columns (three cameras' rotations, the focal).
  static constexpr int kMaxColumns = 10;
  struct Linear {
    Eigen::Vector2d r = Eigen::Vector2d::Zero();
    Eigen::Matrix2d Jd = Eigen::Matrix2d::Zero();
    Eigen::Matrix<double, 2, kMaxColumns> Jg = Eigen::Matrix<double, 2, kMaxColumns>::Zero();
    int col[kMaxColumns] = {};
    int columns = 0;
    double weight = 0.0;  // Huber IRLS weight; 0: not seen (behind the camera)
  };
  double evaluate(std::span<const Eigen::Matrix3d> rotations,
                  std::span<const Eigen::Vector3d> directions,
                  std::span<const RotationObservation> observations,
                  std::span<const BaTrajectoryNeighbours> neighbours, const BaIntrinsics& k,
                  double huber, double* rms);
  void updateMotions(std::span<const Eigen::Matrix3d> rotations,
                     std::span<const BaTrajectoryNeighbours> neighbours);
  void linearise(std::span<const Eigen::Matrix3d> rotations,
                 std::span<const Eigen::Vector3d> directions,
                 std::span<const RotationObservation> observations,
                 std::span<const BaTrajectoryNeighbours> neighbours, const BaIntrinsics& k,
                 double huber);
  bool solveStep(double lambda, int directions);
  void subtractDirection(const Eigen::Matrix2d& Vinv, const Eigen::Vector2d& bv);

  int max_cameras_, max_directions_, max_observations_;
  RollingShutter shutter_;
  bool refine_focal_ = false;
  std::vector<int> camera_column_;        // first reduced-system column of a camera, -1 fixed
  int columns_ = 0;                       // reduced system size
  std::vector<Eigen::Vector3d> angular_;  // each camera's rotation over the readout (w)
  std::vector<Eigen::Matrix3d> dw_;       // dw / dtheta of previous, self, next (3 per camera)
  std::vector<Linear> linear_;            // per observation
  std::vector<int> obs_order_;            // observations grouped by direction
  std::vector<int> dir_offset_;           // obs_order_ range of each direction
  std::vector<int> cursor_;               // counting-sort cursor per direction
  std::vector<BaCamera> cameras_;         // the rotations as cameras (trajectoryMotion's input)
  Eigen::MatrixXd S_;                     // reduced system (undamped normal equations)
  Eigen::VectorXd g_;                     // its right-hand side
  Eigen::MatrixXd A_;                     // the damped Schur complement
  Eigen::VectorXd b_, step_;
  std::vector<Eigen::Matrix2d> V_;         // direction blocks (undamped)
  std::vector<Eigen::Vector2d> bv_;        // direction right-hand sides
  std::vector<Eigen::Vector2d> dstep_;     // direction steps
  Eigen::MatrixXd W_;                      // one direction's coupling (columns_ x 2)
  Eigen::MatrixXd WV_;                     // W V^-1 of the touched rows
  std::vector<int> touched_;               // reduced-system columns touched by one direction
  std::vector<std::pair<int, int>> runs_;  // touched_ as contiguous (first, count) runs
  std::vector<uint8_t> is_touched_;
  std::vector<Eigen::Matrix3d> rot_trial_;
  std::vector<Eigen::Vector3d> dir_trial_;
};

}  // namespace epitrack

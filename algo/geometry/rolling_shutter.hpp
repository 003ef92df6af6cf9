#pragma once

// A rolling-shutter camera (issue 27): image row y is exposed at its own time
//
//   tau(y) = line_delay * (y - reference_row)          [frame intervals]
//
// relative to the frame's reference row, whose pose is the frame's pose (the one a global-shutter
// solver, the exports and groundtruth.txt carry). Over one readout the camera moves with a
// constant angular velocity w (camera frame, rad per frame interval) and a constant velocity v of
// its centre (world frame, world units per frame interval):
//
//   R_wc(tau) = R_wc Exp(w tau),     c(tau) = c + v tau,
//   x_c(tau)  = Exp(w tau)^T R_cw (X - c - v tau).
//
// A point is seen on the row where the camera was when that row was exposed, so projection is a
// fixed point y = pi_y(x_c(tau(y))): starting from the reference pose's projection, each step
// re-projects with the pose of the row found; the map contracts when the image motion over a
// readout is smaller than the image (line_delay x row speed < 1); each step shrinks the row's
// error by that factor, about 0.06 for 3 deg per frame at 600 px focal and a 30 ms readout, so the
// row settles to 1e-3 px in 3-4 steps and to 1e-6 px in at most 6 (Meingast, Geyer & Sastry 2005;
// Hedborg et al. 2012 use the same per-frame constant-velocity model). line_delay = 0 is the global
// shutter, exactly.
//
// Units: a readout of R ms on a clip of P ms per frame and H rows is line_delay = R / (P H).

#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "algo/geometry/camera_intrinsics.hpp"
#include "algo/geometry/pose.hpp"

namespace epitrack {

/// When each row is exposed: tau(y) = line_delay (y - reference_row), in frame intervals.
struct RollingShutter {
  double line_delay = 0.0;     ///< frame intervals per row (0: global shutter)
  double reference_row = 0.0;  ///< the row whose pose is the frame's pose

  /// A readout of `readout_frames` frame intervals over `rows` rows, referred to `reference_row`.
  static RollingShutter fromReadout(double readout_frames, int rows, double reference_row) {
    RollingShutter rs;
    rs.line_delay = rows > 0 ? readout_frames / rows : 0.0;
    rs.reference_row = reference_row;
    return rs;
  }
  [[nodiscard]] double rowTime(double row) const { return line_delay * (row - reference_row); }
};

/// The camera's motion over one frame's readout.
struct RollingShutterMotion {
  Eigen::Vector3d angular = Eigen::Vector3d::Zero();  ///< w: camera frame, rad per frame interval
  Eigen::Vector3d linear = Eigen::Vector3d::Zero();   ///< v: world frame, units per frame interval
};

/// The pose (world to camera) at time `tau` of the readout, from the reference row's `pose`.
PoseCw poseAtTime(const PoseCw& pose, const RollingShutterMotion& motion, double tau);

enum class RollingShutterProjection : uint8_t {
  kOk,
  kBehindCamera,   ///< the point is not in front of the camera at the row found
  kNoConvergence,  ///< the fixed point did not settle (motion too fast for the readout)
};

struct RollingShutterPixel {
  Eigen::Vector2d px = Eigen::Vector2d::Zero();  ///< where the point is seen (distorted pixels)
  double tau = 0.0;                              ///< when its row was exposed
  int iterations = 0;
  RollingShutterProjection status = RollingShutterProjection::kOk;
};

/// The pixel where `X` is seen: the fixed point of the row (see the file comment); distortion
/// (k1, k2 of `k`) applied. `tolerance_px`: stop when the row moves less than this.
RollingShutterPixel projectRollingShutter(const CameraIntrinsics& k, const RollingShutter& shutter,
                                          const PoseCw& pose, const RollingShutterMotion& motion,
                                          const Eigen::Vector3d& X, int max_iterations = 10,
                                          double tolerance_px = 1e-6);

struct RollingShutterResectionOptions {
  int max_iterations = 20;
  /// Observations beyond this (pixels) get Huber weights (robust to a few bad matches).
  double huber_px = 2.0;
  /// Prior pulling w and v towards zero (per frame interval), weighted like this many pixels
  /// per radian and per world unit: keeps v defined when the points are far (v then has no
  /// image effect) without biasing a motion the rows observe.
  double velocity_prior = 1.0;
  double stop_step = 1e-10;  ///< stop when the update's norm falls below this
};

struct RollingShutterResectionResult {
  bool converged = false;
  int iterations = 0;
  double rms_px = 0.0;  ///< reprojection RMS over the observations after the refinement
};

/// Refines a frame's reference-row pose and its readout motion from 2D-3D correspondences
/// (`observed` in distorted pixels), starting from `pose` and `motion` (a global-shutter
/// resection and zero motion are fine starts): Gauss-Newton with a Levenberg damping over the 12
/// parameters (pose increment, w, v), numeric central-difference Jacobians of
/// projectRollingShutter. Fixed-size normal equations: never allocates.
RollingShutterResectionResult refineRollingShutterPose(
    const CameraIntrinsics& k, const RollingShutter& shutter, std::span<const Eigen::Vector3d> X,
    std::span<const Eigen::Vector2d> observed, PoseCw& pose, RollingShutterMotion& motion,
    const RollingShutterResectionOptions& options = {});

}  // namespace epitrack

#pragma once

// The offline solve of a rolling-shutter clip (issue 27 item 3), after the global-shutter solve:
// with the readout given, each solved frame's reference-row pose and its readout motion
// (algo/geometry/rolling_shutter.hpp) are refined on its points (the points fixed), then every
// point is triangulated again from the pose of the row it was seen on in each frame, and the two
// steps alternate (resection-intersection: each step lowers the same reprojection error, so the
// alternation converges to the joint optimum of poses, motions and points that a bundle adjustment
// with the motion parameters would reach, more slowly). A bundle adjustment with the readout in the
// projection (algo/sfm/bundle_adjustment.hpp) then refines poses, motions and points jointly
// (and the focal, when asked): the alternation only gives it a start in which every frame's
// motion is already near its value, so the adjustment's first linearisation is good.

#include <vector>

#include "algo/geometry/camera_intrinsics.hpp"
#include "algo/geometry/rolling_shutter.hpp"
#include "algo/sfm/solver.hpp"
#include "algo/sfm/track_table.hpp"

namespace epitrack {

/// The final adjustments' stop (SolverOptions::final_function_tolerance) of a global-shutter
/// solve that is only the refinement's start: the refinement moves every pose and point from
/// there (fast orbit: 1.47 -> 0.26 px), so 1e-4 instead of 1e-6 halves their time and the refined
/// cameras are the same (docs/rolling-shutter.md "Solve time").
inline constexpr double kRefinementStartTolerance = 1e-4;

/// The options of a general solve on tracks moved to their reference-row times (a given readout
/// of `readout_frames` frame intervals) whose result the refinement then takes over: the readout
/// and the refinement's start tolerance (epitrack-solve --readout-ms and its bench).
inline void solveForRefinement(SolverOptions& so, double readout_frames) {
  so.readout_frames = readout_frames;
  so.final_function_tolerance = kRefinementStartTolerance;
}

struct RollingShutterRefinementOptions {
  int rounds = 1;                    ///< resection + intersection alternations
  double reproj_threshold_px = 2.5;  ///< observations beyond this are left out of both steps
  RollingShutterResectionOptions resection;
  bool bundle_adjustment = true;  ///< the joint adjustment after the alternation
  bool refine_focal = false;      ///< also refine the focal (a self-calibrated solve's)
  int ba_iterations = 30;
  double huber_px = 1.0;  ///< the adjustment's Huber threshold
  /// > 0: a second adjustment with each frame's motion pulled towards the trajectory's motion at
  /// that frame (central differences of the refined poses), weighted like this many pixels per
  /// radian (per world unit for v). Free per-frame motions with free points are nearly
  /// degenerate (the scene bends to absorb them; Albl et al., "Degeneracies in rolling shutter
  /// SfM", ECCV 2016); the trajectory removes that. Needs the readout right (given).
  double trajectory_prior = 0.0;
  /// The smooth-trajectory model (BundleAdjuster::solveTrajectory): each frame's motion over the
  /// readout is the trajectory's at that frame (central differences of the neighbouring poses),
  /// not a parameter of its own; no resection-intersection rounds (the global-shutter poses give
  /// the motions). Replaces the per-frame motions and `trajectory_prior`.
  bool smooth_trajectory = false;
  /// With `smooth_trajectory`: also estimate the readout (one parameter; `shutter` is the start).
  bool refine_readout = false;
};

struct RollingShutterRefinementResult {
  int frames = 0;              ///< frames refined
  int points = 0;              ///< points triangulated again in the last round
  double rms_before_px = 0.0;  ///< reprojection RMS (rolling-shutter model, zero motion) before
  double rms_after_px = 0.0;   ///< and after
  int ba_iterations = 0;       ///< iterations of the joint adjustment (0: not run)
  int ba_observations = 0;
  /// The line delay at the end (the given one unless refine_readout) and its standard error
  /// (refine_readout), frame intervals per row.
  double line_delay = 0.0;
  double line_delay_std_error = 0.0;
};

/// Refines `frames` (reference-row poses), `points` and writes each frame's readout motion into
/// `motions` (one per frame; zero for unsolved frames). `K`: the solve's intrinsics (its focal
/// refined with `options.refine_focal`). With `options.smooth_trajectory` the motions are the
/// trajectory's and the readout may be estimated (result.line_delay). The first solved frame's pose
/// holds the gauge. Allocates its working buffers (once per solve, offline).
RollingShutterRefinementResult refineRollingShutter(const TrackTable& tracks, CameraIntrinsics& K,
                                                    const RollingShutter& shutter,
                                                    std::vector<SolvedFrame>& frames,
                                                    std::vector<MapPoint>& points,
                                                    std::vector<RollingShutterMotion>& motions,
                                                    const RollingShutterRefinementOptions& options);

/// Each frame's motion over the readout as the tripod solve's rotation-only adjustment modelled
/// it (Solver::refineTripod with a readout): the trajectory's angular velocity at the frame
/// (BundleAdjuster::trajectoryMotion: central differences of the solved neighbours' rotations,
/// one-sided at a gap), no linear motion. One per frame; zero for unsolved frames.
void rotationTrajectoryMotions(const std::vector<SolvedFrame>& frames,
                               std::vector<RollingShutterMotion>& motions);

/// The readout estimated from a refinement made with a nominal readout (issue 27, --readout auto).
///
/// With a free motion per frame the readout is not observable by itself: the projection depends
/// on the motions only through (line delay x w, line delay x v), so a refinement with any nonzero
/// readout reaches the same poses and points, its motions scaled by nominal / true readout. What
/// pins the readout is the frame-to-frame motion: the motion over a readout is the camera's motion
/// at that instant, which the neighbouring frames' poses also give (central differences). The
/// estimate is the least-squares slope of the fitted motions against the frame-to-frame ones,
/// both as the image motion they cause at the frame's median depth (rotation about the image axes
/// and sideways motion shear alike; their sum is what the rows observe):
///   readout = nominal x sum <m_fit, m_fd> / sum |m_fd|^2.
struct ReadoutEstimate {
  double readout_frames = 0.0;  ///< estimate, clamped to [0, 1] frame interval
  double std_error = 0.0;       ///< its standard error (frame intervals)
  int frames = 0;               ///< frames with both neighbours solved, used
  bool observable = false;      ///< enough frame-to-frame motion: std_error <= max_std_error
};

/// `motions` from refineRollingShutter with `nominal` (the frames and points it refined).
/// `max_std_error`: frame intervals (0.1: 3.3 ms at 30 fps).
ReadoutEstimate estimateReadout(const TrackTable& tracks, const RollingShutter& nominal, int rows,
                                const std::vector<SolvedFrame>& frames,
                                const std::vector<MapPoint>& points,
                                const std::vector<RollingShutterMotion>& motions,
                                double max_std_error = 0.1);

}  // namespace epitrack

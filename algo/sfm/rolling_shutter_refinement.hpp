#pragma once

// The offline solve of a rolling-shutter clip (issue 27 item 3), after the global-shutter solve:
// with the readout given, each solved frame's reference-row pose and its readout motion
// (algo/geometry/rolling_shutter.hpp) are refined on its points (the points fixed), then every
// point is triangulated again from the pose of the row it was seen on in each frame, and the two
// steps alternate (resection-intersection: each step lowers the same reprojection error, so the
// alternation converges to the joint optimum of poses, motions and points that a bundle adjustment
// with the motion parameters would reach, more slowly). The focal and the distortion stay as the
// global-shutter solve left them.

#include <vector>

#include "algo/geometry/camera_intrinsics.hpp"
#include "algo/geometry/rolling_shutter.hpp"
#include "algo/sfm/solver.hpp"
#include "algo/sfm/track_table.hpp"

namespace epitrack {

struct RollingShutterRefinementOptions {
  int rounds = 4;                    ///< resection + intersection alternations
  double reproj_threshold_px = 2.5;  ///< observations beyond this are left out of both steps
  RollingShutterResectionOptions resection;
};

struct RollingShutterRefinementResult {
  int frames = 0;              ///< frames refined
  int points = 0;              ///< points triangulated again in the last round
  double rms_before_px = 0.0;  ///< reprojection RMS (rolling-shutter model, zero motion) before
  double rms_after_px = 0.0;   ///< and after
};

/// Refines `frames` (reference-row poses), `points` and writes each frame's readout motion into
/// `motions` (one per frame; zero for unsolved frames). `K`: the solve's intrinsics. Allocates its
/// working buffers (once per solve, offline).
RollingShutterRefinementResult refineRollingShutter(
    const TrackTable& tracks, const CameraIntrinsics& K, const RollingShutter& shutter,
    std::vector<SolvedFrame>& frames, std::vector<MapPoint>& points,
    std::vector<RollingShutterMotion>& motions, const RollingShutterRefinementOptions& options);

}  // namespace epitrack

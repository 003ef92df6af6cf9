#pragma once

#include "algo/geometry/rolling_shutter.hpp"
#include "algo/sfm/track_table.hpp"

namespace epitrack {

/// The tracks as a global shutter would have seen them at each frame's reference-row time: each
/// observation, made at its row's time f + tau(y), is moved along its own track to time f by the
/// polynomial through the track's observations in frames f - 2 ... f + 2 at their true times
/// (Lagrange interpolation over those it has; unchanged when it has no other). The image motion
/// of a track is smooth where the camera's is, so the error is of high order in the motion over
/// the readout. Used where a model cannot carry the rolling shutter itself: the two-view tests of
/// the motion (a homography between rolling-shutter frames of a rotating camera is not one; its
/// residual reads as parallax) and the chained homographies of the tripod solve.
void shiftTracksToReferenceRow(const TrackTable& in, const RollingShutter& shutter,
                               TrackTable& out);

}  // namespace epitrack

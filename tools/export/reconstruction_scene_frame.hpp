#pragma once

// Glue between the solver's Reconstruction and algo/sfm/scene_frame: parse `--origin` and move
// a reconstruction into its scene frame before it is exported.

#include <string>

#include "algo/sfm/scene_frame.hpp"
#include "tools/export/reconstruction.hpp"

namespace epitrack::io {

/// Parses `--origin plane|first-camera|track:ID` into options.origin/track_id. False with a message
/// on anything else (the command exits with 2, bad usage).
bool parseOriginOption(const std::string& text, SceneFrameOptions& options, std::string& error);

/// Computes the scene frame from the solved cameras (the first solved one is the "first camera")
/// and the finite points, maps every camera pose and point into it, and records the outcome in
/// rec.origin, rec.plane_found and rec.origin_note. With kInvalidInput nothing is moved.
SceneFrame applySceneFrame(Reconstruction& rec, const SceneFrameOptions& options);

}  // namespace epitrack::io

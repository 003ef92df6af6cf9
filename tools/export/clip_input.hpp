#pragma once

// What the exports need to know of the clip itself, besides the solve: the frame files (COLMAP's
// images.txt names, the Blender and Nuke plates), a video input, and the frame rate.

#include <string>
#include <vector>

#include "tools/export/reconstruction.hpp"

namespace epitrack::io {

/// Fills rec.frame_names, rec.frames_dir, rec.input_movie and rec.fps.
/// `input`: the INPUT argument of epitrack-solve; `frame_paths[i]`: the file readable frame i was
/// read from (hal::Frame::path, empty for streams); `fps`: the source's nominal rate (0: unknown).
/// Frames from several directories (not produced by any source today) keep their base names only,
/// frames_dir then names the first frame's directory.
void describeClipInput(Reconstruction& rec, const std::string& input,
                       const std::vector<std::string>& frame_paths, double fps);

}  // namespace epitrack::io

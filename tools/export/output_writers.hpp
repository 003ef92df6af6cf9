#pragma once

// Writers of every output of epitrack-solve (ARCHITECTURE.md "File formats" and the epitrack-solve
// outputs): each format has a pure `format*` function returning the file's bytes (tested directly)
// and writeAllOutputs() writes them all atomically (temporary name + rename) into a directory.
// Conventions per file are documented at each function and in notes/README-outputs.md.

#include <cstdint>
#include <string>
#include <vector>

#include "tools/export/reconstruction.hpp"

namespace epitrack::io {

/// cameras.tum: `t tx ty tz qx qy qz qw`, T_wc, t = frame index (or timestamp when the clip has
/// them); unsolved frames omitted.
std::string formatCamerasTum(const Reconstruction& rec);

/// The sentence every export with room for a comment carries for a rolling-shutter solve (its
/// poses are the middle row's, the readout, where the motions are); "" for a global shutter.
std::string rollingShutterNote(const Reconstruction& rec);

/// rolling_shutter.txt (written when Reconstruction::readout_frames > 0): the readout line and
/// each solved frame's motion over its readout, `t wx wy wz vx vy vz` (docs/formats.md).
std::string formatRollingShutter(const Reconstruction& rec);

/// intrinsics.txt through hal::formatIntrinsics.
std::string formatIntrinsicsFile(const Reconstruction& rec);

/// points.ply: binary little-endian PLY, `float x y z` + `uchar red green blue` (gray repeated),
/// one vertex per scene point with finite coordinates, in Reconstruction::points order.
std::vector<uint8_t> formatPointsPly(const Reconstruction& rec);

/// summary.json: the ARCHITECTURE.md fields plus extras; non-finite numbers are written as null.
std::string formatSummaryJson(const Reconstruction& rec);
/// The same with `more_files` listed after `rec.files` in "files".
std::string formatSummaryJson(const Reconstruction& rec,
                              const std::vector<std::string>& more_files);

/// Mean and median reprojection error as summary.json reports them (see Reconstruction).
void reprojectionStatistics(const Reconstruction& rec, double& mean_px, double& median_px);

/// COLMAP text model (https://colmap.github.io/format.html). COLMAP puts the pixel origin at the
/// top-left corner of the top-left pixel, so cx, cy and every 2D point get +0.5. Camera model:
/// PINHOLE (no distortion), SIMPLE_RADIAL (fx = fy, k2 = 0), RADIAL (fx = fy) or OPENCV.
/// Image ids are frame index + 1; point ids are ours.
std::string formatColmapCameras(const Reconstruction& rec);
std::string formatColmapImages(const Reconstruction& rec, const ExportOptions& options);
std::string formatColmapPoints3D(const Reconstruction& rec);

/// What the COLMAP model holds (what `colmap model_analyzer` reports): registered images, points
/// (tracks of at least two images) and observations (the sum of the track lengths).
struct ColmapCounts {
  int64_t images = 0;
  int64_t points = 0;
  int64_t observations = 0;
  double mean_error_px = 0.0;  ///< mean of the points' ERROR column ("Mean reprojection error")
};
ColmapCounts colmapCounts(const Reconstruction& rec);

/// blender_camera.py: run in Blender (`blender --python blender_camera.py` or the Text Editor).
std::string formatBlenderScript(const Reconstruction& rec, const ExportOptions& options);

/// camera.chan (Nuke): `frame tx ty tz rx ry rz vfov`, Nuke's Y-up world and camera looking down
/// -Z, rotations in degrees for Nuke's default order ZXY (R = Ry * Rx * Rz), vfov in degrees.
/// The file cannot carry the principal point, fx (with fx != fy), the distortion, the frame rate
/// or the plate: camera.nk does, but the distortion.
std::string formatNukeChan(const Reconstruction& rec, const ExportOptions& options);

/// Nuke's lens for our intrinsics with a horizontal aperture (film back width) of `haperture_mm`:
/// Nuke projects x_ndc = 2 focal / haperture * X / -Z + win_translate_u, y_ndc likewise with
/// win_translate_v, in units of half the image width for both; pixels from the bottom-left corner:
/// x = (x_ndc + 1) W / 2, y = y_ndc W pixel_aspect / 2 + H / 2.
struct NukeLens {
  double focal_mm = 0.0;
  double haperture_mm = 0.0;
  double vaperture_mm = 0.0;
  double win_translate_u = 0.0;
  double win_translate_v = 0.0;
  double pixel_aspect = 1.0;  ///< the format's: pixel width / height = fy / fx
};
NukeLens nukeLens(const CameraIntrinsics& k, double haperture_mm);

/// camera.nk: a Nuke script with the Root frame range, fps and format, a Read node for the plate
/// (the input frames as a numbered sequence, or the video) and a Camera2 node keyed like
/// camera.chan (rot_order ZXY) with focal, haperture, vaperture and win_translate from nukeLens.
std::string formatNukeScript(const Reconstruction& rec, const ExportOptions& options);

/// The files writeAllOutputs() writes besides summary.json, relative to the directory, in the
/// order it writes them.
const std::vector<std::string>& exportFileNames();

/// Writes summary.json alone (atomically), e.g. for a run stopped before anything else existed.
bool writeSummaryJson(const Reconstruction& rec, const std::string& dir, std::string& error);

/// Writes cameras.tum, intrinsics.txt, points.ply, summary.json, colmap/{cameras,images,
/// points3D}.txt, blender_camera.py, camera.chan and camera.nk into `dir` (created if missing),
/// rolling_shutter.txt too when the solve has a readout (Reconstruction::readout_frames > 0),
/// then summary.json with `rec.files` plus these names as its "files". Returns false with a message
/// naming the file on the first failure.
bool writeAllOutputs(const Reconstruction& rec, const std::string& dir, std::string& error);
bool writeAllOutputs(const Reconstruction& rec, const std::string& dir,
                     const ExportOptions& options, std::string& error);

}  // namespace epitrack::io

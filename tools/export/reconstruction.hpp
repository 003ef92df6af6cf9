#pragma once

// The result of an offline solve (epitrack-solve, issue 6) as the exporters see it: the solver
// fills a Reconstruction and tools/export writes it to every output format of ARCHITECTURE.md.
// Plain data, no invariants beyond those documented per field; poses are T_wc (camera -> world)
// in the camera convention of ARCHITECTURE.md (x right, y down, z forward).
//
// Typical use at the end of epitrack-solve:
//   io::Reconstruction rec = ...;                        // filled by the solver
//   io::applySceneFrame(rec, options);                   // reconstruction_scene_frame.hpp
//   io::computeReprojectionErrors(rec);                  // reprojection_errors.hpp
//   if (!io::writeAllOutputs(rec, out_dir, error)) ...   // output_writers.hpp
// with io::ProgressReporter (progress.hpp) reporting the stages on stderr.

#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "algo/geometry/camera_intrinsics.hpp"
#include "algo/sfm/distortion_trial.hpp"
#include "algo/sfm/row_misfit.hpp"
#include "algo/sfm/view_pair_contradiction.hpp"

namespace epitrack::io {

/// Where a solve's rolling-shutter readout came from (summary.json "readout_source").
enum class ReadoutSource {
  kNone,       ///< a global-shutter solve: no "rolling_shutter" block
  kGiven,      ///< epitrack-solve --readout-ms
  kEstimated,  ///< epitrack-solve --readout auto
};

/// The summary.json name of a readout source ("given", "estimated"; "" for kNone).
inline const char* readoutSourceName(ReadoutSource source) {
  switch (source) {
    case ReadoutSource::kGiven:
      return "given";
    case ReadoutSource::kEstimated:
      return "estimated";
    case ReadoutSource::kNone:
      break;
  }
  return "";
}

/// Where the lens distortion (k1, k2) of a solve comes from.
enum class DistortionSource {
  kNone,       ///< a pinhole camera (--distortion none, or auto found no lens)
  kGiven,      ///< --intrinsics with k1 or k2
  kEstimated,  ///< --distortion k1 | k1k2
  kDetected,   ///< --distortion auto: the trial found the lens and kept its k1, k2
};

/// The summary.json name of a distortion source.
inline const char* distortionSourceName(DistortionSource source) {
  switch (source) {
    case DistortionSource::kGiven:
      return "given";
    case DistortionSource::kEstimated:
      return "estimated";
    case DistortionSource::kDetected:
      return "detected";
    case DistortionSource::kNone:
      break;
  }
  return "none";
}

/// The first `most` contradicted view pairs as "a-b (solve_inliers of best_inliers), ...": the
/// stderr warning and the report name them alike.
inline std::string contradictedPairsText(const std::vector<ViewPairContradiction>& pairs,
                                         std::size_t most) {
  std::string text;
  for (std::size_t i = 0; i < pairs.size() && i < most; ++i) {
    const ViewPairContradiction& c = pairs[i];
    text += (i == 0 ? "" : ", ") + std::to_string(c.a) + "-" + std::to_string(c.b) + " (" +
            std::to_string(c.solve_inliers) + " of " + std::to_string(c.best_inliers) + ")";
  }
  return text;
}

/// One frame of the clip. Unsolved frames may be listed (solved = false): they are omitted from
/// every trajectory export but counted in the summary.
struct SolvedCamera {
  int64_t frame = 0;       ///< frame index in the clip (0-based)
  double timestamp = 0.0;  ///< seconds, used by cameras.tum when Reconstruction::has_timestamps
  bool solved = false;
  Eigen::Matrix3d R_wc = Eigen::Matrix3d::Identity();                ///< camera-to-world rotation
  Eigen::Vector3d p_wc = Eigen::Vector3d::Zero();                    ///< camera centre in the world
  double mean_reproj_px = std::numeric_limits<double>::quiet_NaN();  ///< NaN: unknown
  int inliers = 0;        ///< observations used for this pose
  int features = 0;       ///< 2D features tracked in this frame (for the report), 0: unknown
  bool keyframe = false;  ///< used as a keyframe by the solver
  /// Rolling shutter (Reconstruction::readout_frames > 0): the camera's motion over this frame's
  /// readout (algo/geometry/rolling_shutter.hpp): w in the camera frame (rad per frame interval),
  /// v of the centre in the world (scene) frame (units per frame interval). R_wc and p_wc are the
  /// reference row's pose; row y's is R_wc Exp(w tau(y)), p_wc + v tau(y).
  Eigen::Vector3d rs_angular = Eigen::Vector3d::Zero();
  Eigen::Vector3d rs_linear = Eigen::Vector3d::Zero();
};

/// One triangulated scene point (world coordinates).
struct ScenePoint {
  int64_t id = 0;  ///< track id, >= 0 (COLMAP's POINT3D_ID; `--origin track:ID` refers to it)
  Eigen::Vector3d X = Eigen::Vector3d::Zero();
  uint8_t gray = 128;  ///< intensity for the point cloud colour
  double reproj_px = std::numeric_limits<double>::quiet_NaN();  ///< mean reprojection error
  int observations = 0;                                         ///< track length used
};

/// One 2D measurement of a scene point in a frame (pixel coordinates of ARCHITECTURE.md: origin at
/// the centre of the top-left pixel). Feeds COLMAP's images.txt/points3D.txt tracks.
struct PointObservation {
  int64_t frame = 0;
  int64_t point_id = 0;
  double x = 0.0;
  double y = 0.0;
  double residual_px =
      std::numeric_limits<double>::quiet_NaN();  ///< reprojection error, NaN: unknown
  /// The residual as a vector, observed minus projected (pixels; NaN: unknown).
  double residual_dx = std::numeric_limits<double>::quiet_NaN();
  double residual_dy = std::numeric_limits<double>::quiet_NaN();
  /// Left out of the model as an outlier (computeReprojectionErrors: residual above the outlier
  /// threshold, or the point behind the camera): not in any mean, count or COLMAP track.
  bool outlier = false;
};

/// One pairwise focal estimate of the self-calibration (for the report).
struct FocalEstimate {
  int64_t frame_a = 0;
  int64_t frame_b = 0;
  double focal_px = 0.0;
  bool coherent = false;  ///< agreed with the chosen value
};

/// One candidate of the focal profile (when F did not observe the focal; for the report).
struct FocalProfileEntry {
  double start_px = 0.0;
  double focal_px = 0.0;
  bool refined = false;
  double median_reproj_px = 0.0;
  int solved_frames = 0;
};

/// A run of consecutive frames, all solved or all unsolved for one cause (summary.json
/// "solved_ranges" and "unsolved_ranges", the report's gaps).
struct FrameRangeEntry {
  int64_t first = 0;
  int64_t last = 0;
  bool solved = false;
  std::string cause;   ///< unsolved: a short name ("tracks-lost", "too-little-parallax", ...)
  std::string reason;  ///< unsolved: what the cause means, in a few words
};

/// Wall time per solver stage, in the order they ran, plus the total.
struct StageSeconds {
  std::vector<std::pair<std::string, double>> stages;
  double total = 0.0;
};

/// Below this confidence of the cameras' up estimate the report and the command warn that the
/// scene's up may be wrong (the cameras' image-up axes spread over more than about 35 degrees).
constexpr double kWeakUpConfidence = 0.8;

/// The virtual object drawn into the augmented frames (--render; tools/solve/object_placement.hpp)
/// and how well it shows: the figures of issue 23.
struct AugmentedObject {
  std::string placement;  ///< "auto" (chosen from the solve), "given" (--object-at/--object-scale)
                          ///< or "" (nothing rendered)
  Eigen::Vector3d at = Eigen::Vector3d::Zero();              ///< scene frame, on the ground
  double scale = 1.0;                                        ///< the object's size factor
  double height = std::numeric_limits<double>::quiet_NaN();  ///< scene units, base to top
  int solved_frames = 0;                                     ///< frames with a camera pose
  int visible_frames = 0;  ///< of those, frames where it covers >= 0.5 % of the image
  double median_coverage = std::numeric_limits<double>::quiet_NaN();  ///< image fraction, 0..1
  /// Median over the solved frames of the cosine between the scene's +z drawn at the object and
  /// the image's up direction (1: upright, -1: upside down).
  double upright_cosine_median = std::numeric_limits<double>::quiet_NaN();
};

/// The whole solve. Fields left at their defaults are written as "unknown" (null in JSON).
struct Reconstruction {
  CameraIntrinsics intrinsics;        ///< includes width, height, k1, k2
  std::vector<SolvedCamera> cameras;  ///< ordered by frame
  std::vector<ScenePoint> points;     ///< ids unique
  std::vector<PointObservation> observations;
  int frames = 0;               ///< frames in the clip (>= cameras.size() of solved ones)
  int skipped_frames = 0;       ///< corrupt or missing frames skipped while reading the input
  bool has_timestamps = false;  ///< cameras.tum uses SolvedCamera::timestamp instead of the index

  std::string focal_source = "given";  ///< "given", "self-calibrated" or "fallback"
  bool focal_observable = true;
  /// > 0: the focal was given (--intrinsics or --focal) and refined from this value
  /// (epitrack-solve --refine-focal); summary.json says focal_refined and focal_given_px.
  double focal_given_px = 0.0;
  /// Rolling shutter (epitrack-solve --readout-ms): readout in ms (0: global shutter), the row
  /// whose pose the frame's pose is, and the reprojection RMS of the rolling-shutter refinement
  /// before and after it (summary.json "rolling_shutter").
  double readout_ms = 0.0;
  double readout_reference_row = 0.0;
  /// The readout the cameras' motions (SolvedCamera::rs_angular, rs_linear) were solved with, in
  /// frame intervals from the first row to the last; 0: global shutter, no motion (nothing
  /// written to rolling_shutter.txt, frames rendered with one pose).
  double readout_frames = 0.0;
  double readout_rms_before_px = 0.0;
  double readout_rms_after_px = 0.0;
  int readout_ba_iterations = 0;  ///< the joint rolling-shutter adjustment's iterations
  ReadoutSource readout_source = ReadoutSource::kNone;
  /// --readout auto: the estimate's standard error was small (at most 0.1 frame interval).
  bool readout_observable = true;
  double readout_std_error_ms = 0.0;  ///< --readout auto: that standard error
  /// --readout auto: the model was kept (false: the estimate was not significantly above zero,
  /// and the global-shutter solve is written unchanged).
  bool readout_applied = true;
  /// The lens distortion's source (summary.json "distortion"): kNone (a pinhole camera),
  /// kGiven (--intrinsics with k1 or k2), kEstimated (--distortion k1|k1k2), kDetected
  /// (--distortion auto found the lens: the trial's figures below).
  DistortionSource distortion_source = DistortionSource::kNone;
  DistortionTrial distortion_trial;  ///< --distortion auto's trial (tried: it ran)
  /// Whether the camera model explains the rows (algo/sfm/row_misfit.hpp, computed from the
  /// residuals by io::rowMisfitOf; summary.json "row_misfit" when frames_tested > 0).
  RowMisfit row_misfit;
  std::string motion = "general";  ///< "general", "planar-scene", "rotation-only", ...
  std::string matcher;             ///< 2D tracks from "lk" or "descriptors" ("": not told)
  /// "ok" (at least 90 % of the frames solved), "partial" (a reconstruction of fewer; see
  /// frame_ranges), "trajectory-uncertain" (the camera centres not determined; see
  /// centre_sd_steps), or the reason the solve failed.
  std::string status = "ok";
  std::string message;  ///< optional human sentence about the status
  /// How well the final adjustment determines the camera centres: the RMS of their standard
  /// deviations in percent of the path length and in mean frame-to-frame steps, and the limit
  /// (steps) beyond which the status is "trajectory-uncertain" (summary.json
  /// "centre_uncertainty"; negative: not measured).
  double centre_sd_percent = -1.0;
  double centre_sd_steps = -1.0;
  double centre_sd_limit_steps = 0.0;
  /// Key frames: the pairs of solved views checked against their own matches (summary.json
  /// "view_pair_check"; negative: not checked, a video solve) and those contradicted, worst first.
  int view_pairs_checked = -1;
  std::vector<ViewPairContradiction> contradicted_view_pairs;
  /// A tripod solve's rotation-only adjustment (summary.json "tripod_adjustment"; iterations < 0:
  /// not run): RMS reprojection error before and after, iterations, and whether it modelled each
  /// row's time (a rolling shutter with --readout-ms).
  double tripod_rms_before_px = 0.0;
  double tripod_rms_after_px = 0.0;
  int tripod_iterations = -1;
  bool tripod_rows_modelled = false;
  /// When a stop signal ended the run early (status "interrupted"): the signal ("SIGINT",
  /// "SIGTERM"), the stage it stopped ("tracking", "calibration", ...) and, when the solve itself
  /// had finished, the solver's own status ("ok", "rotation-only", ...; empty otherwise).
  std::string interrupted_by;
  std::string interrupted_stage;
  std::string solve_status;
  /// Every output written besides summary.json, relative to the output directory ("files" in
  /// summary.json); summary.json is written last, so the list is complete when it exists.
  std::vector<std::string> files;
  std::vector<FocalEstimate> focal_estimates;
  /// How a fallback focal was chosen ("profile", "profile-flat", "field-of-view"; "" otherwise)
  /// and the profile behind it.
  std::string focal_fallback;
  std::vector<FocalProfileEntry> focal_profile;
  StageSeconds seconds;
  /// Solved and unsolved runs of frames in frame order (empty: not known; then not written).
  std::vector<FrameRangeEntry> frame_ranges;

  /// Reprojection statistics. NaN: computed by the summary from the observation residuals, or
  /// failing those from the points' reproj_px.
  double mean_reproj_px = std::numeric_limits<double>::quiet_NaN();
  double median_reproj_px = std::numeric_limits<double>::quiet_NaN();

  /// Scene frame (algo/sfm/scene_frame.hpp): the origin mode used and whether a plane was found.
  std::string origin = "plane";  ///< "plane", "first-camera" or "track:ID"
  bool plane_found = false;
  std::string origin_note;  ///< e.g. "no dominant plane: first-camera frame used"
  /// What the ground (z = 0, +z up) came from: "plane", "cameras" (the cameras' up, the ground
  /// under the points) or "none" (the first camera's frame, -y up).
  std::string ground = "none";
  /// The cameras' up estimate: confidence 0..1 and spread (degrees), NaN when not estimated.
  double up_confidence = std::numeric_limits<double>::quiet_NaN();
  double up_spread_deg = std::numeric_limits<double>::quiet_NaN();
  double plane_up_angle_deg = std::numeric_limits<double>::quiet_NaN();  ///< plane normal to up
  AugmentedObject object;

  /// Optional image file names per frame index (basename, e.g. "000012.png"), used by COLMAP's
  /// images.txt; frames beyond the vector are named from the index by ExportOptions.
  std::vector<std::string> frame_names;
  /// Absolute directory holding the frame_names files ("" when the input was not a directory of
  /// images): the plate of the Blender and Nuke scripts.
  std::string frames_dir;
  /// Absolute path of a video INPUT (MJPEG AVI, Y4M; "" otherwise): the plate when there are no
  /// frame files.
  std::string input_movie;
  /// Nominal frame rate of the clip (frames per second, as augmented.avi is written); 0: unknown,
  /// then the median timestamp interval when Reconstruction::has_timestamps.
  double fps = 0.0;
};

/// Settings of the exports that are not part of the solve.
struct ExportOptions {
  double sensor_width_mm = 36.0;         ///< Blender camera sensor width (horizontal fit)
  int image_name_digits = 6;             ///< COLMAP image name: zero-padded frame index ...
  std::string image_extension = ".png";  ///< ... plus this extension (when no frame_names)
  int blender_frame_offset = 1;  ///< Blender frame = frame index + offset (Blender starts at 1)
  int nuke_frame_offset = 0;     ///< Nuke frame = frame index + offset (Read node numbering)
};

}  // namespace epitrack::io

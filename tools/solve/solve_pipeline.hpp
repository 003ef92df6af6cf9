#pragma once

// The offline pipeline behind epitrack-solve: INPUT -> 2D tracks of the whole clip -> Solver ->
// Reconstruction (tools/export) in the scene frame -> outputs and augmented frames.

#include <optional>
#include <string>
#include <vector>

#include "algo/matching/descriptor_tracker.hpp"
#include "algo/sfm/scene_frame.hpp"
#include "algo/sfm/solver.hpp"
#include "algo/tracking/feature_tracker.hpp"
#include "tools/common/clip_tracker.hpp"
#include "tools/export/progress.hpp"
#include "tools/export/reconstruction.hpp"

namespace epitrack::tools {

struct SolveCommandOptions {
  std::string input;
  std::string out_dir;
  std::string mask;  ///< PGM or directory of PGMs (0 = never track)
  /// tracks.csv to solve instead of tracking INPUT (--tracks): another tracker's or an edited
  /// epitrack-track output; INPUT still gives the frame size, the clip length and the frames
  /// drawn by --render/--overlay.
  std::string tracks_file;
  std::string intrinsics_file;     ///< given intrinsics (focal, principal point, distortion)
  double focal_px = 0.0;           ///< given focal (0: self-calibrate)
  int distortion = 0;              ///< 0 none, 1 k1, 2 k1k2 (estimated)
  bool detect_distortion = false;  ///< --distortion auto (SolverOptions::detect_distortion)
  /// Rolling shutter (--readout-ms): the time from the first row's exposure to the last's, in
  /// milliseconds (0: a global shutter). The frames' poses are then the middle row's.
  double readout_ms = 0.0;
  /// --readout auto: the readout estimated (algo/sfm/rolling_shutter_refinement.hpp
  /// estimateReadout); the model is kept when the estimate is observable and clearly above zero.
  bool readout_auto = false;
  SceneFrameOptions scene;  ///< --origin (defaults tuned in the constructor)
  std::string origin_text = "plane";
  std::string render = "none";   ///< towers | cube | axes | none
  std::string overlay = "none";  ///< tracks: augmented frames side by side with the 2D tracks
  /// --object-at / --object-scale; what is not given is chosen (tools/render/object_placement.hpp).
  std::optional<Eigen::Vector3d> object_at;
  std::optional<double> object_scale;
  FeatureTrackerOptions tracker;
  Matcher matcher = Matcher::kAuto;   ///< --matcher: LK, descriptor matching, or chosen (auto)
  DescriptorTrackerOptions matching;  ///< the descriptor matcher (key frames)
  SolverOptions solver;
  io::ProgressReporter::Mode progress = io::ProgressReporter::Mode::kAuto;
  double max_memory_mib = 4096.0;  ///< refuse inputs whose buffers would need more (--max-memory)
  bool force = false;              ///< --force: replace the outputs of an earlier solve in out_dir
};

/// The files of an earlier solve in `dir` (relative names: summary.json, cameras.tum, ...,
/// augmented/NNNNNN.jpg); empty when there is none. Other files are never counted.
std::vector<std::string> previousSolveFiles(const std::string& dir);

/// Bytes the solve reserves up front for a clip of this size: the tracker's frame, pyramid,
/// gradient and template buffers plus the track table for `frames` frames (a lower bound of
/// the peak; the solver's own state is small beside it).
double estimateSolveMemoryBytes(int width, int height, int max_features, int window, long frames);

/// Exit code of a partial solve: every output written, but at least a tenth of the frames
/// (views) unsolved (status "partial"; summary.json lists the solved and unsolved ranges).
inline constexpr int kExitPartial = 3;
/// Exit code of a solve whose camera path the final adjustment leaves uncertain (status
/// "trajectory-uncertain"): every output written, rotations and focal solved, the centres'
/// standard deviation beyond the limit (summary.json centre_uncertainty).
inline constexpr int kExitTrajectoryUncertain = 4;
/// Exit code of a key-frame solve whose view pairs contradict it (status "inconsistent"):
/// every output written, the pairs named in summary.json view_pair_check.
inline constexpr int kExitInconsistent = 5;

/// Runs the whole solve and writes every output. Returns the process exit code: 0 solved (at
/// least 90 % of the frames; or a tripod solve of as many), 1 a runtime failure (summary.json
/// says why whenever the clip could be read), 2 an unusable INPUT, --intrinsics, --mask or --out
/// (one line on stderr, nothing written), 3 (kExitPartial) a partial solve, 4
/// (kExitTrajectoryUncertain) every frame solved but the camera path uncertain, 5
/// (kExitInconsistent) key frames registered but pairs of them contradicted by their matches, or
/// 128 + the signal (130 SIGINT, 143 SIGTERM) when a stop signal ended it early: then
/// summary.json has status "interrupted" and lists the consistent outputs written (see
/// tools/common/interrupt.hpp; the caller installs the handler).
int runSolve(const SolveCommandOptions& options);

}  // namespace epitrack::tools

#pragma once

// The state one epitrack-solve run carries from stage to stage, and the stages that live in
// their own files (solve_pipeline.cpp runs them in order, see runSolve). Internal to tools/solve.

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "algo/geometry/camera_intrinsics.hpp"
#include "algo/geometry/rolling_shutter.hpp"
#include "algo/image/image.hpp"
#include "algo/sfm/solver.hpp"
#include "algo/sfm/track_table.hpp"
#include "hal/frame_source.hpp"
#include "hal/io/tracks_csv.hpp"
#include "tools/common/clip_tracker.hpp"
#include "tools/common/mask_source.hpp"
#include "tools/export/progress.hpp"
#include "tools/export/reconstruction.hpp"
#include "tools/render/report_writer.hpp"
#include "tools/solve/solve_pipeline.hpp"

namespace epitrack::tools {

/// Seconds per stage into summary.json (wall time, steady clock).
class StageClock {
 public:
  explicit StageClock(io::StageSeconds& s) : s_(s), start_(now()), stage_start_(now()) {}
  void lap(const std::string& name) {
    const auto t = now();
    s_.stages.emplace_back(name, std::chrono::duration<double>(t - stage_start_).count());
    stage_start_ = t;
    s_.total = std::chrono::duration<double>(t - start_).count();
  }

 private:
  static std::chrono::steady_clock::time_point now() { return std::chrono::steady_clock::now(); }
  io::StageSeconds& s_;
  std::chrono::steady_clock::time_point start_, stage_start_;
};

/// What a stage returns: an exit code ends the run with it; nothing goes on to the next stage.
using StageResult = std::optional<int>;

struct SolveRun {
  explicit SolveRun(const SolveCommandOptions& options)
      : o(options), progress(options.progress), clock(rec.seconds) {}

  const SolveCommandOptions& o;
  io::ProgressReporter progress;
  io::Reconstruction rec;
  StageClock clock;
  std::string error;

  // The inputs (solve_inputs.cpp).
  SolverOptions so;        ///< the command line's, with the given intrinsics
  CameraIntrinsics given;  ///< --intrinsics, when have_given
  bool have_given = false;
  hal::SourceOptions source_options;
  std::unique_ptr<hal::FrameSource> source;
  bool given_tracks = false;  ///< --tracks: solve these instead of tracking
  std::vector<hal::TrackRow> given_rows;
  MaskSource masks;

  // The tracking pass (solve_tracking.cpp).
  std::unique_ptr<ClipTracker> tracker;
  TrackTable tracks;
  /// With --readout-ms: the tracks moved to each frame's middle-row time
  /// (shiftTracksToReferenceRow), the solver's input; `tracks` stays as exposed.
  TrackTable reference_row_tracks;
  std::unordered_map<int64_t, uint8_t> track_gray;  ///< each track's gray where first seen
  std::vector<int> features_per_frame;
  std::vector<double> timestamps;
  std::vector<std::string> frame_paths;  ///< the file of each readable frame, for the exports
  bool draw_frames = false;              ///< --render or --overlay: a second pass draws frames
  bool keep_frames = false;              ///< ... from frames kept in memory (stdin)
  std::vector<Image<uint8_t>> kept;
  int width = 0, height = 0, frames = 0, skipped = 0;
  std::string input_error;         ///< why reading stopped before the end of the stream, if it did
  bool decision_reported = false;  ///< the matcher's choice (auto) was said on stderr

  // The solve and what is written (solve_pipeline.cpp, solve_render.cpp).
  bool solve_ok = false;
  SolverSummary summary;
  /// The solver's frames and points, refined for a rolling shutter with --readout-ms.
  std::vector<SolvedFrame> solved_frames;
  std::vector<MapPoint> solved_points;
  /// Each frame's motion over the readout (indexed like solved_frames; empty without a rolling
  /// shutter), scaled to the readout written (rec.readout_frames).
  std::vector<RollingShutterMotion> motions;
  /// > 0: the focal the rolling-shutter adjustment refined (it replaces the solver's).
  double readout_focal_px = 0.0;
  /// rec_observation[i]: index into rec.observations of tracks.observations()[i], -1 when left out.
  std::vector<int> rec_observation;
  std::string stop_stage;  ///< the stage a stop signal ended after the solve, if one did
  render::ReportOptions report;

  /// Observations farther than this from their reprojection are outliers (the report's
  /// statistics and the --overlay tracks colours).
  [[nodiscard]] double outlierPx() const { return 2.0 * so.reproj_threshold_px; }
};

/// One line on stderr: "epitrack-solve: WHAT".
void fail(const char* what);
/// Ends a run stopped by SIGINT/SIGTERM before any output but summary.json was consistent:
/// summary.json (atomically) says so and lists no other file. Returns the exit code.
int stopInterrupted(io::Reconstruction& rec, const std::string& out_dir, const char* stage,
                    const std::string& detail);

/// Removes the files of an earlier solve (--force) and the folders they leave empty; nothing else.
bool removePreviousSolve(const std::string& dir, const std::vector<std::string>& files,
                         std::string& error);

/// --intrinsics / --focal into run.so (exit 2 on a bad file).
StageResult readGivenIntrinsics(SolveRun& run);
/// Opens INPUT and reads --tracks, checked before anything is written (exit 2).
StageResult openInputs(SolveRun& run);
/// --mask opened, an earlier solve in --out refused (or removed with --force), --out created.
StageResult prepareOutputDir(SolveRun& run);
/// Reads (and unless --tracks, tracks) every frame of INPUT.
StageResult trackClip(SolveRun& run);
/// The track table of the clip (the tracker's or --tracks'); a stop signal or no frame ends here.
StageResult finishTracks(SolveRun& run);
/// DIR/augmented/*.jpg, augmented.avi and scene_frame.jpg, when --render or --overlay asks.
StageResult renderAugmented(SolveRun& run, int solved_frames);

}  // namespace epitrack::tools

// epitrack-bench rolling-shutter: the solve of a rolling-shutter clip with the model (the readout
// given) against the global-shutter solve of the same clip (issue 27: "solve time with the model
// <= 1.5x the global-shutter solve on the same clip"), both from the same 2D tracks, with their
// accuracy against the clip's ground truth. Without INPUT it renders the fast orbit of
// docs/rolling-shutter.md (640x480, 120 frames, 0.75 degree of arc per frame, a 0.9-frame
// readout, focal 600). The model's solve is what `epitrack-solve --readout-ms` runs: the solver on
// the tracks moved to their frames' middle-row time, then the smooth-trajectory refinement on the
// tracks as exposed (tools/solve/solve_pipeline.cpp, solverTracks and refineReadout).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <string>
#include <vector>

#include "algo/geometry/camera_intrinsics.hpp"
#include "algo/geometry/rolling_shutter.hpp"
#include "algo/image/image.hpp"
#include "algo/sfm/rolling_shutter_refinement.hpp"
#include "algo/sfm/rolling_shutter_tracks.hpp"
#include "algo/sfm/solver.hpp"
#include "algo/sfm/track_table.hpp"
#include "algo/tracking/feature_tracker.hpp"
#include "tools/bench/bench_input.hpp"
#include "tools/bench/bench_registry.hpp"
#include "tools/common/clip_tracker.hpp"
#include "tools/common/command_line.hpp"
#include "tools/eval/trajectory_metrics.hpp"
#include "tools/synth/synthetic_sequence.hpp"

namespace epitrack::bench {
namespace {

/// Processor time in seconds: the solves run on this one thread.
double cpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

struct RollingSolveRun {
  double solve = 0.0;       ///< calibration to the global adjustment
  double refinement = 0.0;  ///< the rolling-shutter refinement (0 for the global shutter)
  [[nodiscard]] double total() const { return solve + refinement; }
  std::string status;
  int solved = 0;
  double rms_px = 0.0;  ///< the refinement's reprojection RMS after (the model's run)
  std::vector<hal::TrajectoryEntry> poses;
};

void collectPoses(const std::vector<SolvedFrame>& frames, RollingSolveRun& run) {
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const SolvedFrame& s = frames[f];
    if (!s.solved) continue;
    hal::TrajectoryEntry e;
    e.t = static_cast<double>(f);
    e.position = s.pose.centre();
    e.rotation = Eigen::Quaterniond(s.pose.R_cw.transpose()).normalized();
    run.poses.push_back(e);
    ++run.solved;
  }
}

/// One solve from `tracks` (as exposed), the focal given; with `readout_frames` > 0 the model's.
RollingSolveRun solveClip(const TrackTable& tracks, int width, int height, double focal,
                          double readout_frames) {
  RollingSolveRun run;
  const double t0 = cpuSeconds();
  SolverOptions so;
  so.focal_px = focal;
  const RollingShutter shutter =
      RollingShutter::fromReadout(readout_frames, height, 0.5 * (height - 1));
  TrackTable reference_row_tracks;
  const bool rolling = readout_frames > 0.0;
  if (rolling) {
    solveForRefinement(so, readout_frames);  // as epitrack-solve --readout-ms
    shiftTracksToReferenceRow(tracks, shutter, reference_row_tracks);
  }
  Solver solver(rolling ? reference_row_tracks : tracks, width, height, so);
  if (rolling) solver.setExposedTracks(&tracks);
  const bool ok =
      solver.calibrate() && solver.initialize() && solver.registerFrames() && solver.finalize();
  (void)ok;  // the status says it
  const double t1 = cpuSeconds();
  run.solve = t1 - t0;
  run.status = toString(solver.status());
  std::vector<SolvedFrame> frames = solver.frames();
  if (!rolling || solver.solvedFrames() == 0) {
    collectPoses(frames, run);
    return run;
  }
  const SolverSummary s = solver.summary();
  CameraIntrinsics K = CameraIntrinsics::centered(width, height, s.focal_px);
  K.cx = s.cx;
  K.cy = s.cy;
  std::vector<MapPoint> points = solver.points();
  std::vector<RollingShutterMotion> motions;
  RollingShutterRefinementOptions ro;  // as epitrack-solve --readout-ms (refineReadout)
  ro.reproj_threshold_px = 2.0 * so.reproj_threshold_px;
  ro.smooth_trajectory = true;
  const auto r = refineRollingShutter(tracks, K, shutter, frames, points, motions, ro);
  run.refinement = cpuSeconds() - t1;
  run.rms_px = r.rms_after_px;
  collectPoses(frames, run);
  return run;
}

double medianOf(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

double medianTotal(const std::vector<RollingSolveRun>& runs) {
  std::vector<double> v;
  for (const auto& r : runs) v.push_back(r.total());
  return medianOf(v);
}

void report(const char* impl, const std::vector<RollingSolveRun>& runs,
            const std::vector<hal::TrajectoryEntry>& gt, int frames) {
  std::vector<double> solve, refinement;
  for (const auto& r : runs) {
    solve.push_back(r.solve);
    refinement.push_back(r.refinement);
  }
  const RollingSolveRun& last = runs.back();
  JsonLine j;
  j.add("bench", "rolling-shutter")
      .add("impl", impl)
      .add("clock", "process-cpu")
      .add("s_median", medianTotal(runs))
      .add("runs", runs.size())
      .add("solve_s", medianOf(solve))
      .add("refinement_s", medianOf(refinement))
      .add("status", last.status)
      .add("frames", frames)
      .add("solved_frames", last.solved);
  if (last.rms_px > 0.0) j.add("rms_after_px", last.rms_px);
  eval::TrajectoryMetrics m;
  std::string error;
  if (!gt.empty() && last.poses.size() >= 3 &&
      eval::evaluateTrajectory(gt, last.poses, 0.5, m, error))
    j.add("ate_rmse_rel_pct", 100.0 * m.ate_rmse_rel).add("rot_err_deg_mean", m.rot_err_deg_mean);
  j.print();
}

int runRollingShutter(int argc, const char* const* argv) {
  std::string input;
  int repeat = 5;
  int threads = 1;
  int frame_count = 120;
  double focal = 0.0;
  double readout = 0.9;
  tools::CommandLine cl("epitrack-bench rolling-shutter",
                        "[INPUT] [--repeat N] [--readout FRAMES] [--focal PX]",
                        "Times the solve of a rolling-shutter clip with the model (the readout\n"
                        "given) against its global-shutter solve, from the same tracks, focal\n"
                        "given. Without INPUT, renders the fast orbit of docs/rolling-shutter.md\n"
                        "(640x480, 120 frames, 0.75 deg/frame, readout 0.9 frame, focal 600) and\n"
                        "scores both against its ground truth.");
  cl.positional("INPUT", "frames to solve (any INPUT form); default: the rendered fast orbit",
                &input, false);
  cl.integer("repeat", "N", "solves per configuration (default 5; medians are reported)", &repeat,
             1, 100);
  cl.integer("threads", "N", "threads (only 1: every figure is single-core)", &threads, 1, 1);
  cl.integer("frames", "N", "frames to render or load (default 120)", &frame_count, 3, 100000);
  cl.real("readout", "FRAMES", "readout in frame intervals (default 0.9: 30 ms at 30 fps)",
          &readout, 0.001, 1.0);
  cl.real("focal", "PX", "the given focal for an INPUT (default: the rendered clip's 600)", &focal,
          1.0, 1e6);
  if (const auto r = cl.parse(argc, argv); r != tools::CommandLine::Result::kOk)
    return tools::CommandLine::exitCode(r);
  std::vector<Image<uint8_t>> frames;
  std::vector<hal::TrajectoryEntry> gt;
  std::string error;
  if (!input.empty() && !(focal > 0.0)) {
    std::fprintf(stderr, "epitrack-bench rolling-shutter: --focal is needed with an INPUT\n");
    return 2;
  }
  if (input.empty()) {
    synth::SynthOptions so;
    so.frames = frame_count;
    so.width = 640;
    so.height = 480;
    so.orbit_speed_deg = 0.75;
    so.readout = readout;
    focal = so.focal;
    const synth::SyntheticSequence seq(so);
    synth::FrameRenderer renderer(seq);
    frames.resize(static_cast<std::size_t>(frame_count));
    for (int i = 0; i < frame_count; ++i) {
      renderer.render(i, frames[static_cast<std::size_t>(i)]);
      const synth::Pose p = seq.pose(i);
      hal::TrajectoryEntry e;
      e.t = i;
      e.position = p.t_wc;
      e.rotation = Eigen::Quaterniond(p.R_wc).normalized();
      gt.push_back(e);
    }
  } else if (!loadBenchFrames(input, frame_count, frames, error)) {
    std::fprintf(stderr, "epitrack-bench rolling-shutter: %s\n", error.c_str());
    return 2;
  }
  FeatureTrackerOptions to;
  to.max_features = tools::kSolveFeatures;
  const TrackTable tracks = trackFrames(frames, to);
  const int w = frames.front().width();
  const int h = frames.front().height();
  const int n = static_cast<int>(frames.size());
  std::vector<RollingSolveRun> global, model;
  // Interleaved, so a slow spell of a shared machine falls on both.
  for (int r = 0; r < repeat; ++r) {
    global.push_back(solveClip(tracks, w, h, focal, 0.0));
    model.push_back(solveClip(tracks, w, h, focal, readout));
  }
  report("global-shutter", global, gt, n);
  report("rolling-shutter-model", model, gt, n);
  JsonLine()
      .add("bench", "rolling-shutter")
      .add("impl", "ratio")
      .add("ratio", medianTotal(model) / medianTotal(global))
      .print();
  return 0;
}

const BenchRegistrar kRegister(
    "rolling-shutter",
    "solve of a rolling-shutter clip with the model against its global-shutter solve",
    runRollingShutter);

}  // namespace
}  // namespace epitrack::bench

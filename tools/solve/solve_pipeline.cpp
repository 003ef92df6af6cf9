#include "tools/solve/solve_pipeline.hpp"

#include "algo/sfm/rolling_shutter_refinement.hpp"
#include "algo/sfm/rolling_shutter_tracks.hpp"
#include "tools/solve/solve_run.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <system_error>
#include <unordered_map>

#include "hal/frame_source.hpp"
#include "hal/io/file_util.hpp"
#include "hal/io/text_formats.hpp"
#include "hal/io/tracks_csv.hpp"
#include "tools/common/interrupt.hpp"
#include "tools/common/mask_source.hpp"
#include "tools/export/clip_input.hpp"
#include "tools/export/output_writers.hpp"
#include "tools/export/reconstruction_scene_frame.hpp"
#include "tools/export/reprojection_errors.hpp"
#include "tools/render/object_placement.hpp"
#include "tools/render/report_writer.hpp"

namespace epitrack::tools {

void fail(const char* what) { std::fprintf(stderr, "epitrack-solve: %s\n", what); }

namespace {

// Issue 23: say on stderr when the scene's up is a weak guess or the object hardly shows, so a
// first run on one's own clip does not silently give a wrong picture.
void warnAboutObject(const io::Reconstruction& rec, io::ProgressReporter::Mode progress) {
  if (progress == io::ProgressReporter::Mode::kQuiet) return;
  if (std::isfinite(rec.up_confidence) && rec.up_confidence < io::kWeakUpConfidence)
    std::fprintf(stderr,
                 "epitrack-solve: warning: the cameras disagree about up (confidence %.2f): the "
                 "ground may be tilted; check the augmented frames or give --origin\n",
                 rec.up_confidence);
  const io::AugmentedObject& obj = rec.object;
  if (obj.solved_frames > 0 && 2 * obj.visible_frames < obj.solved_frames)
    std::fprintf(stderr,
                 "epitrack-solve: warning: the object covers >= 0.5 %% of the image in only %d of "
                 "%d frames; try --object-at / --object-scale\n",
                 obj.visible_frames, obj.solved_frames);
}

// Every name epitrack-solve writes in its output directory, besides augmented/NNNNNN.jpg.
std::vector<std::string> solveOutputNames() {
  std::vector<std::string> names = {"summary.json"};
  names.insert(names.end(), io::exportFileNames().begin(), io::exportFileNames().end());
  names.insert(names.end(),
               {"rolling_shutter.txt", "report.html", "augmented.avi", "scene_frame.jpg"});
  return names;
}

// augmented/NNNNNN.jpg (six digits), the rendered frames.
bool isAugmentedFrameName(const std::string& name) {
  if (name.size() != 10 || name.compare(6, 4, ".jpg") != 0) return false;
  for (int i = 0; i < 6; ++i)
    if (name[static_cast<std::size_t>(i)] < '0' || name[static_cast<std::size_t>(i)] > '9')
      return false;
  return true;
}

}  // namespace

int stopInterrupted(io::Reconstruction& rec, const std::string& out_dir, const char* stage,
                    const std::string& detail) {
  rec.status = "interrupted";
  rec.interrupted_by = interruptSignalName();
  rec.interrupted_stage = stage;
  rec.message = std::string("stopped by ") + rec.interrupted_by + " during " + stage + " (" +
                detail + "); no output but summary.json was written";
  std::string error;
  if (!io::writeSummaryJson(rec, out_dir, error)) {
    fail(error.c_str());
    return 1;
  }
  std::fprintf(stderr, "epitrack-solve: interrupted: %s\n", rec.message.c_str());
  return interruptExitCode();
}

bool removePreviousSolve(const std::string& dir, const std::vector<std::string>& files,
                         std::string& error) {
  namespace fs = std::filesystem;
  for (const auto& f : files) {
    std::error_code ec;
    fs::remove(fs::path(dir) / f, ec);
    if (ec) {
      error = "cannot remove '" + (fs::path(dir) / f).string() + "': " + ec.message();
      return false;
    }
  }
  for (const char* sub : {"augmented", "colmap"}) {
    std::error_code ec;
    if (fs::is_directory(fs::path(dir) / sub, ec) && fs::is_empty(fs::path(dir) / sub, ec))
      fs::remove(fs::path(dir) / sub, ec);
  }
  return true;
}

std::vector<std::string> previousSolveFiles(const std::string& dir) {
  namespace fs = std::filesystem;
  std::vector<std::string> found;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return found;
  for (const auto& name : solveOutputNames()) {
    if (fs::exists(fs::path(dir) / name, ec)) found.push_back(name);
  }
  const fs::path augmented = fs::path(dir) / "augmented";
  if (fs::is_directory(augmented, ec)) {
    std::vector<std::string> frames;
    for (const auto& entry : fs::directory_iterator(augmented, ec)) {
      const std::string name = entry.path().filename().string();
      if (isAugmentedFrameName(name)) frames.push_back("augmented/" + name);
    }
    std::sort(frames.begin(), frames.end());
    found.insert(found.end(), frames.begin(), frames.end());
  }
  return found;
}

double estimateSolveMemoryBytes(int width, int height, int max_features, int window, long frames) {
  const double pixels = static_cast<double>(width) * static_cast<double>(height);
  // Frame (1 B/px) + pyramid (4/3 B/px) + Scharr gradients of a level (2 x 2 B/px) + detector
  // response and masks (~6 B/px); per feature, the LK templates of every level.
  const double per_frame = pixels * (1.0 + 4.0 / 3.0 + 4.0 + 6.0);
  const double templates =
      static_cast<double>(max_features) * 4.0 * static_cast<double>(window * window) * 8.0;
  const double track_table = static_cast<double>(frames) * static_cast<double>(max_features) *
                             static_cast<double>(sizeof(TrackObservation) + 8);
  return per_frame + templates + track_table;
}

namespace {

// The image size of --intrinsics must be the clip's (exit 2).
StageResult checkIntrinsicsSize(SolveRun& run) {
  const bool have_given = run.have_given;
  const CameraIntrinsics& given = run.given;
  const int width = run.width, height = run.height;
  if (have_given && (given.width != width || given.height != height)) {
    const std::string msg = "intrinsics are for " + std::to_string(given.width) + "x" +
                            std::to_string(given.height) + " but the frames are " +
                            std::to_string(width) + "x" + std::to_string(height);
    fail(msg.c_str());
    return 2;
  }
  return std::nullopt;
}

// The solver's four stages; a stop signal is looked at between them.
StageResult solveStages(SolveRun& run, Solver& solver) {
  const SolveCommandOptions& o = run.o;
  auto& progress = run.progress;
  auto& rec = run.rec;
  auto& clock = run.clock;
  const int width = run.width, height = run.height, frames = run.frames;
  progress.begin("solving", 4);
  // A stop signal is looked at between the solver's stages (each runs to its end). Before the
  // final adjustment has run the cameras are not final, and nothing but summary.json is written;
  // after it, the solve is complete and its exports are written (quickly) before stopping.
  const auto stopped = [&](const char* stage) {
    progress.end();
    const SolverSummary sum = solver.summary();
    rec.intrinsics = CameraIntrinsics::centered(width, height, sum.focal_px);
    rec.focal_source = toString(sum.focal_source);
    rec.focal_observable = sum.focal_observable;
    rec.motion = toString(sum.motion);
    return stopInterrupted(rec, o.out_dir, stage,
                           std::to_string(frames) + " frames tracked, solve not finished");
  };
  bool& ok = run.solve_ok;
  ok = solver.calibrate();
  clock.lap("calibration");
  progress.update(1);
  if (interruptRequested()) return stopped("calibration");
  ok = ok && solver.initialize();
  clock.lap("initialization");
  progress.update(2);
  if (interruptRequested()) return stopped("initialization");
  ok = ok && solver.registerFrames();
  clock.lap("registration");
  progress.update(3);
  if (interruptRequested()) return stopped("registration");
  ok = ok && solver.finalize();
  clock.lap("bundle_adjustment");
  progress.update(4);
  progress.end();
  // From here the solve is complete: a stop signal skips the rest of the rendering only.
  if (interruptRequested()) run.stop_stage = "bundle_adjustment";
  return std::nullopt;
}

// The solve as a Reconstruction (tools/export) in the scene frame, with every observation's
// reprojection error.
// What the solve found and how: intrinsics, focal source, status, the ranges of solved frames.
// summary.json "distortion": where k1, k2 come from, and --distortion auto's trial.
void recordDistortion(SolveRun& run, const SolverSummary& summary) {
  auto& rec = run.rec;
  rec.distortion_trial = summary.distortion_trial;
  if (summary.distortion_trial.detected)
    rec.distortion_source = io::DistortionSource::kDetected;
  else if (run.so.refine_distortion > 0)
    rec.distortion_source = io::DistortionSource::kEstimated;
  else if (run.so.k1 != 0.0 || run.so.k2 != 0.0)
    rec.distortion_source = io::DistortionSource::kGiven;
  else
    rec.distortion_source = io::DistortionSource::kNone;
}

void describeSolve(SolveRun& run, const Solver& solver) {
  const SolveCommandOptions& o = run.o;
  auto& rec = run.rec;
  const auto& so = run.so;
  const auto& input_error = run.input_error;
  const auto& source = run.source;
  run.summary = solver.summary();
  const SolverSummary& summary = run.summary;
  rec.intrinsics = CameraIntrinsics::centered(run.width, run.height, summary.focal_px);
  rec.intrinsics.cx = summary.cx;
  rec.intrinsics.cy = summary.cy;
  rec.intrinsics.fy = summary.focal_px * summary.aspect;
  rec.intrinsics.k1 = summary.k1;
  rec.intrinsics.k2 = summary.k2;
  rec.focal_source = toString(summary.focal_source);
  rec.focal_observable = summary.focal_observable;
  recordDistortion(run, summary);
  if (so.refine_given_focal && so.focal_px > 0.0) rec.focal_given_px = so.focal_px;
  rec.motion = toString(summary.motion);
  rec.status = toString(summary.status);
  rec.message = summary.message;
  rec.centre_sd_percent = summary.centre_sd_percent;
  rec.centre_sd_steps = summary.centre_sd_steps;
  rec.centre_sd_limit_steps = so.max_centre_sd_steps;
  rec.view_pairs_checked = summary.view_pairs_checked;
  rec.contradicted_view_pairs = summary.contradicted_pairs;
  rec.tripod_rms_before_px = summary.tripod_rms_before_px;
  rec.tripod_rms_after_px = summary.tripod_rms_after_px;
  rec.tripod_iterations = summary.tripod_iterations;
  rec.tripod_rows_modelled = summary.tripod_rows_modelled;
  if (!input_error.empty())
    rec.message = "input stopped early (" + input_error + "), frames after it are not solved" +
                  (rec.message.empty() ? std::string() : "; " + rec.message);
  rec.has_timestamps = source->info().real_timestamps;
  io::describeClipInput(rec, o.input, run.frame_paths, source->info().fps);
  rec.focal_fallback = toString(summary.focal_fallback);
  for (const auto& p : solver.focalProfile())
    rec.focal_profile.push_back(
        {p.start_px, p.focal_px, p.refined, p.median_reproj_px, p.solved_frames});
  for (const auto& p : solver.pairFocals()) {
    if (!p.observable) continue;
    rec.focal_estimates.push_back({p.frame_a, p.frame_b, p.focal_px, p.coherent});
  }
  for (const FrameRange& r : frameRanges(solver.frames()))
    rec.frame_ranges.push_back({r.first, r.last, r.solved, r.solved ? "" : toString(r.cause),
                                r.solved ? "" : describe(r.cause)});
}

// The cameras, the valid points and their observations in solved frames.
void collectGeometry(SolveRun& run) {
  auto& rec = run.rec;
  const auto& tracks = run.tracks;
  const int frames = run.frames;
  for (int f = 0; f < frames; ++f) {
    const auto& fr = run.solved_frames[static_cast<std::size_t>(f)];
    io::SolvedCamera c;
    c.frame = f;
    c.timestamp = run.timestamps[static_cast<std::size_t>(f)];
    c.solved = fr.solved;
    c.R_wc = fr.pose.R_cw.transpose();
    c.p_wc = fr.pose.centre();
    c.mean_reproj_px = fr.rms_px;
    c.inliers = fr.inliers;
    c.features = run.features_per_frame[static_cast<std::size_t>(f)];
    c.keyframe = fr.keyframe;
    if (static_cast<std::size_t>(f) < run.motions.size()) {
      c.rs_angular = run.motions[static_cast<std::size_t>(f)].angular;
      c.rs_linear = run.motions[static_cast<std::size_t>(f)].linear;
    }
    rec.cameras.push_back(c);
  }
  std::vector<char> point_valid(static_cast<std::size_t>(tracks.trackCount()), 0);
  for (const auto& p : run.solved_points) {
    if (!p.valid || !p.X.allFinite()) continue;
    io::ScenePoint sp;
    sp.id = tracks.trackId(p.track);
    sp.X = p.X;
    const auto g = run.track_gray.find(sp.id);
    sp.gray = g != run.track_gray.end() ? g->second : 128;
    sp.observations = p.observations;
    rec.points.push_back(sp);
    point_valid[static_cast<std::size_t>(p.track)] = 1;
  }
  std::vector<int>& rec_observation = run.rec_observation;
  rec_observation.assign(tracks.observations().size(), -1);
  for (std::size_t i = 0; i < tracks.observations().size(); ++i) {
    const auto& ob = tracks.observations()[i];
    if (!point_valid[static_cast<std::size_t>(ob.track)]) continue;
    if (!run.solved_frames[static_cast<std::size_t>(ob.frame)].solved) continue;
    rec_observation[i] = static_cast<int>(rec.observations.size());
    rec.observations.push_back({ob.frame, tracks.trackId(ob.track), ob.x, ob.y});
  }
}

// --readout-ms: the rolling-shutter refinement of the solved frames and points (issue 27): each
// frame's middle-row pose and its motion over the readout, the points from the rows' poses
// (algo/sfm/rolling_shutter_refinement.hpp). The readout in frame intervals needs the frame rate
// (the input's, 30 fps when it has none).
// The clip's frame rate (30 fps when the input has none): the readout in frame intervals.
double clipFps(const SolveRun& run) {
  return run.source->info().fps > 0.0 ? run.source->info().fps : 30.0;
}

// The solver's tracks. With a given readout, the tracks moved to each frame's middle-row time:
// the solve's two-view models (F, H and the tests of the motion between them, the focal from F,
// the chained homographies of a tripod) are global-shutter models, and a rolling shutter's
// shear otherwise reads as parallax (a panning camera is then not seen to rotate). The exact
// model follows: the rolling-shutter refinement of a general solve (refineReadout), the tripod
// solve's adjustment on the tracks as exposed (Solver::setExposedTracks).
const TrackTable& solverTracks(SolveRun& run) {
  // --readout auto: a tripod solve estimates the readout in its adjustment (on the tracks as
  // exposed); a general solve after it (refineReadout).
  run.so.estimate_readout = run.o.readout_auto;
  run.so.readout_min_frames = 0.001 * clipFps(run);
  if (!(run.o.readout_ms > 0.0)) return run.tracks;
  // The global-shutter solve on these tracks is only the refinement's start. Not with --readout
  // auto: its global-shutter solve is written as it is when no readout is found.
  solveForRefinement(run.so, run.o.readout_ms * clipFps(run) / 1000.0);
  shiftTracksToReferenceRow(
      run.tracks,
      RollingShutter::fromReadout(run.so.readout_frames, run.height, 0.5 * (run.height - 1)),
      run.reference_row_tracks);
  return run.reference_row_tracks;
}

// An estimated readout is "observable" (summary.json readout_observable) when its standard error
// is at most a tenth of a frame interval (3.3 ms at 30 fps), for the general and the tripod solve
// alike.
constexpr double kReadoutObservableFrames = 0.1;

// A tripod solve with a readout given or estimated (--readout auto): its rotation-only adjustment
// modelled each row's time on the tracks as exposed (Solver::refineTripod); the rolling_shutter
// block reports that adjustment, and each frame's motion over the readout is the trajectory's
// rotation it modelled. An estimate not kept leaves the global-shutter solve as it is.
void recordTripodReadout(SolveRun& run, const SolverSummary& s, double fps) {
  const bool given = run.o.readout_ms > 0.0;
  const double readout_frames = given ? run.o.readout_ms * fps / 1000.0 : s.tripod_readout_frames;
  run.rec.readout_ms = readout_frames * 1000.0 / fps;
  run.rec.readout_source = given ? io::ReadoutSource::kGiven : io::ReadoutSource::kEstimated;
  run.rec.readout_reference_row = 0.5 * (run.height - 1);
  run.rec.readout_rms_before_px = s.tripod_rms_before_px;
  run.rec.readout_rms_after_px = s.tripod_rms_after_px;
  run.rec.readout_ba_iterations = s.tripod_iterations;
  if (!given) {
    run.rec.readout_std_error_ms = s.tripod_readout_std_error * 1000.0 / fps;
    run.rec.readout_observable = s.tripod_readout_std_error <= kReadoutObservableFrames;
    run.rec.readout_applied = s.tripod_readout_applied;
    run.progress.message(
        "rolling shutter: readout estimated " + std::to_string(run.rec.readout_ms).substr(0, 5) +
        " ms +- " + std::to_string(run.rec.readout_std_error_ms).substr(0, 5) +
        " ms by the tripod adjustment" +
        (s.tripod_readout_applied ? "" : ", not used (global-shutter solve kept)"));
  }
  if (s.tripod_rows_modelled) {
    run.rec.readout_frames = readout_frames;
    rotationTrajectoryMotions(run.solved_frames, run.motions);
  }
  run.clock.lap("rolling_shutter");
}

// --readout auto on a fast pan: the readout whose middle-row tracks pass the tripod test best
// (the lowest ratio of the homography's residual to the noise, Solver::rotationCheck) on a grid
// of 0.1 frame interval; 0 when none passes. The test passes within about 15 % of the true
// readout on tracked fast pans (2.5 deg a frame, 30 ms), so the grid's step is fine enough: the
// tripod adjustment then estimates the readout itself.
double readoutForRotation(const SolveRun& run) {
  TrackTable shifted;
  double best = 0.0, best_ratio = std::numeric_limits<double>::infinity();
  for (int step = 1; step <= 10; ++step) {
    const double readout = 0.1 * step;
    shiftTracksToReferenceRow(
        run.tracks, RollingShutter::fromReadout(readout, run.height, 0.5 * (run.height - 1)),
        shifted);
    const RotationCheck check = Solver(shifted, run.width, run.height, run.so).rotationCheck();
    if (check.holds && check.ratio < best_ratio) {
      best = readout;
      best_ratio = check.ratio;
    }
  }
  return best;
}

// --readout auto when the tripod test refused a pan whose short frame pairs fit rotations
// (SolverSummary::rotation_refused) and the solve is not ok: a rolling shutter's shear on a fast
// pan reads as parallax over the wide windows. The clip is solved again on its tracks moved to the
// readout that makes them a rotation (readoutForRotation), its tripod adjustment estimating the
// readout on the tracks as exposed. That solve replaces the first when it is a tripod solve with
// the estimate applied; otherwise the first stands (a walking camera stays what it was).
std::unique_ptr<Solver> solveRollingShutterPan(SolveRun& run, const Solver& first) {
  const SolverSummary s = first.summary();
  if (!run.o.readout_auto || !s.rotation_refused || s.status == SolverStatus::kOk) return nullptr;
  run.progress.message(
      "rolling shutter: the pan's short pairs fit rotations; searching the "
      "readout that makes it a tripod");
  const double readout = readoutForRotation(run);
  if (!(readout > 0.0)) return nullptr;
  SolverOptions so = run.so;
  so.readout_frames = readout;
  shiftTracksToReferenceRow(
      run.tracks, RollingShutter::fromReadout(readout, run.height, 0.5 * (run.height - 1)),
      run.reference_row_tracks);
  auto solver = std::make_unique<Solver>(run.reference_row_tracks, run.width, run.height, so);
  solver->setExposedTracks(&run.tracks);
  if (solver->calibrate()) solver->initialize();  // a tripod solve ends in initialize
  const SolverSummary t = solver->summary();
  if (t.status != SolverStatus::kRotationOnly || !t.tripod_readout_applied) return nullptr;
  run.so = so;
  run.clock.lap("rolling_shutter_search");
  return solver;
}

void refineReadout(SolveRun& run, const Solver& solver) {
  run.solved_frames = solver.frames();
  run.solved_points = solver.points();
  const bool given = run.o.readout_ms > 0.0;
  if (!(given || run.o.readout_auto) || solver.solvedFrames() == 0) return;
  const double fps = clipFps(run);
  const SolverSummary s = solver.summary();
  if ((given && s.tripod_rows_modelled) || (!given && s.tripod_readout_frames >= 0.0)) {
    recordTripodReadout(run, s, fps);
    return;
  }
  CameraIntrinsics K = CameraIntrinsics::centered(run.width, run.height, s.focal_px);
  K.cx = s.cx;
  K.cy = s.cy;
  K.fy = s.focal_px * s.aspect;
  K.k1 = s.k1;
  K.k2 = s.k2;
  const double reference_row = 0.5 * (run.height - 1);
  // --readout auto starts the readout at half a frame interval and estimates it in the
  // adjustment: each frame's motion over the readout is the trajectory's (the smooth-trajectory
  // model), so the rows' shear against the motion between frames gives the readout.
  constexpr double kNominalReadoutFrames = 0.5;
  const double readout_frames = given ? run.o.readout_ms * fps / 1000.0 : kNominalReadoutFrames;
  const RollingShutter shutter =
      RollingShutter::fromReadout(readout_frames, run.height, reference_row);
  run.progress.message(
      "rolling shutter: refining " + std::to_string(solver.solvedFrames()) + " frames" +
      (given ? " with a " + std::to_string(run.o.readout_ms).substr(0, 5) + " ms readout"
             : ", readout to be estimated"));
  std::vector<RollingShutterMotion>& motions = run.motions;
  RollingShutterRefinementOptions options;
  options.reproj_threshold_px = 2.0 * run.so.reproj_threshold_px;
  options.smooth_trajectory = true;
  options.refine_readout = !given;
  // The focal is refined with the readout where the solve refined it: a global-shutter solve
  // absorbs part of the rows' shear into its focal.
  options.refine_focal = s.focal_source == FocalSource::kSelfCalibrated ||
                         s.focal_source == FocalSource::kFallback || run.so.refine_given_focal;
  const auto r = refineRollingShutter(run.tracks, K, shutter, run.solved_frames, run.solved_points,
                                      motions, options);
  run.rec.readout_reference_row = reference_row;
  run.rec.readout_rms_before_px = r.rms_before_px;
  run.rec.readout_rms_after_px = r.rms_after_px;
  run.rec.readout_ba_iterations = r.ba_iterations;
  bool keep = true;
  if (given) {
    run.rec.readout_ms = run.o.readout_ms;
    run.rec.readout_source = io::ReadoutSource::kGiven;
  } else {
    // No adjustment (no points: a rotation-only solve, or too few observations): no estimate.
    ReadoutEstimate e;
    if (r.ba_iterations > 0) {
      e.readout_frames = r.line_delay * (run.height - 1);
      e.std_error = r.line_delay_std_error * (run.height - 1);
    }
    e.observable = r.ba_iterations > 0 && std::isfinite(e.std_error) && e.std_error > 0.0 &&
                   e.std_error <= kReadoutObservableFrames;
    for (const auto& f : run.solved_frames) e.frames += f.solved ? 1 : 0;
    run.rec.readout_source = io::ReadoutSource::kEstimated;
    run.rec.readout_ms = e.readout_frames * 1000.0 / fps;
    run.rec.readout_std_error_ms = e.std_error * 1000.0 / fps;
    run.rec.readout_observable = e.observable;
    // Kept when clearly above zero (three standard errors and 1 ms): a global shutter's estimate
    // is zero within its error, and its solve is then written unchanged (the motions would only
    // fit noise). A kept estimate need not be well determined: on tracked clips its error is
    // several ms (the tracks' errors persist along each track; bundle_adjustment.cpp,
    // lineDelayStdErrors), still far nearer the truth than zero; readout_observable says which.
    keep = std::isfinite(e.std_error) && e.std_error > 0.0 &&
           e.readout_frames > std::max(3.0 * e.std_error, 0.001 * fps);
    run.rec.readout_applied = keep;
    run.progress.message("rolling shutter: readout estimated " +
                         std::to_string(run.rec.readout_ms).substr(0, 5) + " ms +- " +
                         std::to_string(run.rec.readout_std_error_ms).substr(0, 5) + " ms over " +
                         std::to_string(e.frames) + " frames" +
                         (keep ? "" : ", not used (global-shutter solve kept)"));
    if (!keep) {
      run.solved_frames = solver.frames();
      run.solved_points = solver.points();
      motions.clear();
    }
  }
  // The smooth-trajectory motions are the trajectory's per frame interval, whatever the readout
  // (the projection uses line delay x motion): written as they are, with the readout found.
  if (keep) run.rec.readout_frames = given ? readout_frames : run.rec.readout_ms * fps / 1000.0;
  if (keep && options.refine_focal && r.ba_iterations > 0) run.readout_focal_px = K.fx;
  run.clock.lap("rolling_shutter");
}

}  // namespace

// The solve as a Reconstruction (tools/export) in the scene frame, with every observation's
// reprojection error.
void buildReconstruction(SolveRun& run, const Solver& solver) {
  describeSolve(run, solver);
  if (run.readout_focal_px > 0.0) {
    run.rec.intrinsics.fy *= run.readout_focal_px / run.rec.intrinsics.fx;
    run.rec.intrinsics.fx = run.readout_focal_px;
  }
  collectGeometry(run);
  auto& rec = run.rec;
  if (solver.status() == Solver::Status::kOk || solver.status() == Solver::Status::kRotationOnly ||
      solver.status() == Solver::Status::kPartial ||
      solver.status() == Solver::Status::kTrajectoryUncertain ||
      solver.status() == Solver::Status::kInconsistent) {
    const auto sf = io::applySceneFrame(rec, run.o.scene);
    (void)sf;
  }
  io::computeReprojectionErrors(rec, run.outlierPx());
  rec.row_misfit = io::rowMisfitOf(rec);
  run.clock.lap("scene_frame");
}

namespace {

// The virtual object placed (unless given) and measured, and the report's options.
void placeObject(SolveRun& run, const Solver& solver) {
  const SolveCommandOptions& o = run.o;
  auto& rec = run.rec;
  auto& report = run.report;
  report.input = o.input;
  report.render_object = o.render;
  report.has_object = o.render != "none";
  if (report.has_object && solver.solvedFrames() > 0) {
    rec.object = render::placeObject(rec, o.render, o.object_at, o.object_scale,
                                     render::ObjectPlacementOptions{});
    render::measureObjectView(
        rec, render::makeObjectMesh(o.render, rec.object.at, rec.object.scale), rec.object);
    warnAboutObject(rec, o.progress);
  }
  report.object_at = rec.object.at;
}

// report.html and every export, the one-line result on stderr; returns the exit code.
// A stop signal after the solve: summary.json says which outputs are whole.
void markInterrupted(SolveRun& run) {
  auto& rec = run.rec;
  std::string& stop_stage = run.stop_stage;
  if (stop_stage.empty() && interruptRequested()) stop_stage = "exports";
  if (!stop_stage.empty()) {
    rec.solve_status = rec.status;
    rec.status = "interrupted";
    rec.interrupted_by = interruptSignalName();
    rec.interrupted_stage = stop_stage;
    rec.message =
        std::string("stopped by ") + rec.interrupted_by + " during " + stop_stage +
        " after the solve had finished (" + rec.solve_status +
        "); the solve's outputs were written" +
        (stop_stage == "rendering" ? ", the augmented frames only up to the stop" : std::string()) +
        (rec.message.empty() ? std::string() : "; " + rec.message);
  }
}

// What the result line says of a fallback focal (summary.json focal_fallback).
const char* fallbackNote(const std::string& fallback) {
  if (fallback == "profile") return ", from the reprojection profile";
  if (fallback == "converged") return ", the profile's refined solves converged on it";
  if (fallback == "profile-flat") return ", profile flat: a guess";
  return "";
}

// An estimated readout that was applied but is poorly determined (--readout auto) is said even
// under --quiet: the user may know the camera's readout better.
void printUncertainReadout(const io::Reconstruction& rec) {
  if (rec.readout_source != io::ReadoutSource::kEstimated || !rec.readout_applied ||
      rec.readout_observable)
    return;
  std::fprintf(stderr,
               "epitrack-solve: warning: the readout estimated, %.1f ms +- %.1f ms, is applied "
               "but poorly determined; give --readout-ms MS if the camera's readout is known\n",
               rec.readout_ms, rec.readout_std_error_ms);
}

// Key-frame view pairs whose own matches contradict the solve are said even under --quiet when
// the status does not already say so (a partial solve): the poses near them are likely wrong
// although their reprojection errors look fine.
void printContradictedPairs(const io::Reconstruction& rec) {
  const auto& pairs = rec.contradicted_view_pairs;
  if (pairs.empty() || rec.status == "inconsistent") return;  // the status line names them
  std::string named = io::contradictedPairsText(pairs, 5);
  if (pairs.size() > 5) named += ", ...";
  std::fprintf(stderr,
               "epitrack-solve: warning: %zu of %d view pairs are contradicted by their own "
               "matches (the solve's relative pose explains far fewer of them than the pose the "
               "matches give: %s): the poses near them may be wrong although their reprojection "
               "errors look fine; summary.json view_pair_check\n",
               pairs.size(), rec.view_pairs_checked, named.c_str());
}

// A lens found by --distortion auto is said (it changes the camera model the outputs carry).
void printDetectedDistortion(const SolveRun& run) {
  const auto& rec = run.rec;
  if (rec.distortion_source != io::DistortionSource::kDetected ||
      run.o.progress == io::ProgressReporter::Mode::kQuiet)
    return;
  std::fprintf(stderr,
               "epitrack-solve: lens distortion found and modelled: k1 %.4f, k2 %.4f (up to "
               "%.1f px; median reprojection error %.3f -> %.3f px); --distortion none for a "
               "pinhole camera; summary.json distortion\n",
               rec.intrinsics.k1, rec.intrinsics.k2, rec.distortion_trial.max_displacement_px,
               rec.distortion_trial.median_before_px, rec.distortion_trial.median_after_px);
}

// A camera model that leaves the rows unexplained (algo/sfm/row_misfit.hpp) is said even under
// --quiet: the poses are written, but an inserted object will slide against the plate.
void printRowMisfit(const io::Reconstruction& rec) {
  const RowMisfit& m = rec.row_misfit;
  if (!m.misfit) return;
  const char* advice = rec.readout_source == io::ReadoutSource::kNone || !rec.readout_applied
                           ? "a rolling shutter? try --readout auto or --readout-ms MS"
                           : "the rolling-shutter model does not follow this motion (jitter "
                             "faster than the frame rate, or key frames far apart in time)";
  std::fprintf(stderr,
               "epitrack-solve: warning: the residuals grow with the image row in %d of %d "
               "frames (row shear median %.2f px, 90th percentile %.2f px, largest %.2f px at "
               "frame %lld): %s; summary.json row_misfit\n",
               m.frames_sheared, m.frames_tested, m.median_shear_px, m.p90_shear_px, m.max_shear_px,
               static_cast<long long>(m.max_shear_frame), advice);
}

// The one-line result on stderr (no nan in what a user reads).
void printResult(const SolveRun& run, const Solver& solver) {
  const auto& rec = run.rec;
  const auto& summary = run.summary;
  const int frames = run.frames;
  double mean = 0.0, median = 0.0;
  io::reprojectionStatistics(rec, mean, median);
  char refined_from[64] = "";
  if (rec.focal_given_px > 0.0)
    std::snprintf(refined_from, sizeof(refined_from), ", refined from %.2f", rec.focal_given_px);
  // No nan in what a user reads: a solve without a reprojected observation has no mean.
  char reprojection[48] = "no reprojected observation";
  if (std::isfinite(mean))
    std::snprintf(reprojection, sizeof(reprojection), "reprojection mean %.3f px", mean);
  char focal_text[32] = "unknown";
  if (std::isfinite(summary.focal_px) && summary.focal_px > 0.0)
    std::snprintf(focal_text, sizeof(focal_text), "%.2f px", summary.focal_px);
  char line[512];
  std::snprintf(line, sizeof(line),
                "%s: %d/%d frames solved, focal %s (%s%s%s%s), %zu points, %s, %.2f s; outputs "
                "in %s",
                rec.status.c_str(), solver.solvedFrames(), frames, focal_text,
                rec.focal_source.c_str(), refined_from,
                rec.focal_observable ? "" : ", not observable from F",
                fallbackNote(rec.focal_fallback), rec.points.size(), reprojection,
                rec.seconds.total, run.o.out_dir.c_str());
  if (run.o.progress != io::ProgressReporter::Mode::kQuiet)
    std::fprintf(stderr, "epitrack-solve: %s\n", line);
  printUncertainReadout(rec);
  printDetectedDistortion(run);
  printRowMisfit(rec);
  printContradictedPairs(rec);
}

// The exit code (solve_pipeline.hpp, runSolve), with the reason on stderr.
int exitCode(const SolveRun& run, const Solver& solver) {
  const auto& summary = run.summary;
  const bool ok = run.solve_ok;
  const auto& rec = run.rec;
  const auto& stop_stage = run.stop_stage;
  const auto& input_error = run.input_error;
  if (!stop_stage.empty()) {
    std::fprintf(stderr, "epitrack-solve: interrupted: %s\n", rec.message.c_str());
    return interruptExitCode();
  }
  if (!input_error.empty()) {
    std::fprintf(stderr, "epitrack-solve: input stopped early: %s\n", input_error.c_str());
    return 1;
  }
  if (solver.status() == Solver::Status::kPartial) {
    // Outputs written, but not of the whole clip: the ranges and their causes are named here and
    // in summary.json (solved_ranges, unsolved_ranges).
    std::fprintf(stderr, "epitrack-solve: partial: %s\n", summary.message.c_str());
    return kExitPartial;
  }
  if (solver.status() == Solver::Status::kTrajectoryUncertain) {
    // Outputs written, every frame solved, but the camera path is not determined (the figure
    // is in the message and in summary.json centre_uncertainty).
    std::fprintf(stderr, "epitrack-solve: trajectory-uncertain: %s\n", summary.message.c_str());
    return kExitTrajectoryUncertain;
  }
  if (solver.status() == Solver::Status::kInconsistent) {
    // Outputs written, the views registered, but pairs of them contradict the solve (named in
    // the message and in summary.json view_pair_check).
    std::fprintf(stderr, "epitrack-solve: inconsistent: %s\n", summary.message.c_str());
    return kExitInconsistent;
  }
  if (!ok) {
    std::fprintf(stderr, "epitrack-solve: %s\n", summary.message.c_str());
    // A tripod solve is a result (every camera's rotation and the focal), not a failure.
    return solver.status() == Solver::Status::kRotationOnly ? 0 : 1;
  }
  return 0;
}

// report.html and every export, the one-line result on stderr; returns the exit code.
int writeOutputs(SolveRun& run, const Solver& solver) {
  const SolveCommandOptions& o = run.o;
  auto& rec = run.rec;
  auto& error = run.error;
  markInterrupted(run);
  // report.html before the exports: summary.json stays the last file written.
  if (!render::writeReportHtml(rec, run.report, o.out_dir + "/report.html", error)) {
    fail(error.c_str());
    return 1;
  }
  rec.files.insert(rec.files.begin(), "report.html");
  if (!io::writeAllOutputs(rec, o.out_dir, error)) {
    fail(error.c_str());
    return 1;
  }
  printResult(run, solver);
  return exitCode(run, solver);
}

}  // namespace

int runSolve(const SolveCommandOptions& options) {
  SolveRun run(options);
  for (const auto stage : {readGivenIntrinsics, openInputs, prepareOutputDir, trackClip,
                           finishTracks, checkIntrinsicsSize})
    if (const auto code = stage(run)) return *code;
  Solver solver(solverTracks(run), run.width, run.height, run.so);
  if (run.so.readout_frames > 0.0) solver.setExposedTracks(&run.tracks);
  if (const auto code = solveStages(run, solver)) return *code;
  const std::unique_ptr<Solver> pan = solveRollingShutterPan(run, solver);
  const Solver& solved = pan ? *pan : solver;
  if (pan) run.solve_ok = false;  // a tripod solve, as solveStages leaves one
  refineReadout(run, solved);
  buildReconstruction(run, solved);
  placeObject(run, solved);
  if (const auto code = renderAugmented(run, solved.solvedFrames())) return *code;
  return writeOutputs(run, solved);
}

}  // namespace epitrack::tools

#include "tools/solve/solve_pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <system_error>
#include <unordered_map>

#include <Eigen/Geometry>

#include "algo/image/image.hpp"
#include "hal/frame_source.hpp"
#include "hal/io/file_util.hpp"
#include "hal/io/image_codec.hpp"
#include "hal/io/text_formats.hpp"
#include "hal/io/tracks_csv.hpp"
#include "tools/common/interrupt.hpp"
#include "tools/common/mask_source.hpp"
#include "tools/export/clip_input.hpp"
#include "tools/export/output_writers.hpp"
#include "tools/export/reconstruction_scene_frame.hpp"
#include "tools/export/reprojection_errors.hpp"
#include "tools/render/avi_writer.hpp"
#include "tools/render/object_placement.hpp"
#include "tools/render/overlay_renderer.hpp"
#include "tools/render/report_writer.hpp"
#include "tools/render/track_overlay.hpp"

namespace epitrack::tools {

using render::LineSet;
using render::makeGroundGrid;
using render::Mesh;
using render::MjpegAviWriter;
using render::OverlayRenderer;
using render::Rgb8;

namespace {

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

void fail(const char* what) { std::fprintf(stderr, "epitrack-solve: %s\n", what); }

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

// The camera-to-scene transform of a solved camera (what the renderer draws with).
Eigen::Isometry3d cameraToScene(const io::SolvedCamera& cam) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = cam.R_wc;
  T.translation() = cam.p_wc;
  return T;
}

// The solved frame nearest the middle of the solved ones (-1: none): the report's scene-frame
// picture (the object is placed for the middle of the clip, see object_placement.hpp).
int middleSolvedFrame(const io::Reconstruction& rec) {
  std::vector<int> solved;
  for (const auto& c : rec.cameras)
    if (c.solved) solved.push_back(static_cast<int>(c.frame));
  return solved.empty() ? -1 : solved[solved.size() / 2];
}

// DIR/scene_frame.jpg (issue 23): `plate` with the ground grid, the object and the scene's up as
// a yellow arrow beside the object (offset along the camera's right, so it stands clear of it).
bool writeSceneFrameImage(const io::Reconstruction& rec, int frame, const Mesh& object,
                          const LineSet& grid, OverlayRenderer& renderer, ImageView<Rgb8> plate,
                          hal::JpegEncoder& encoder, const std::string& path, std::string& error) {
  const auto& cam = rec.cameras[static_cast<std::size_t>(frame)];
  Eigen::Vector3d right(cam.R_wc(0, 0), cam.R_wc(1, 0), 0.0);
  right = right.norm() > 1e-9 ? Eigen::Vector3d(right.normalized()) : Eigen::Vector3d::UnitX();
  const double scale = rec.object.scale;
  const double length = std::isfinite(rec.object.height) ? 1.3 * rec.object.height : 0.6 * scale;
  const Eigen::Isometry3d T = cameraToScene(cam);
  renderer.clear();
  renderer.drawLines(grid, T);
  renderer.drawMesh(object, T);
  renderer.drawMesh(render::makeUpArrow(rec.object.at + 0.45 * scale * right, length), T);
  renderer.composite(plate);
  return encoder.encodeRgb(reinterpret_cast<const uint8_t*>(plate.data), plate.width, plate.height,
                           plate.stride * static_cast<std::ptrdiff_t>(sizeof(Rgb8)), 90, error) &&
         hal::writeFileAtomic(path, encoder.data(), encoder.size(), error);
}

// Every name epitrack-solve writes in its output directory, besides augmented/NNNNNN.jpg.
std::vector<std::string> solveOutputNames() {
  std::vector<std::string> names = {"summary.json"};
  names.insert(names.end(), io::exportFileNames().begin(), io::exportFileNames().end());
  names.insert(names.end(), {"report.html", "augmented.avi", "scene_frame.jpg"});
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

// Removes the files of an earlier solve (--force) and the folders they leave empty; nothing else.
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

// Ends a run stopped by SIGINT/SIGTERM before any output but summary.json was consistent:
// summary.json (atomically) says so and lists no other file. Returns the exit code.
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

}  // namespace

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

int runSolve(const SolveCommandOptions& o) {
  io::ProgressReporter progress(o.progress);
  io::Reconstruction rec;
  StageClock clock(rec.seconds);
  std::string error;

  // --- given intrinsics --------------------------------------------------------------------
  SolverOptions so = o.solver;
  CameraIntrinsics given;
  bool have_given = false;
  if (!o.intrinsics_file.empty()) {
    if (!hal::readIntrinsicsFile(o.intrinsics_file, given, error)) {
      fail(error.c_str());
      return 2;
    }
    have_given = true;
    so.focal_px = given.fx;
    so.has_principal_point = true;
    so.cx = given.cx;
    so.cy = given.cy;
    so.aspect = given.fy / given.fx;
    so.k1 = given.k1;
    so.k2 = given.k2;
  } else if (o.focal_px > 0.0) {
    so.focal_px = o.focal_px;
  }
  so.refine_distortion = o.distortion;

  // --- everything named on the command line is checked before anything is written ---------
  hal::SourceOptions source_options;
  auto source = hal::openFrameSource(o.input, source_options, error);
  if (!source) {
    fail(error.c_str());
    return 2;
  }
  // --tracks: read and checked (syntax, finite coordinates) before anything is written; the
  // frame range is checked against the clip once its length is known.
  std::vector<hal::TrackRow> given_rows;
  const bool given_tracks = !o.tracks_file.empty();
  if (given_tracks) {
    if (!hal::readTracksCsv(o.tracks_file, given_rows, error)) {
      fail(error.c_str());
      return 2;
    }
    if (given_rows.empty()) {
      fail(("'" + o.tracks_file + "' holds no observation").c_str());
      return 2;
    }
    for (const auto& r : given_rows) {
      if (r.frame < 0 || !std::isfinite(r.x) || !std::isfinite(r.y)) {
        char msg[160];
        std::snprintf(msg, sizeof(msg), "'%s': frame %lld, track %d: ", o.tracks_file.c_str(),
                      static_cast<long long>(r.frame), r.track_id);
        fail((std::string(msg) + (r.frame < 0 ? "negative frame" : "coordinates not finite"))
                 .c_str());
        return 2;
      }
    }
    // TrackTable takes frames in order; a stable sort keeps each frame's rows as written.
    std::stable_sort(
        given_rows.begin(), given_rows.end(),
        [](const hal::TrackRow& a, const hal::TrackRow& b) { return a.frame < b.frame; });
  }
  // A clip of known length is checked now; a stream's once it has been read.
  if (given_tracks && source->info().frame_count > 0 &&
      given_rows.back().frame >= static_cast<int64_t>(source->info().frame_count)) {
    char msg[256];
    std::snprintf(msg, sizeof(msg), "'%s' has observations in frame %lld but INPUT has %ld frames",
                  o.tracks_file.c_str(), static_cast<long long>(given_rows.back().frame),
                  static_cast<long>(source->info().frame_count));
    fail(msg);
    return 2;
  }
  MaskSource masks;
  if (!masks.open(o.mask, error)) {
    fail(error.c_str());
    return 2;
  }
  if (const auto previous = previousSolveFiles(o.out_dir); !previous.empty()) {
    if (!o.force) {
      const std::string msg =
          "'" + o.out_dir + "' already holds the outputs of a solve (" + previous.front() +
          (previous.size() > 1 ? " and " + std::to_string(previous.size() - 1) + " more files"
                               : std::string()) +
          "); pass --force to overwrite it";
      fail(msg.c_str());
      return 2;
    }
    if (!removePreviousSolve(o.out_dir, previous, error)) {
      fail(error.c_str());
      return 1;
    }
  }
  if (!hal::makeDirectories(o.out_dir, error)) {
    fail(error.c_str());
    return 2;
  }

  // --- 2D tracking of the whole clip ---------------------------------------------------------
  const long expected = static_cast<long>(source->info().frame_count);
  // With --tracks the frames are only read (size, count, timestamps, point colours).
  progress.begin(given_tracks ? "reading" : "tracking", expected);
  std::unique_ptr<ClipTracker> tracker;
  TrackTable tracks;
  std::unordered_map<int64_t, uint8_t> track_gray;
  std::vector<int> features_per_frame;
  bool decision_reported = false;
  std::vector<double> timestamps;
  std::vector<std::string> frame_paths;  // the file of each readable frame, for the exports
  const bool draw_frames = o.render != "none" || o.overlay == "tracks";
  const bool keep_frames = draw_frames && o.input == "-";  // stdin cannot be re-read
  std::vector<Image<uint8_t>> kept;
  int width = 0, height = 0, frames = 0, skipped = 0;
  std::string input_error;  // why reading stopped before the end of the stream, if it did
  hal::Frame frame;
  // A stop signal is looked at between frames: the frames tracked so far are consistent, but a
  // solve of a clip cut short is not what was asked for, so only summary.json is written.
  for (;;) {
    if (interruptRequested()) break;
    const hal::FrameStatus st = source->next(frame);
    if (st == hal::FrameStatus::kEndOfStream) break;
    if (st == hal::FrameStatus::kCorruptFrame || st == hal::FrameStatus::kTimeout) {
      ++skipped;
      if (tracker) tracker->skipFrames(1);

      progress.message("skipping frame: " + source->lastError());
      continue;
    }
    if (st != hal::FrameStatus::kOk) {
      if (frames == 0) {
        fail(source->lastError().c_str());
        return 1;
      }
      // The frames read so far are solved and written; the run still exits 1.
      input_error = source->lastError();
      progress.message("input stopped: " + input_error + "; solving the " + std::to_string(frames) +
                       " frames before it");
      break;
    }
    // A frame of another size ends the clip: the frames before it are solved.
    const auto stopAtSizeChange = [&] {
      input_error = "frame " + std::to_string(frame.index) + " is " +
                    std::to_string(frame.luma.width) + "x" + std::to_string(frame.luma.height) +
                    ", the clip started at " + std::to_string(width) + "x" + std::to_string(height);
      progress.message("input stopped: " + input_error + "; solving the " + std::to_string(frames) +
                       " frames before it");
    };
    if (given_tracks) {
      // Frames are numbered as epitrack-track numbers them (readable frames, from 0).
      if (frames == 0) {
        width = frame.luma.width;
        height = frame.luma.height;
      } else if (frame.luma.width != width || frame.luma.height != height) {
        stopAtSizeChange();
        break;
      }
      // Point colours: each track's gray value where it is first seen.
      const auto before = [](const hal::TrackRow& r, long f) { return r.frame < f; };
      for (auto it = std::lower_bound(given_rows.begin(), given_rows.end(), frames, before);
           it != given_rows.end() && it->frame == frames; ++it) {
        const int x = std::clamp(static_cast<int>(std::lround(it->x)), 0, width - 1);
        const int y = std::clamp(static_cast<int>(std::lround(it->y)), 0, height - 1);
        track_gray.try_emplace(it->track_id, frame.luma(x, y));
      }
    } else {
      if (!tracker) {
        width = frame.luma.width;
        height = frame.luma.height;
        const double need = estimateSolveMemoryBytes(width, height, o.tracker.max_features,
                                                     o.tracker.window, std::max<long>(expected, 1));
        if (need > o.max_memory_mib * 1024.0 * 1024.0) {
          char msg[256];
          std::snprintf(msg, sizeof(msg),
                        "a %dx%d clip of %ld frames needs about %.0f MiB, above the limit of %.0f "
                        "MiB (--max-memory)",
                        width, height, std::max<long>(expected, 1), need / (1024.0 * 1024.0),
                        o.max_memory_mib);
          fail(msg);
          return 1;
        }
        DescriptorTrackerOptions matching = o.matching;
        if (so.focal_px > 0.0) {  // known intrinsics: five-point verification of the pairs
          matching.focal_px = so.focal_px;
          matching.cx = so.has_principal_point ? so.cx : (width - 1) * 0.5;
          matching.cy = so.has_principal_point ? so.cy : (height - 1) * 0.5;
          matching.aspect = so.aspect;
        }
        tracker = std::make_unique<ClipTracker>(o.matcher, o.tracker, matching, width, height,
                                                expected > 0 ? static_cast<int>(expected) : 1024);
      }
      ImageView<const uint8_t> mask;
      if (!masks.maskFor(frames, width, height, mask, error)) {
        fail(error.c_str());
        return 2;
      }
      if (tracker->track(frame.luma, mask) != ClipTracker::Status::kOk) {
        stopAtSizeChange();
        break;
      }
      if (!decision_reported && !tracker->decision().empty()) {
        progress.message("matcher: " + tracker->decision());
        decision_reported = true;
      }
    }
    timestamps.push_back(frame.timestamp_s);
    frame_paths.emplace_back(frame.path);
    if (keep_frames) {
      kept.emplace_back(width, height);
      copyPixels<uint8_t>(frame.luma, kept.back().view());
    }
    ++frames;
    progress.update(frames);
  }
  progress.end();
  rec.frames = frames;
  rec.skipped_frames = skipped;
  if (interruptRequested()) {
    // Nothing is known of the solve: null focal, "unknown" source and motion.
    rec.intrinsics = have_given ? given
                                : CameraIntrinsics::centered(
                                      width, height, std::numeric_limits<double>::quiet_NaN());
    rec.focal_source = have_given ? "given" : "unknown";
    rec.focal_observable = false;
    rec.motion = "unknown";
    return stopInterrupted(rec, o.out_dir, "tracking",
                           std::to_string(frames) + " frames tracked, nothing solved");
  }
  if (frames == 0) {
    fail("the input holds no readable frame");
    return 1;
  }
  if (given_tracks) {
    if (given_rows.back().frame >= frames) {
      char msg[256];
      std::snprintf(msg, sizeof(msg),
                    "'%s' has observations in frame %lld but INPUT has %d readable frames (0-%d)",
                    o.tracks_file.c_str(), static_cast<long long>(given_rows.back().frame), frames,
                    frames - 1);
      fail(msg);
      return 2;
    }
    tracks.reserve(frames, given_rows.size());
    features_per_frame.assign(static_cast<std::size_t>(frames), 0);
    for (const auto& r : given_rows) {
      tracks.add(static_cast<int>(r.frame), r.track_id, r.x, r.y);
      ++features_per_frame[static_cast<std::size_t>(r.frame)];
    }
    tracks.setFrameCount(frames);
    tracks.finalize();
    rec.matcher = "given";
    progress.message("tracks: " + std::to_string(given_rows.size()) + " observations of " +
                     std::to_string(tracks.trackCount()) + " tracks from " + o.tracks_file);
    // Tracks that are not continuous video tracks (key frames, matched photos) are solved as a
    // key-frame collection, as the descriptor matcher's are.
    if (o.matcher == Matcher::kDescriptors) so.keyframe_collection = true;
  } else {
    tracker->finish(tracks, features_per_frame, track_gray);
    if (!decision_reported) progress.message("matcher: " + tracker->decision());
    rec.matcher = matcherName(tracker->chosen());
    // Key frames (descriptor tracks): every frame a keyframe, next-best-view registration.
    if (tracker->chosen() == Matcher::kDescriptors) so.keyframe_collection = true;
  }
  clock.lap("tracking");

  // --- 3D solve ---------------------------------------------------------------------------------
  if (have_given && (given.width != width || given.height != height)) {
    const std::string msg = "intrinsics are for " + std::to_string(given.width) + "x" +
                            std::to_string(given.height) + " but the frames are " +
                            std::to_string(width) + "x" + std::to_string(height);
    fail(msg.c_str());
    return 2;
  }
  Solver solver(tracks, width, height, so);
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
  bool ok = solver.calibrate();
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
  std::string stop_stage;
  if (interruptRequested()) stop_stage = "bundle_adjustment";

  // --- reconstruction ------------------------------------------------------------------------
  const SolverSummary summary = solver.summary();
  rec.intrinsics = CameraIntrinsics::centered(width, height, summary.focal_px);
  rec.intrinsics.cx = summary.cx;
  rec.intrinsics.cy = summary.cy;
  rec.intrinsics.fy = summary.focal_px * summary.aspect;
  rec.intrinsics.k1 = summary.k1;
  rec.intrinsics.k2 = summary.k2;
  rec.focal_source = toString(summary.focal_source);
  rec.focal_observable = summary.focal_observable;
  if (so.refine_given_focal && so.focal_px > 0.0) rec.focal_given_px = so.focal_px;
  rec.motion = toString(summary.motion);
  rec.status = toString(summary.status);
  rec.message = summary.message;
  if (!input_error.empty())
    rec.message = "input stopped early (" + input_error + "), frames after it are not solved" +
                  (rec.message.empty() ? std::string() : "; " + rec.message);
  rec.has_timestamps = source->info().real_timestamps;
  io::describeClipInput(rec, o.input, frame_paths, source->info().fps);
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
  for (int f = 0; f < frames; ++f) {
    const auto& fr = solver.frames()[static_cast<std::size_t>(f)];
    io::SolvedCamera c;
    c.frame = f;
    c.timestamp = timestamps[static_cast<std::size_t>(f)];
    c.solved = fr.solved;
    c.R_wc = fr.pose.R_cw.transpose();
    c.p_wc = fr.pose.centre();
    c.mean_reproj_px = fr.rms_px;
    c.inliers = fr.inliers;
    c.features = features_per_frame[static_cast<std::size_t>(f)];
    c.keyframe = fr.keyframe;
    rec.cameras.push_back(c);
  }
  std::vector<char> point_valid(static_cast<std::size_t>(tracks.trackCount()), 0);
  for (const auto& p : solver.points()) {
    if (!p.valid || !p.X.allFinite()) continue;
    io::ScenePoint sp;
    sp.id = tracks.trackId(p.track);
    sp.X = p.X;
    const auto g = track_gray.find(sp.id);
    sp.gray = g != track_gray.end() ? g->second : 128;
    sp.observations = p.observations;
    rec.points.push_back(sp);
    point_valid[static_cast<std::size_t>(p.track)] = 1;
  }
  // rec_observation[i]: index into rec.observations of tracks.observations()[i], -1 when left out.
  std::vector<int> rec_observation(tracks.observations().size(), -1);
  for (std::size_t i = 0; i < tracks.observations().size(); ++i) {
    const auto& ob = tracks.observations()[i];
    if (!point_valid[static_cast<std::size_t>(ob.track)]) continue;
    if (!solver.frames()[static_cast<std::size_t>(ob.frame)].solved) continue;
    rec_observation[i] = static_cast<int>(rec.observations.size());
    rec.observations.push_back({ob.frame, tracks.trackId(ob.track), ob.x, ob.y});
  }
  if (solver.status() == Solver::Status::kOk || solver.status() == Solver::Status::kRotationOnly ||
      solver.status() == Solver::Status::kPartial) {
    const auto sf = io::applySceneFrame(rec, o.scene);
    (void)sf;
  }
  const double outlier_px = 2.0 * so.reproj_threshold_px;
  io::computeReprojectionErrors(rec, outlier_px);
  clock.lap("scene_frame");

  // --- augmented frames ----------------------------------------------------------------------
  render::ReportOptions report;  // report.html, written with the other outputs
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
  if (draw_frames && solver.solvedFrames() > 0 && stop_stage.empty()) {
    const std::string aug_dir = o.out_dir + "/augmented";
    if (!hal::makeDirectories(aug_dir, error)) {
      fail(error.c_str());
      return 1;
    }
    std::unique_ptr<hal::FrameSource> replay;
    if (!keep_frames) {
      replay = hal::openFrameSource(o.input, source_options, error);
      if (!replay) {
        fail(error.c_str());
        return 1;
      }
    }
    OverlayRenderer renderer(rec.intrinsics);
    const Mesh mesh = render::makeObjectMesh(o.render, rec.object.at, rec.object.scale);
    const LineSet grid = o.render == "none" ? LineSet{}
                                            : makeGroundGrid(rec.object.at, 1.0 * rec.object.scale,
                                                             0.25 * rec.object.scale);
    Image<Rgb8> rgb(width, height);
    const int scene_frame = o.render == "none" ? -1 : middleSolvedFrame(rec);
    Image<Rgb8> scene_plate;
    if (scene_frame >= 0) scene_plate.allocate(width, height);
    // --overlay tracks: the tracked features on the right, each observation classified by its
    // reprojection error in the exported model (the threshold of the report's statistics).
    const bool with_tracks = o.overlay == "tracks";
    std::vector<render::TrackKind> kinds;
    Image<Rgb8> panel, both;
    if (with_tracks) {
      kinds.assign(tracks.observations().size(), render::TrackKind::kUnused);
      for (std::size_t i = 0; i < kinds.size(); ++i) {
        if (rec_observation[i] < 0) continue;
        const double r = rec.observations[static_cast<std::size_t>(rec_observation[i])].residual_px;
        if (std::isfinite(r))
          kinds[i] = r <= outlier_px ? render::TrackKind::kInlier : render::TrackKind::kOutlier;
      }
      panel.allocate(width, height);
      both.allocate(2 * width, height);
    }
    const int out_width = with_tracks ? 2 * width : width;
    hal::JpegEncoder encoder;
    MjpegAviWriter avi;
    const double fps = source->info().fps > 0.0 ? source->info().fps : 30.0;
    if (!avi.open(o.out_dir + "/augmented.avi", out_width, height, fps, error)) {
      fail(error.c_str());
      return 1;
    }
    progress.begin("rendering", frames);
    int index = 0;
    for (int f = 0; f < frames;) {
      if (interruptRequested()) {  // the frames rendered so far stay, the video ends with them
        stop_stage = "rendering";
        break;
      }
      ImageView<const uint8_t> luma;
      if (keep_frames) {
        luma = kept[static_cast<std::size_t>(f)].constView();
      } else {
        const auto st = replay->next(frame);
        if (st == hal::FrameStatus::kEndOfStream) break;
        if (st != hal::FrameStatus::kOk) continue;  // the tracking pass skipped it too
        luma = frame.luma;
      }
      for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
          const uint8_t v = luma(x, y);
          rgb.view()(x, y) = Rgb8{v, v, v};
        }
      if (with_tracks) copyPixels<Rgb8>(rgb.constView(), panel.view());
      if (f == scene_frame) copyPixels<Rgb8>(rgb.constView(), scene_plate.view());
      const auto& cam = rec.cameras[static_cast<std::size_t>(f)];
      if (cam.solved && (!mesh.triangles.empty() || !grid.from.empty())) {
        const Eigen::Isometry3d T = cameraToScene(cam);
        renderer.clear();
        renderer.drawLines(grid, T);
        renderer.drawMesh(mesh, T);
        renderer.composite(rgb.view());
      }
      ImageView<const Rgb8> out = rgb.constView();
      if (with_tracks) {
        render::drawTracks(panel.view(), tracks, kinds, f);
        render::sideBySide(rgb.constView(), panel.constView(), both.view());
        out = both.constView();
      }
      if (!encoder.encodeRgb(reinterpret_cast<const uint8_t*>(out.data), out.width, out.height,
                             out.stride * static_cast<std::ptrdiff_t>(sizeof(Rgb8)), 90, error) ||
          !avi.addFrame(encoder.data(), encoder.size(), error)) {
        fail(error.c_str());
        return 1;
      }
      char name[32];
      std::snprintf(name, sizeof(name), "/%06d.jpg", index);
      if (!hal::writeFileAtomic(aug_dir + name, encoder.data(), encoder.size(), error)) {
        fail(error.c_str());
        return 1;
      }
      if (f == scene_frame) {
        if (!writeSceneFrameImage(rec, f, mesh, grid, renderer, scene_plate.view(), encoder,
                                  o.out_dir + "/scene_frame.jpg", error)) {
          fail(error.c_str());
          return 1;
        }
        report.scene_frame_image = "scene_frame.jpg";
        report.scene_frame_index = f;
        rec.files.emplace_back("scene_frame.jpg");
      }
      ++index;
      ++f;
      progress.update(f);
    }
    progress.end();
    if (!avi.finish(error)) {
      fail(error.c_str());
      return 1;
    }
    for (int i = 0; i < index; ++i) {
      char rel[40];
      std::snprintf(rel, sizeof(rel), "augmented/%06d.jpg", i);
      report.augmented_frames.emplace_back(i, rel);
      rec.files.emplace_back(rel);
    }
    report.video = "augmented.avi";
    rec.files.emplace_back("augmented.avi");
    clock.lap("rendering");
  }
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

  // report.html before the exports: summary.json stays the last file written.
  if (!render::writeReportHtml(rec, report, o.out_dir + "/report.html", error)) {
    fail(error.c_str());
    return 1;
  }
  rec.files.insert(rec.files.begin(), "report.html");
  if (!io::writeAllOutputs(rec, o.out_dir, error)) {
    fail(error.c_str());
    return 1;
  }
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
                rec.focal_fallback == "profile"
                    ? ", from the reprojection profile"
                    : (rec.focal_fallback == "profile-flat" ? ", profile flat: a guess" : ""),
                rec.points.size(), reprojection, rec.seconds.total, o.out_dir.c_str());
  if (o.progress != io::ProgressReporter::Mode::kQuiet)
    std::fprintf(stderr, "epitrack-solve: %s\n", line);
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
  if (!ok) {
    std::fprintf(stderr, "epitrack-solve: %s\n", summary.message.c_str());
    // A tripod solve is a result (every camera's rotation and the focal), not a failure.
    return solver.status() == Solver::Status::kRotationOnly ? 0 : 1;
  }
  return 0;
}

}  // namespace epitrack::tools

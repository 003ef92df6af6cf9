#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "tools/common/interrupt.hpp"
#include "tools/solve/solve_run.hpp"

// The tracking pass of epitrack-solve: every frame read once, tracked (or, with --tracks, only
// read for its size, timestamp and the tracks' colours), then the track table.

namespace epitrack::tools {

namespace {

// The tracker for the clip's frame size, once the first frame is read (exit 1 when the clip
// would need more memory than --max-memory allows).
StageResult startTracker(SolveRun& run, long expected) {
  const SolveCommandOptions& o = run.o;
  const SolverOptions& so = run.so;
  const int width = run.width, height = run.height;
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
    matching.k1 = so.k1;  // verification on undistorted points (issue 22 item 3)
    matching.k2 = so.k2;
  }
  run.tracker = std::make_unique<ClipTracker>(o.matcher, o.tracker, matching, width, height,
                                              expected > 0 ? static_cast<int>(expected) : 1024);
  return std::nullopt;
}

// A frame of another size ends the clip: the frames before it are solved (the run exits 1).
void stopAtSizeChange(SolveRun& run, const hal::Frame& frame) {
  run.input_error = "frame " + std::to_string(frame.index) + " is " +
                    std::to_string(frame.luma.width) + "x" + std::to_string(frame.luma.height) +
                    ", the clip started at " + std::to_string(run.width) + "x" +
                    std::to_string(run.height);
  run.progress.message("input stopped: " + run.input_error + "; solving the " +
                       std::to_string(run.frames) + " frames before it");
}

// --tracks: the frame gives the size and each track's gray value where it is first seen (the
// point colours). Frames are numbered as epitrack-track numbers them (readable frames, from 0).
// `ended`: the frame has another size, the clip ends before it.
void readGivenTracksFrame(SolveRun& run, const hal::Frame& frame, bool& ended) {
  if (run.frames == 0) {
    run.width = frame.luma.width;
    run.height = frame.luma.height;
  } else if (frame.luma.width != run.width || frame.luma.height != run.height) {
    stopAtSizeChange(run, frame);
    ended = true;
    return;
  }
  const auto before = [](const hal::TrackRow& r, long f) { return r.frame < f; };
  for (auto it = std::lower_bound(run.given_rows.begin(), run.given_rows.end(), run.frames, before);
       it != run.given_rows.end() && it->frame == run.frames; ++it) {
    const int x = std::clamp(static_cast<int>(std::lround(it->x)), 0, run.width - 1);
    const int y = std::clamp(static_cast<int>(std::lround(it->y)), 0, run.height - 1);
    run.track_gray.try_emplace(it->track_id, frame.luma(x, y));
  }
}

// The frame through the 2D tracker (made on the first frame). `ended`: the frame has another
// size, the clip ends before it.
StageResult trackFrame(SolveRun& run, const hal::Frame& frame, long expected, bool& ended) {
  if (!run.tracker) {
    run.width = frame.luma.width;
    run.height = frame.luma.height;
    if (const auto code = startTracker(run, expected)) return code;
  }
  ImageView<const uint8_t> mask;
  if (!run.masks.maskFor(run.frames, run.width, run.height, mask, run.error)) {
    fail(run.error.c_str());
    return 2;
  }
  if (run.tracker->track(frame.luma, mask) != ClipTracker::Status::kOk) {
    stopAtSizeChange(run, frame);
    ended = true;
    return std::nullopt;
  }
  if (!run.decision_reported && !run.tracker->decision().empty()) {
    run.progress.message("matcher: " + run.tracker->decision());
    run.decision_reported = true;
  }
  return std::nullopt;
}

}  // namespace

StageResult trackClip(SolveRun& run) {
  const SolveCommandOptions& o = run.o;
  hal::FrameSource& source = *run.source;
  const long expected = static_cast<long>(source.info().frame_count);
  // With --tracks the frames are only read (size, count, timestamps, point colours).
  run.progress.begin(run.given_tracks ? "reading" : "tracking", expected);
  run.draw_frames = o.render != "none" || o.overlay == "tracks";
  run.keep_frames = run.draw_frames && o.input == "-";  // stdin cannot be re-read
  hal::Frame frame;
  // A stop signal is looked at between frames: the frames tracked so far are consistent, but a
  // solve of a clip cut short is not what was asked for, so only summary.json is written.
  while (!interruptRequested()) {
    const hal::FrameStatus st = source.next(frame);
    if (st == hal::FrameStatus::kEndOfStream) break;
    if (st == hal::FrameStatus::kCorruptFrame || st == hal::FrameStatus::kTimeout) {
      ++run.skipped;
      if (run.tracker) run.tracker->skipFrames(1);
      run.progress.message("skipping frame: " + source.lastError());
      continue;
    }
    if (st != hal::FrameStatus::kOk) {
      if (run.frames == 0) {
        fail(source.lastError().c_str());
        return 1;
      }
      // The frames read so far are solved and written; the run still exits 1.
      run.input_error = source.lastError();
      run.progress.message("input stopped: " + run.input_error + "; solving the " +
                           std::to_string(run.frames) + " frames before it");
      break;
    }
    bool ended = false;
    if (run.given_tracks) {
      readGivenTracksFrame(run, frame, ended);
    } else if (const auto code = trackFrame(run, frame, expected, ended)) {
      return code;
    }
    if (ended) break;
    run.timestamps.push_back(frame.timestamp_s);
    run.frame_paths.emplace_back(frame.path);
    if (run.keep_frames) {
      run.kept.emplace_back(run.width, run.height);
      copyPixels<uint8_t>(frame.luma, run.kept.back().view());
    }
    ++run.frames;
    run.progress.update(run.frames);
  }
  return std::nullopt;
}

StageResult finishTracks(SolveRun& run) {
  const SolveCommandOptions& o = run.o;
  auto& progress = run.progress;
  auto& rec = run.rec;
  auto& tracks = run.tracks;
  auto& features_per_frame = run.features_per_frame;
  const auto& given_rows = run.given_rows;
  const int width = run.width, height = run.height, frames = run.frames;
  progress.end();
  rec.frames = frames;
  rec.skipped_frames = run.skipped;
  if (interruptRequested()) {
    // Nothing is known of the solve: null focal, "unknown" source and motion.
    rec.intrinsics = run.have_given ? run.given
                                    : CameraIntrinsics::centered(
                                          width, height, std::numeric_limits<double>::quiet_NaN());
    rec.focal_source = run.have_given ? "given" : "unknown";
    rec.focal_observable = false;
    rec.motion = "unknown";
    return stopInterrupted(rec, o.out_dir, "tracking",
                           std::to_string(frames) + " frames tracked, nothing solved");
  }
  if (frames == 0) {
    fail("the input holds no readable frame");
    return 1;
  }
  if (run.given_tracks) {
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
    if (o.matcher == Matcher::kDescriptors) run.so.keyframe_collection = true;
  } else {
    run.tracker->finish(tracks, features_per_frame, run.track_gray);
    if (!run.decision_reported) progress.message("matcher: " + run.tracker->decision());
    rec.matcher = matcherName(run.tracker->chosen());
    // Key frames (descriptor tracks): every frame a keyframe, next-best-view registration.
    if (run.tracker->chosen() == Matcher::kDescriptors) run.so.keyframe_collection = true;
  }
  run.clock.lap("tracking");
  return std::nullopt;
}

}  // namespace epitrack::tools

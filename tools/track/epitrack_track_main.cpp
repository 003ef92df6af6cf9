// epitrack-track: runs the 2D feature tracker over an INPUT and writes tracks.csv
// (ARCHITECTURE.md "Commands": epitrack-track INPUT --out tracks.csv [--features N] [--window PX]
// [--levels L]).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include <unistd.h>

#include "algo/image/image.hpp"
#include "algo/tracking/feature_tracker.hpp"
#include "hal/cpu/cpu_features.hpp"
#include "hal/frame_source.hpp"
#include "hal/io/file_util.hpp"
#include "hal/io/image_codec.hpp"
#include "hal/io/tracks_csv.hpp"
#include "tools/common/clip_tracker.hpp"
#include "tools/common/command_line.hpp"
#include "tools/common/interrupt.hpp"
#include "tools/common/mask_source.hpp"

namespace hal = epitrack::hal;
using epitrack::DescriptorTrackerOptions;
using epitrack::FeatureTrackerOptions;
using epitrack::Image;
using epitrack::tools::CommandLine;

using epitrack::tools::MaskSource;

namespace {

/// What the command line asks for.
struct TrackCommand {
  std::string input;
  std::string out;
  std::string mask_spec;
  FeatureTrackerOptions lk;
  DescriptorTrackerOptions matching;
  epitrack::tools::Matcher matcher = epitrack::tools::Matcher::kAuto;
  int max_frames = 0;
  bool quiet = false;
  bool frame_stats = false;
};

/// The tracker's options on the command line (the LK and Kalman settings of docs/tracker.md).
void addTrackerOptions(CommandLine& cl, FeatureTrackerOptions& o) {
  cl.integer("features", "N", "features to keep (default 300)", &o.max_features, 1, 100000);
  cl.integer("window", "PX", "LK window side, odd (default 21)", &o.window, 3, 99);
  cl.integer("levels", "L", "pyramid levels beyond the base (default 3)", &o.levels, 0, 7);
  cl.real("min-distance", "PX", "minimum distance between features (default 10)", &o.min_distance,
          1.0, 1000.0);
  cl.real("redetect", "FRACTION",
          "re-detect when fewer than this fraction of --features live (default 0.9)",
          &o.redetect_fraction, 0.0, 1.0);
  cl.integer("redetect-cells", "N",
             "re-detect only in the grid cells (about N) that lost tracks (default 0: the whole "
             "frame)",
             &o.redetect_cells, 0, 10000);
  cl.integer("redetect-min-gap", "N",
             "at least N frames between re-detections unless a cell emptied (default 1; with "
             "--redetect-cells)",
             &o.redetect_min_gap, 1, 1000);
  cl.real("max-residual", "R",
          "drop a track beyond this relative residual or --residual-scale-max frame medians "
          "(default 0.5)",
          &o.max_residual, 0.0, 1e9);
  cl.real("max-residual-jump", "R",
          "drop a track whose residual jumps by more than this or --residual-scale-jump frame "
          "medians above its own level (default 0.15)",
          &o.max_residual_jump, 0.0, 1e9);
  cl.real("residual-scale-max", "K", "see --max-residual (default 3)", &o.residual_scale_max, 0.0,
          1e9);
  cl.real("residual-scale-jump", "K", "see --max-residual-jump (default 1.5)",
          &o.residual_scale_jump, 0.0, 1e9);
  cl.real("residual-scale-young", "K",
          "a new track's first residual: drop beyond this many frame medians or "
          "--max-residual-jump (default 3)",
          &o.residual_scale_young, 0.0, 1e9);
  cl.real("residual-scale-refresh", "K", "see --refresh-residual (default 1.5)",
          &o.residual_scale_refresh, 0.0, 1e9);
  cl.real("fb", "PX",
          "forward-backward tolerance of the check of young and drifted tracks (default 0.75; "
          "0: no check)",
          &o.forward_backward_px, 0.0, 1e6);
  cl.flag("fb-all", "check every track forward-backward", &o.forward_backward);
  cl.real("refresh-residual", "R",
          "beyond this residual or --residual-scale-refresh frame medians a track is checked "
          "forward-backward and takes a new template (default 0.4)",
          &o.refresh_residual, 0.0, 1e9);
  cl.integer("iterations", "N", "LK iterations per level (default 10)", &o.max_iterations, 1, 1000);
  cl.real("kalman-accel", "PX", "Kalman process noise, px/frame^2 (default 0.3)",
          &o.kalman.process_accel_sigma, 0.0, 1e6);
  cl.real("gate-speed", "FRACTION",
          "widen the Kalman gate by this fraction of the predicted speed (default 0.25)",
          &o.gate_speed_fraction, 0.0, 100.0);
}

/// The matcher's options: which matcher, and the descriptor matcher's settings.
void addMatcherOptions(CommandLine& cl, std::string& matcher_text,
                       DescriptorTrackerOptions& matching) {
  cl.choice("matcher", {"lk", "descriptors", "auto"},
            "lk = pyramidal Lucas-Kanade frame to frame (video); descriptors = oriented BRIEF "
            "matched against the previous frames, verified, chained (key frames); auto (default) "
            "= LK unless fewer than 35 % of its tracks survive from frame to frame over the "
            "first 16 frames, or a pair after the first keeps fewer than 30 % (a cut in the "
            "file order)",
            &matcher_text);
  cl.integer("match-features", "N", "descriptor matcher: keypoints per frame (default 2000)",
             &matching.features.max_features, 50, 100000);
  matching.window = epitrack::tools::kMatchWindowAuto;
  cl.option("match-window", "N|all|auto",
            "descriptor matcher: previous frames each frame is matched against; all = every "
            "pair of frames (the view graph of a photo set, whatever the order of its files); "
            "auto (default) = all for at most 60 frames, else 2",
            [&matching](const std::string& v, std::string& e) {
              return epitrack::tools::parseMatchWindow(v, matching.window, e);
            });
}

/// Parses the command line into `cmd`; returns -1 to go on, else the exit code.
int parseCommandLine(int argc, char** argv, TrackCommand& cmd) {
  CommandLine cl(
      "epitrack-track", "INPUT --out tracks.csv [options]",
      "Tracks Shi-Tomasi corners through INPUT with pyramidal Lucas-Kanade and a Kalman\n"
      "gate, re-detecting as tracks are lost, and writes tracks.csv (frame,track_id,x,y).\n"
      "INPUT: a frame directory, .y4m (or - for Y4M on stdin), .mjpeg or v4l2:/dev/videoN.\n"
      "tracks.csv is written atomically once tracking ends. Ctrl-C (SIGINT) or SIGTERM stops\n"
      "between frames and writes tracks.csv complete for the frames tracked so far.\n"
      "Exit: 0 done, 1 tracking failed (unreadable stream, size change; nothing written),\n"
      "2 bad command line or unusable INPUT/--mask, 130 (143) stopped by SIGINT (SIGTERM).");
  cl.positional("INPUT", "frames to track", &cmd.input);
  cl.text("out", "FILE", "tracks.csv to write", &cmd.out);
  cl.require("out");
  std::string matcher_text = "auto";
  addMatcherOptions(cl, matcher_text, cmd.matching);
  FeatureTrackerOptions& o = cmd.lk;
  addTrackerOptions(cl, o);
  cl.text("mask", "PGM|DIR", "zero pixels are never tracked (one image, or one per frame)",
          &cmd.mask_spec);
  bool no_kalman = false;
  cl.flag("no-kalman", "disable the Kalman gate", &no_kalman);
  bool no_global_motion = false;
  cl.flag("no-global-motion",
          "no per-frame camera motion model: each track predicted from its own velocity alone "
          "(docs/tracker.md; the model is on by default)",
          &no_global_motion);
  bool motion_rows = false;
  cl.flag("motion-rows",
          "rolling shutter: the camera motion model follows the rows of a jerk (a row term "
          "beside the similarity; docs/tracker.md; default off)",
          &motion_rows);
  bool epipolar = false;
  cl.flag("epipolar",
          "the epipolar check: drop tracks that stay off the rigid two-view relation (F, or H "
          "for a rotation or a plane) over several frames (docs/tracker.md; default off)",
          &epipolar);
  bool translation_only = false;
  cl.flag("translation", "base level: translation only (default: affine template warp)",
          &translation_only);
  bool whole_window = false;
  cl.flag("whole-window",
          "the earlier residual and refresh set: residual over the whole LK window, refresh "
          "beyond 0.5 whatever the shape (sets --refresh-residual 0.5; default: centre window, "
          "stretch-gated refresh)",
          &whole_window);
  cl.integer("max-frames", "N", "stop after N frames (default: all)", &cmd.max_frames, 0,
             100000000);
  cl.flag("quiet", "no progress on stderr", &cmd.quiet);
  cl.flag("frame-stats", "per frame on stderr: live tracks, losses by reason, detections, ms",
          &cmd.frame_stats);
  if (const auto r = cl.parse(argc, argv); r != CommandLine::Result::kOk)
    return CommandLine::exitCode(r);
  if (o.window % 2 == 0) return cl.usageError("--window must be odd");
  if (whole_window) o.wholeWindow();
  o.kalman_gate = !no_kalman;
  o.global_motion = !no_global_motion;
  o.motion.row_term = motion_rows;
  o.epipolar_check = epipolar;
  o.affine = !translation_only;
  epitrack::tools::parseMatcher(matcher_text, cmd.matcher);
  return -1;
}

/// tracks.csv is written at the end: a directory that cannot take it is refused up front.
bool outputWritable(const std::string& out) {
  const auto slash = out.find_last_of('/');
  const std::string dir = slash == std::string::npos ? "." : out.substr(0, slash + 1);
  if (!hal::isDirectory(dir) || ::access(dir.c_str(), W_OK) != 0 || hal::isDirectory(out)) {
    std::fprintf(stderr, "epitrack-track: --out: cannot write '%s' (%s)\n", out.c_str(),
                 hal::isDirectory(out) ? "a directory" : "no writable directory");
    return false;
  }
  return true;
}

/// One line of --frame-stats: the tracker's account of the frame just tracked.
void printFrameStats(int frame, const epitrack::FrameStats& fs) {
  std::fprintf(
      stderr,
      "frame %d:%s live %d, lost: left-image %d no-convergence %d low-texture %d "
      "residual %d forward-backward %d gate %d mask %d epipolar %d; fb checks %d, "
      "refreshed %d, detected %d in %d cells; residual median %.3f; motion %.1f %.1f inliers %d/%d "
      "released %d; lk iterations %ld; ms pyramid %.2f lk %.2f epipolar %.2f detect "
      "%.2f\n",
      frame, fs.repeated != 0 ? " repeat," : "", fs.tracked, fs.lost_left_image,
      fs.lost_no_convergence, fs.lost_low_texture, fs.lost_residual, fs.lost_forward_backward,
      fs.lost_gate, fs.lost_mask, fs.lost_epipolar, fs.forward_backward_checks, fs.refreshed,
      fs.detected, fs.detect_cells, fs.residual_median, fs.motion_dx, fs.motion_dy,
      fs.motion_inliers, fs.motion_anchors, fs.gate_released, fs.lk_iterations, fs.pyramid_ms,
      fs.lk_ms, fs.epipolar_ms, fs.detect_ms);
}

/// What the frame loop produced.
struct TrackedClip {
  std::unique_ptr<epitrack::tools::ClipTracker> tracker;
  std::vector<int64_t> frame_index;  // the input's index of each tracked frame
  int frames = 0;
  double ms_total = 0.0;
  bool decision_reported = false;  // the matcher's choice printed
};

/// Tracks frames until the input ends, --max-frames or a stop signal (looked at between frames:
/// the frames tracked so far are then written as a complete tracks.csv, never a partial frame).
/// Returns -1 to go on, else the exit code.
int trackFrames(const TrackCommand& cmd, hal::FrameSource& source, MaskSource& masks,
                TrackedClip& clip) {
  int width = 0, height = 0;
  std::string error;
  hal::Frame frame;
  while ((cmd.max_frames == 0 || clip.frames < cmd.max_frames) &&
         !epitrack::tools::interruptRequested()) {
    const hal::FrameStatus st = source.next(frame);
    if (st == hal::FrameStatus::kEndOfStream) break;
    if (st == hal::FrameStatus::kCorruptFrame || st == hal::FrameStatus::kTimeout) {
      if (!cmd.quiet)
        std::fprintf(stderr, "epitrack-track: skipping frame: %s\n", source.lastError().c_str());
      if (clip.tracker) clip.tracker->skipFrames(1);
      continue;
    }
    if (st != hal::FrameStatus::kOk) {
      std::fprintf(stderr, "epitrack-track: %s\n", source.lastError().c_str());
      return 1;
    }
    if (!clip.tracker) {
      clip.tracker = std::make_unique<epitrack::tools::ClipTracker>(
          cmd.matcher, cmd.lk, cmd.matching, frame.luma.width, frame.luma.height,
          static_cast<int>(std::max<int64_t>(1, source.info().frame_count)));
      width = frame.luma.width;
      height = frame.luma.height;
    }
    epitrack::ImageView<const uint8_t> mask;
    if (!masks.maskFor(clip.frames, frame.luma.width, frame.luma.height, mask, error)) {
      std::fprintf(stderr, "epitrack-track: %s\n", error.c_str());
      return 2;  // the --mask named on the command line does not fit the frames
    }
    const auto t0 = std::chrono::steady_clock::now();
    if (clip.tracker->track(frame.luma, mask) != epitrack::tools::ClipTracker::Status::kOk) {
      std::fprintf(stderr, "epitrack-track: frame %lld is %dx%d, the first was %dx%d\n",
                   static_cast<long long>(frame.index), frame.luma.width, frame.luma.height, width,
                   height);
      return 1;
    }
    clip.ms_total +=
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    clip.frame_index.push_back(frame.index);
    if (!cmd.quiet && !clip.decision_reported && !clip.tracker->decision().empty()) {
      std::fprintf(stderr, "epitrack-track: matcher: %s\n", clip.tracker->decision().c_str());
      clip.decision_reported = true;
    }
    if (cmd.frame_stats && clip.tracker->lkTracker() != nullptr)
      printFrameStats(clip.frames, clip.tracker->lkTracker()->lastStats());
    ++clip.frames;
    if (!cmd.quiet && clip.frames % 50 == 0) {
      std::fprintf(stderr, "epitrack-track: frame %d, %d live features\n", clip.frames,
                   clip.tracker->liveFeatures());
    }
  }
  return -1;
}

/// The tracks of the clip (the descriptor matcher knows them only now), rows in frame order, and
/// the length of each track.
std::vector<hal::TrackRow> trackRows(const TrackCommand& cmd, TrackedClip& clip,
                                     std::map<int64_t, int>& lengths) {
  std::vector<hal::TrackRow> rows;
  if (!clip.tracker) return rows;
  epitrack::TrackTable table;
  std::vector<int> features_per_frame;
  std::unordered_map<int64_t, uint8_t> first_gray;
  clip.tracker->finish(table, features_per_frame, first_gray);
  if (!cmd.quiet && !clip.decision_reported)
    std::fprintf(stderr, "epitrack-track: matcher: %s\n", clip.tracker->decision().c_str());
  rows.reserve(table.observations().size());
  for (const auto& ob : table.observations()) {
    const int64_t id = table.trackId(ob.track);
    rows.push_back(hal::TrackRow{clip.frame_index[static_cast<std::size_t>(ob.frame)],
                                 static_cast<int32_t>(id), ob.x, ob.y});
    ++lengths[id];
  }
  return rows;
}

/// The closing line: tracks, their lengths, the time per frame.
void printSummary(const TrackedClip& clip, std::size_t rows, const std::map<int64_t, int>& lengths,
                  const std::string& out) {
  std::vector<int> len;
  for (const auto& [id, n] : lengths) len.push_back(n);
  std::sort(len.begin(), len.end());
  const double mean = static_cast<double>(rows) / static_cast<double>(len.size() ? len.size() : 1);
  auto at_least = [&len](int n) {
    return static_cast<long long>(
        std::count_if(len.begin(), len.end(), [n](int l) { return l >= n; }));
  };
  const int frames = std::max(clip.frames, 1);
  std::fprintf(stderr,
               "epitrack-track: %d frames, %zu tracks (mean length %.1f, median %d; %lld of 5+ "
               "frames, %lld of 10+, %lld of 20+, %lld of 50+), %.0f live per frame, %zu rows, "
               "%.2f ms/frame -> %s\n",
               clip.frames, len.size(), mean, len.empty() ? 0 : len[len.size() / 2], at_least(5),
               at_least(10), at_least(20), at_least(50), static_cast<double>(rows) / frames, rows,
               clip.ms_total / frames, out.c_str());
}

}  // namespace

// Stages: command line -> inputs -> track the frames -> the rows -> tracks.csv -> summary.
int main(int argc, char** argv) {
  hal::selectKernelsForThisCpu();
  TrackCommand cmd;
  if (const int code = parseCommandLine(argc, argv, cmd); code >= 0) return code;
  std::string error;
  auto source = hal::openFrameSource(cmd.input, {}, error);
  MaskSource masks;
  if (!source || !masks.open(cmd.mask_spec, error)) {
    std::fprintf(stderr, "epitrack-track: %s\n", error.c_str());
    return 2;
  }
  if (!outputWritable(cmd.out)) return 2;
  epitrack::tools::installInterruptHandlers();
  TrackedClip clip;
  if (const int code = trackFrames(cmd, *source, masks, clip); code >= 0) return code;
  const bool interrupted = epitrack::tools::interruptRequested();
  if (clip.frames == 0 && !interrupted) {
    std::fprintf(stderr, "epitrack-track: %s: no frames\n", cmd.input.c_str());
    return 1;
  }
  std::map<int64_t, int> lengths;
  const std::vector<hal::TrackRow> rows = trackRows(cmd, clip, lengths);
  if (!hal::writeTracksCsv(cmd.out, rows, error)) {
    std::fprintf(stderr, "epitrack-track: %s\n", error.c_str());
    return 1;
  }
  if (!cmd.quiet) printSummary(clip, rows.size(), lengths, cmd.out);
  if (interrupted) {
    std::fprintf(stderr, "epitrack-track: interrupted by %s after %d frames; %s holds them\n",
                 epitrack::tools::interruptSignalName(), clip.frames, cmd.out.c_str());
    return epitrack::tools::interruptExitCode();
  }
  return 0;
}

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "hal/io/file_util.hpp"
#include "hal/io/text_formats.hpp"
#include "tools/solve/solve_run.hpp"

// The inputs of epitrack-solve, every one checked before anything is written.

namespace epitrack::tools {

StageResult readGivenIntrinsics(SolveRun& run) {
  const SolveCommandOptions& o = run.o;
  SolverOptions& so = run.so;
  CameraIntrinsics& given = run.given;
  bool& have_given = run.have_given;
  std::string& error = run.error;
  so = o.solver;
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
  so.detect_distortion = o.detect_distortion;
  return std::nullopt;
}

StageResult openInputs(SolveRun& run) {
  const SolveCommandOptions& o = run.o;
  std::string& error = run.error;
  auto& given_rows = run.given_rows;
  run.source = hal::openFrameSource(o.input, run.source_options, error);
  if (!run.source) {
    fail(error.c_str());
    return 2;
  }
  // --tracks: read and checked (syntax, finite coordinates) before anything is written; the
  // frame range is checked against the clip once its length is known.
  run.given_tracks = !o.tracks_file.empty();
  if (run.given_tracks) {
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
  if (run.given_tracks && run.source->info().frame_count > 0 &&
      given_rows.back().frame >= static_cast<int64_t>(run.source->info().frame_count)) {
    char msg[256];
    std::snprintf(msg, sizeof(msg), "'%s' has observations in frame %lld but INPUT has %ld frames",
                  o.tracks_file.c_str(), static_cast<long long>(given_rows.back().frame),
                  static_cast<long>(run.source->info().frame_count));
    fail(msg);
    return 2;
  }
  return std::nullopt;
}

StageResult prepareOutputDir(SolveRun& run) {
  const SolveCommandOptions& o = run.o;
  std::string& error = run.error;
  MaskSource& masks = run.masks;
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
  return std::nullopt;
}

}  // namespace epitrack::tools

#pragma once

// DIR/report.html of epitrack-solve (issue 7): one self-contained HTML file (inline CSS and SVG, no
// script, no network) that shows the solve: the summary.json figures, the reprojection error and
// the live features per frame, the track-length histogram, the per-pair focal estimates with the
// chosen focal, a top view of the camera path over the point cloud, the scene frame (a side view
// of the ground, the up direction and the object, one augmented frame showing them, warnings when
// the choice is weak), and a strip of augmented frames (relative links to DIR/augmented/*.jpg).
//
// Every plotted series also sits in the file as data: each plot is an <svg> whose
// `data-series="NAME"` groups carry `data-values` (space-separated numbers, "nan" for gaps), so
// tests and scripts can check the figures against the reconstruction without parsing geometry.
//
//   render::ReportOptions options;
//   options.augmented_frames = {{0, "augmented/000000.jpg"}, ...};
//   if (!render::writeReportHtml(rec, options, out_dir + "/report.html", error)) ...

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "tools/export/reconstruction.hpp"

namespace epitrack::render {

struct ReportOptions {
  std::string title = "epitrack solve report";
  std::string input;          ///< what was solved (shown under the title), may be empty
  std::string render_object;  ///< "towers", "cube", "axes" or "none"
  /// Augmented frames available, (frame index, path relative to the report or a data: URI),
  /// ordered by frame. The strip shows `strip_frames` of them, evenly spaced.
  std::vector<std::pair<int64_t, std::string>> augmented_frames;
  int strip_frames = 6;
  std::string video;  ///< relative path of the augmented video (a link), may be empty
  /// Where the virtual object stands (scene frame), marked in the top view when set.
  bool has_object = false;
  Eigen::Vector3d object_at = Eigen::Vector3d::Zero();
  /// A frame drawn with the ground grid, the up arrow and the object (path relative to the
  /// report, e.g. "scene_frame.jpg"; empty: none), and its frame index.
  std::string scene_frame_image;
  int64_t scene_frame_index = -1;
};

/// Track length (solved-frame observations) of every scene point with at least one observation,
/// in Reconstruction::points order (points without observations are skipped).
std::vector<int> trackLengths(const io::Reconstruction& rec);

/// Indices into `options.augmented_frames` shown in the strip: `count` evenly spaced entries,
/// first and last included (all of them when there are fewer).
std::vector<std::size_t> stripSelection(std::size_t available, int count);

/// The report's bytes.
std::string formatReportHtml(const io::Reconstruction& rec, const ReportOptions& options);

/// Writes formatReportHtml() atomically (temporary name + rename) to `path`.
bool writeReportHtml(const io::Reconstruction& rec, const ReportOptions& options,
                     const std::string& path, std::string& error);

}  // namespace epitrack::render

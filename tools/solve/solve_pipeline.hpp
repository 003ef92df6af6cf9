#pragma once

// The offline pipeline behind epitrack-solve: INPUT -> 2D tracks of the whole clip -> Solver ->
// Reconstruction (tools/export) in the scene frame -> outputs and augmented frames.

#include <string>
#include <vector>

#include "algo/sfm/scene_frame.hpp"
#include "algo/sfm/solver.hpp"
#include "algo/tracking/feature_tracker.hpp"
#include "tools/export/progress.hpp"
#include "tools/export/reconstruction.hpp"

namespace epitrack::tools {

struct SolveCommandOptions {
  std::string input;
  std::string out_dir;
  std::string mask;             ///< PGM or directory of PGMs (0 = never track)
  std::string intrinsics_file;  ///< given intrinsics (focal, principal point, distortion)
  double focal_px = 0.0;        ///< given focal (0: self-calibrate)
  int distortion = 0;           ///< 0 none, 1 k1, 2 k1k2 (estimated)
  SceneFrameOptions scene;      ///< --origin (defaults tuned in the constructor)
  std::string origin_text = "plane";
  std::string render = "none";   ///< towers | cube | axes | none
  std::string overlay = "none";  ///< tracks: augmented frames side by side with the 2D tracks
  Eigen::Vector3d object_at = Eigen::Vector3d::Zero();
  double object_scale = 1.0;
  FeatureTrackerOptions tracker;
  SolverOptions solver;
  io::ProgressReporter::Mode progress = io::ProgressReporter::Mode::kAuto;
  double max_memory_mib = 4096.0;  ///< refuse inputs whose buffers would need more (--max-memory)
};

/// Bytes the solve reserves up front for a clip of this size: the tracker's frame, pyramid,
/// gradient and template buffers plus the track table for `frames` frames (a lower bound of
/// the peak; the solver's own state is small beside it).
double estimateSolveMemoryBytes(int width, int height, int max_features, int window, long frames);

/// Runs the whole solve and writes every output. Returns the process exit code (0 solved, 1 a
/// runtime failure, with summary.json saying why whenever the clip could be read).
int runSolve(const SolveCommandOptions& options);

}  // namespace epitrack::tools

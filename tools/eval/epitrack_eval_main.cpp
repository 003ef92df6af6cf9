// epitrack-eval: compares an estimated trajectory with ground truth (ARCHITECTURE.md "Commands").
#include <cmath>
#include <cstdio>
#include <string>

#include "hal/io/text_formats.hpp"
#include "tools/common/command_line.hpp"
#include "tools/eval/trajectory_metrics.hpp"

namespace {
std::string jsonNumber(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.9g", v);
  return buf;
}

// A thin path (a walk, a dolly) fixes the centres' alignment about its long axis only through
// its narrow spread across it: say so when the orientations' own alignment fits the centres about
// as well and the orientations much better.
void printAlignmentNote(const epitrack::eval::TrajectoryMetrics& m) {
  const double own = m.rot_err_deg_mean_orient_aligned;
  if (m.rot_err_deg_mean > 2.0 * own + 0.01 && m.ate_rmse_orient_aligned <= 2.0 * m.ate_rmse) {
    std::fprintf(stderr,
                 "epitrack-eval: note: the rotation error after the centres' alignment (%.3g "
                 "deg) is the alignment's: with the orientations' own rotation the orientations "
                 "agree to %.3g deg and the centres to %.3g (ate_rmse %.3g)\n",
                 m.rot_err_deg_mean, own, m.ate_rmse_orient_aligned, m.ate_rmse);
  }
}
}  // namespace

int main(int argc, char** argv) {
  std::string gt_path;
  std::string est_path;
  std::string gt_k_path;
  std::string est_k_path;
  double max_dt = 1e-6;
  epitrack::tools::CommandLine cl(
      "epitrack-eval",
      "--gt groundtruth.txt --est cameras.tum [--gt-intrinsics F --est-intrinsics F]",
      "Associates the two trajectories by frame index (t), aligns the estimate to the ground truth "
      "with\n"
      "the least-squares similarity (Umeyama), and prints one JSON object: ate_rmse and "
      "ate_rmse_rel\n"
      "(ATE RMSE of the camera centres after alignment, and divided by the ground-truth path "
      "length over\n"
      "the matched frames), ate_max, rot_err_deg_mean/max (camera orientation after alignment),\n"
      "rpe_trans_rel (sum of relative translation errors between consecutive matched frames, "
      "scaled by\n"
      "the alignment, over the path length), rpe_rot_deg_mean, focal_err_pct (when both intrinsics "
      "are\n"
      "given; 100 |fx_est - fx_gt| / fx_gt), scale, matched_frames, gt_frames, est_frames,\n"
      "and the second alignment, whose rotation is the orientations' own (no positions):\n"
      "rot_err_deg_mean/max_orient_aligned, ate_rmse_orient_aligned. On a thin path (a walk, a\n"
      "dolly) the centres' alignment tilts with millimetres of error; when the second alignment\n"
      "fits both centres and orientations, a larger rot_err_deg_mean is the alignment's, and a\n"
      "note on stderr says so.");
  cl.text("gt", "FILE", "ground-truth trajectory (t tx ty tz qx qy qz qw, T_wc)", &gt_path);
  cl.text("est", "FILE", "estimated trajectory, same format (e.g. epitrack-solve's cameras.tum)",
          &est_path);
  cl.text("gt-intrinsics", "FILE", "ground-truth intrinsics.txt", &gt_k_path);
  cl.text("est-intrinsics", "FILE", "estimated intrinsics.txt", &est_k_path);
  cl.real("max-dt", "T", "largest |t_gt - t_est| that still matches (default 1e-6: frame indices)",
          &max_dt, 0.0, 1e9);
  cl.require("gt");
  cl.require("est");
  if (const auto r = cl.parse(argc, argv); r != epitrack::tools::CommandLine::Result::kOk) {
    return epitrack::tools::CommandLine::exitCode(r);
  }
  if (gt_k_path.empty() != est_k_path.empty()) {
    return cl.usageError("--gt-intrinsics and --est-intrinsics go together");
  }
  std::vector<epitrack::hal::TrajectoryEntry> gt;
  std::vector<epitrack::hal::TrajectoryEntry> est;
  std::string error;
  if (!epitrack::hal::readTrajectoryFile(gt_path, gt, error) ||
      !epitrack::hal::readTrajectoryFile(est_path, est, error)) {
    std::fprintf(stderr, "epitrack-eval: %s\n", error.c_str());
    return 2;
  }
  double focal_err = NAN;
  if (!gt_k_path.empty()) {
    epitrack::CameraIntrinsics kg;
    epitrack::CameraIntrinsics ke;
    if (!epitrack::hal::readIntrinsicsFile(gt_k_path, kg, error) ||
        !epitrack::hal::readIntrinsicsFile(est_k_path, ke, error)) {
      std::fprintf(stderr, "epitrack-eval: %s\n", error.c_str());
      return 2;
    }
    focal_err = 100.0 * std::abs(ke.fx - kg.fx) / kg.fx;
  }
  epitrack::eval::TrajectoryMetrics m;
  if (!epitrack::eval::evaluateTrajectory(gt, est, max_dt, m, error)) {
    std::fprintf(stderr, "epitrack-eval: %s\n", error.c_str());
    return 1;
  }
  printAlignmentNote(m);
  std::printf(
      "{\"ate_rmse\": %s, \"ate_rmse_rel\": %s, \"ate_max\": %s, \"rot_err_deg_mean\": %s, "
      "\"rot_err_deg_max\": %s, \"rot_err_deg_mean_orient_aligned\": %s, "
      "\"rot_err_deg_max_orient_aligned\": %s, \"ate_rmse_orient_aligned\": %s, "
      "\"rpe_trans_rel\": %s, \"rpe_rot_deg_mean\": %s, \"focal_err_pct\": %s, \"scale\": %s, "
      "\"gt_path_length\": %s, "
      "\"matched_frames\": %d, \"gt_frames\": %d, \"est_frames\": %d, \"similarity_aligned\": "
      "%s}\n",
      jsonNumber(m.ate_rmse).c_str(), jsonNumber(m.ate_rmse_rel).c_str(),
      jsonNumber(m.ate_max).c_str(), jsonNumber(m.rot_err_deg_mean).c_str(),
      jsonNumber(m.rot_err_deg_max).c_str(), jsonNumber(m.rot_err_deg_mean_orient_aligned).c_str(),
      jsonNumber(m.rot_err_deg_max_orient_aligned).c_str(),
      jsonNumber(m.ate_rmse_orient_aligned).c_str(), jsonNumber(m.rpe_trans_rel).c_str(),
      jsonNumber(m.rpe_rot_deg_mean).c_str(), jsonNumber(focal_err).c_str(),
      jsonNumber(m.scale).c_str(), jsonNumber(m.gt_path_length).c_str(), m.matched_frames,
      m.gt_frames, m.est_frames, m.aligned ? "true" : "false");
  return 0;
}

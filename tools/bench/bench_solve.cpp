// epitrack-bench solve: the whole offline solve (2D tracking included) of a clip, by stage, with
// the focal given and self-calibrated, scored against the ground truth when the clip is the
// rendered orbit (704x576, 340 frames, wandering target by default). With the OpenCV comparison
// built (-DEPITRACK_BENCH_OPENCV=ON) it also times, in the same run, the reference pipeline the
// issue names: LK tracking, one keyframe pair, findEssentialMat + recoverPose, triangulation,
// solvePnPRansac per frame (new tracks triangulated every few frames), no bundle adjustment,
// known K. EPITRACK_BENCH_DUMP=FILE writes that pipeline's poses (TUM layout) for inspection.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <map>
#include <string>
#include <vector>

#include "algo/image/image.hpp"
#include "algo/sfm/solver.hpp"
#include "algo/sfm/track_table.hpp"
#include "algo/tracking/feature_tracker.hpp"
#include "tools/bench/bench_input.hpp"
#include "tools/bench/bench_registry.hpp"
#include "tools/bench/opencv_tracker.hpp"
#include "tools/common/clip_tracker.hpp"
#include "tools/common/command_line.hpp"
#include "tools/eval/trajectory_metrics.hpp"
#include "tools/synth/synthetic_sequence.hpp"

#ifdef EPITRACK_HAVE_OPENCV
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#endif

namespace epitrack::bench {
namespace {

/// Processor time in seconds (std::clock): everything runs on this one thread, and on a shared
/// machine processor time measures the work rather than the waiting.
double cpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

hal::TrajectoryEntry entryOf(int frame, const Eigen::Matrix3d& R_wc, const Eigen::Vector3d& c) {
  hal::TrajectoryEntry e;
  e.t = frame;
  e.position = c;
  e.rotation = Eigen::Quaterniond(R_wc).normalized();
  return e;
}

struct SolveRun {
  double tracking = 0, calibration = 0, initialization = 0, registration = 0, adjustment = 0;
  [[nodiscard]] double total() const {
    return tracking + calibration + initialization + registration + adjustment;
  }
  std::string status;
  int solved = 0;
  double focal = 0.0;
  std::vector<hal::TrajectoryEntry> poses;
};

SolveRun solveEpitrack(const std::vector<Image<uint8_t>>& frames, const FeatureTrackerOptions& to,
                       double given_focal) {
  SolveRun run;
  const int w = frames.front().width();
  const int h = frames.front().height();
  double t0 = cpuSeconds();
  const TrackTable tracks = trackFrames(frames, to);
  double t1 = cpuSeconds();
  run.tracking = t1 - t0;
  SolverOptions so;
  so.focal_px = given_focal;
  Solver solver(tracks, w, h, so);
  auto lap = [&](double& slot) {
    t1 = cpuSeconds();
    slot = t1 - t0;
    t0 = t1;
  };
  t0 = cpuSeconds();
  bool ok = solver.calibrate();
  lap(run.calibration);
  ok = ok && solver.initialize();
  lap(run.initialization);
  ok = ok && solver.registerFrames();
  lap(run.registration);
  ok = ok && solver.finalize();
  lap(run.adjustment);
  run.status = toString(solver.status());
  run.solved = solver.solvedFrames();
  run.focal = solver.summary().focal_px;
  for (std::size_t f = 0; f < solver.frames().size(); ++f) {
    const SolvedFrame& s = solver.frames()[f];
    if (!s.solved) continue;
    run.poses.push_back(entryOf(static_cast<int>(f), s.pose.R_cw.transpose(), s.pose.centre()));
  }
  return run;
}

/// Median of each stage over the runs, the accuracy of the last run.
void report(const char* impl, const std::vector<SolveRun>& runs,
            const std::vector<hal::TrajectoryEntry>& gt, double true_focal, int frames) {
  auto median = [&](double SolveRun::*field) {
    std::vector<double> v;
    for (const auto& r : runs) v.push_back(r.*field);
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  std::vector<double> totals;
  for (const auto& r : runs) totals.push_back(r.total());
  std::sort(totals.begin(), totals.end());
  const SolveRun& last = runs.back();
  JsonLine j;
  j.add("bench", "solve")
      .add("impl", impl)
      .add("clock", "process-cpu")
      .add("s_median", totals[totals.size() / 2])
      .add("s_min", totals.front())
      .add("runs", runs.size())
      .add("tracking_s", median(&SolveRun::tracking))
      .add("calibration_s", median(&SolveRun::calibration))
      .add("initialization_s", median(&SolveRun::initialization))
      .add("registration_s", median(&SolveRun::registration))
      .add("bundle_adjustment_s", median(&SolveRun::adjustment))
      .add("status", last.status)
      .add("frames", frames)
      .add("solved_frames", last.solved)
      .add("focal_px", last.focal);
  if (!gt.empty() && last.poses.size() >= 3) {
    eval::TrajectoryMetrics m;
    std::string error;
    if (eval::evaluateTrajectory(gt, last.poses, 0.5, m, error)) {
      j.add("ate_rmse_rel_pct", 100.0 * m.ate_rmse_rel)
          .add("rot_err_deg_mean", m.rot_err_deg_mean)
          .add("focal_err_pct", 100.0 * std::abs(last.focal - true_focal) / true_focal);
    }
  }
  j.print();
}

#ifdef EPITRACK_HAVE_OPENCV
/// The OpenCV reference pipeline (known K, no bundle adjustment). Tracks as the frontend bench
/// does (goodFeaturesToTrack + calcOpticalFlowPyrLK, re-detection below a fraction), initialises
/// on frame 0 and the first frame whose median track displacement reaches 5 % of the width,
/// then registers every frame by solvePnPRansac and triangulates new tracks every 10 frames
/// between the frame and the one 10 frames before.
SolveRun solveOpenCv(const std::vector<Image<uint8_t>>& frames, const FeatureTrackerOptions& o,
                     double focal) {
  SolveRun run;
  const int w = frames.front().width();
  const int h = frames.front().height();
  const cv::Matx33d K(focal, 0, (w - 1) * 0.5, 0, focal, (h - 1) * 0.5, 0, 0, 1);
  const std::size_t n = frames.size();
  // ---- tracking
  double t0 = cpuSeconds();
  std::vector<std::map<int, cv::Point2f>> obs(n);
  {
    OpenCvTracker tracker(w, h, o);
    for (std::size_t f = 0; f < n; ++f) {
      const cv::Mat img = OpenCvTracker::wrap(frames[f]);
      tracker.flow(img);
      tracker.redetect(img);
      const auto& pts = tracker.points();
      for (std::size_t i = 0; i < pts.size(); ++i) obs[f][tracker.ids()[i]] = pts[i];
      tracker.endFrame();
    }
  }
  double t1 = cpuSeconds();
  run.tracking = t1 - t0;
  t0 = t1;

  auto common = [&](std::size_t a, std::size_t b, std::vector<int>& ids,
                    std::vector<cv::Point2f>& pa, std::vector<cv::Point2f>& pb) {
    ids.clear();
    pa.clear();
    pb.clear();
    for (const auto& [id, p] : obs[a]) {
      const auto it = obs[b].find(id);
      if (it == obs[b].end()) continue;
      ids.push_back(id);
      pa.push_back(p);
      pb.push_back(it->second);
    }
  };
  // ---- initial pair
  std::vector<int> ids;
  std::vector<cv::Point2f> pa, pb;
  std::size_t second = 1;
  for (; second + 1 < n; ++second) {
    common(0, second, ids, pa, pb);
    std::vector<double> d;
    for (std::size_t i = 0; i < pa.size(); ++i) d.push_back(cv::norm(pa[i] - pb[i]));
    if (d.size() < 8) break;
    std::nth_element(d.begin(), d.begin() + static_cast<long>(d.size() / 2), d.end());
    if (d[d.size() / 2] >= 0.05 * w) break;
  }
  std::vector<cv::Matx33d> Rs(n);
  std::vector<cv::Vec3d> ts(n);
  std::vector<bool> solved(n, false);
  std::map<int, cv::Point3d> map;
  auto projection = [&](std::size_t f) {
    cv::Matx34d P;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) P(r, c) = Rs[f](r, c);
      P(r, 3) = ts[f](r);
    }
    return K * P;
  };
  auto triangulate = [&](std::size_t a, std::size_t b, bool only_new) {
    common(a, b, ids, pa, pb);
    if (ids.empty()) return;
    cv::Mat X4;
    cv::triangulatePoints(projection(a), projection(b), pa, pb, X4);
    X4.convertTo(X4, CV_64F);
    for (std::size_t i = 0; i < ids.size(); ++i) {
      if (only_new && map.count(ids[i]) != 0) continue;
      const double wgt = X4.at<double>(3, static_cast<int>(i));
      if (std::abs(wgt) < 1e-12) continue;
      const cv::Point3d X(X4.at<double>(0, static_cast<int>(i)) / wgt,
                          X4.at<double>(1, static_cast<int>(i)) / wgt,
                          X4.at<double>(2, static_cast<int>(i)) / wgt);
      const cv::Vec3d ca = Rs[a] * cv::Vec3d(X.x, X.y, X.z) + ts[a];
      const cv::Vec3d cb = Rs[b] * cv::Vec3d(X.x, X.y, X.z) + ts[b];
      if (ca[2] <= 0 || cb[2] <= 0) continue;
      // The usual acceptance tests of a minimal pipeline: both reprojections within 2 px and an
      // angle of at least 1 degree between the rays (Hartley & Zisserman 12.6).
      auto reproj = [&](const cv::Vec3d& c, const cv::Point2f& p) {
        const cv::Vec3d u = K * c;
        return std::hypot(u[0] / u[2] - static_cast<double>(p.x),
                          u[1] / u[2] - static_cast<double>(p.y));
      };
      const cv::Vec3d ray_a = Rs[a].t() * ca, ray_b = Rs[b].t() * cb;
      const double cos_angle = ray_a.dot(ray_b) / (cv::norm(ray_a) * cv::norm(ray_b));
      if (reproj(ca, pa[i]) < 2.0 && reproj(cb, pb[i]) < 2.0 && cos_angle < std::cos(M_PI / 180.0))
        map[ids[i]] = X;
    }
  };
  common(0, second, ids, pa, pb);
  bool ok = pa.size() >= 8;
  if (ok) {
    cv::Mat inl;
    const cv::Mat E = cv::findEssentialMat(pa, pb, K, cv::RANSAC, 0.999, 1.0, inl);
    cv::Mat R, t;
    ok = !E.empty() && E.rows == 3 && cv::recoverPose(E, pa, pb, K, R, t, inl) > 0;
    if (ok) {
      Rs[0] = cv::Matx33d::eye();
      ts[0] = cv::Vec3d(0, 0, 0);
      Rs[second] = cv::Matx33d(R);
      ts[second] = cv::Vec3d(t);
      solved[0] = solved[second] = true;
      triangulate(0, second, false);
    }
  }
  t1 = cpuSeconds();
  run.initialization = t1 - t0;
  t0 = t1;
  // ---- registration
  std::size_t last_tri = second;
  cv::Mat rvec, tvec;
  for (std::size_t f = 0; ok && f < n; ++f) {
    std::vector<cv::Point3d> X;
    std::vector<cv::Point2f> x;
    for (const auto& [id, p] : obs[f]) {
      const auto it = map.find(id);
      if (it == map.end()) continue;
      X.push_back(it->second);
      x.push_back(p);
    }
    if (X.size() < 6) continue;
    // EPnP in RANSAC, then Levenberg-Marquardt on the inliers (OpenCV's own refinement).
    std::vector<int> inliers;
    if (!cv::solvePnPRansac(X, x, K, cv::noArray(), rvec, tvec, false, 100, 2.0, 0.99, inliers,
                            cv::SOLVEPNP_EPNP) ||
        inliers.size() < 12)
      continue;
    std::vector<cv::Point3d> Xi;
    std::vector<cv::Point2f> xi;
    for (const int i : inliers) {
      Xi.push_back(X[static_cast<std::size_t>(i)]);
      xi.push_back(x[static_cast<std::size_t>(i)]);
    }
    cv::solvePnPRefineLM(Xi, xi, K, cv::noArray(), rvec, tvec);
    cv::Mat R;
    cv::Rodrigues(rvec, R);
    Rs[f] = cv::Matx33d(R);
    ts[f] = cv::Vec3d(tvec);
    solved[f] = true;
    if (f >= last_tri + 10 && solved[f - 10]) {
      triangulate(f - 10, f, true);
      last_tri = f;
    }
  }
  t1 = cpuSeconds();
  run.registration = t1 - t0;
  run.status = ok ? "ok" : "initialization-failed";
  run.focal = focal;
  for (std::size_t f = 0; f < n; ++f) {
    if (!solved[f]) continue;
    Eigen::Matrix3d R_cw;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) R_cw(r, c) = Rs[f](r, c);
    const Eigen::Vector3d t(ts[f][0], ts[f][1], ts[f][2]);
    run.poses.push_back(entryOf(static_cast<int>(f), R_cw.transpose(), -R_cw.transpose() * t));
    ++run.solved;
  }
  return run;
}
#endif

int runSolve(int argc, const char* const* argv) {
  std::string input;
  int repeat = 3;
  int threads = 1;
  int frame_count = 340;
  double focal = 0.0;
  FeatureTrackerOptions to;
  to.max_features = tools::kSolveFeatures;  // epitrack-solve's default
  tools::CommandLine cl(
      "epitrack-bench solve", "[INPUT] [--repeat N] [--frames N] [--focal PX]",
      "Times the whole solve (2D tracking, calibration, initialisation,\n"
      "registration, bundle adjustment) with the focal given and self-calibrated.\n"
      "Without INPUT, renders a 704x576 orbit with a wandering target (focal 600)\n"
      "and scores both solves against its ground truth.");
  cl.positional("INPUT", "frames to solve (any INPUT form); default: synthetic orbit", &input,
                false);
  cl.integer("repeat", "N", "solves per configuration (default 3; medians are reported)", &repeat,
             1, 100);
  cl.integer("threads", "N", "threads (only 1: every figure is single-core)", &threads, 1, 1);
  cl.integer("frames", "N", "frames to render or load (default 340)", &frame_count, 2, 100000);
  cl.integer("features", "N", "LK features (default: epitrack-solve's)", &to.max_features, 8,
             100000);
  cl.real("focal", "PX", "the given focal for an INPUT (default: the rendered clip's 600)", &focal,
          1.0, 1e6);
  if (const auto r = cl.parse(argc, argv); r != tools::CommandLine::Result::kOk)
    return tools::CommandLine::exitCode(r);

  std::vector<Image<uint8_t>> frames;
  std::vector<hal::TrajectoryEntry> gt;
  std::string error;
  double true_focal = focal;
  if (!input.empty() && true_focal <= 0.0) {
    std::fprintf(stderr, "epitrack-bench solve: --focal is needed with an INPUT\n");
    return 2;
  }
  if (input.empty()) {
    synth::SynthOptions so;
    so.frames = frame_count;
    so.target_wander = 0.5;
    true_focal = so.focal;
    const synth::SyntheticSequence seq(so);
    synth::FrameRenderer renderer(seq);
    frames.resize(static_cast<std::size_t>(frame_count));
    for (int i = 0; i < frame_count; ++i) {
      renderer.render(i, frames[static_cast<std::size_t>(i)]);
      const synth::Pose p = seq.pose(i);
      gt.push_back(entryOf(i, p.R_wc, p.t_wc));
    }
  } else if (!loadBenchFrames(input, frame_count, frames, error)) {
    std::fprintf(stderr, "epitrack-bench solve: %s\n", error.c_str());
    return 2;  // INPUT named on the command line is unusable
  }
  const int n = static_cast<int>(frames.size());
  std::vector<SolveRun> given, self;
  for (int r = 0; r < repeat; ++r) given.push_back(solveEpitrack(frames, to, true_focal));
  report("epitrack", given, gt, true_focal, n);
  for (int r = 0; r < repeat; ++r) self.push_back(solveEpitrack(frames, to, 0.0));
  report("epitrack-selfcal", self, gt, true_focal, n);
#ifdef EPITRACK_HAVE_OPENCV
  cv::setNumThreads(1);
  std::vector<SolveRun> ocv;
  for (int r = 0; r < repeat; ++r) ocv.push_back(solveOpenCv(frames, to, true_focal));
  report("opencv", ocv, gt, true_focal, n);
  if (const char* dump = std::getenv("EPITRACK_BENCH_DUMP")) {
    if (FILE* fp = std::fopen(dump, "w")) {
      for (const auto& e : ocv.back().poses)
        std::fprintf(fp, "%d %f %f %f %f %f %f %f\n", static_cast<int>(e.t), e.position.x(),
                     e.position.y(), e.position.z(), e.rotation.x(), e.rotation.y(), e.rotation.z(),
                     e.rotation.w());
      std::fclose(fp);
    }
  }
  std::vector<double> a, b;
  for (const auto& x : given) a.push_back(x.total());
  for (const auto& x : ocv) b.push_back(x.total());
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  JsonLine()
      .add("bench", "solve")
      .add("impl", "ratio")
      .add("ratio", b[b.size() / 2] / a[a.size() / 2])
      .print();
#endif
  return 0;
}

const BenchRegistrar kRegister(
    "solve", "whole solve by stage (tracking included), given and self-calibrated", runSolve);

}  // namespace
}  // namespace epitrack::bench

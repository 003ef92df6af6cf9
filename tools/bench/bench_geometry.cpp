// epitrack-bench geometry: time and accuracy of the geometry solvers (fundamental, homography,
// essential, triangulation, PnP) on seeded synthetic scenes with known geometry, against the
// OpenCV equivalents on the same data in the same run when the comparison is built.
//
// Every scene is the tests' two-view generator (tools/synth/two_view_scene.hpp, header-only):
// `--points` correspondences with `--noise` px Gaussian noise, `--outliers` of them replaced by
// random pixels in view 2. F, E and triangulation use the general two-view scene; H a tilted plane
// seen from the same kind of camera pair; PnP the 3D points of the general scene against their
// (noisy, partly wrong) projections in camera 2.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "algo/geometry/essential.hpp"
#include "algo/geometry/fundamental.hpp"
#include "algo/geometry/homography.hpp"
#include "algo/geometry/pnp.hpp"
#include "algo/geometry/pose.hpp"
#include "algo/geometry/triangulation.hpp"
#include "tools/bench/bench_registry.hpp"
#include "tools/common/command_line.hpp"
#include "tools/synth/two_view_scene.hpp"

#ifdef EPITRACK_HAVE_OPENCV
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#endif

namespace epitrack::bench {
namespace {

using scenes::makeTwoViewScene;
using scenes::Motion;
using scenes::TwoViewScene;

/// Per-scene accuracy figures of one implementation of one solver; printed as medians (and the
/// worst scene where that matters) over the scenes.
struct Accuracy {
  std::vector<double> rot_err_deg;
  std::vector<double> t_err_deg;
  std::vector<double> inliers_found;
  std::vector<double> inliers_true;
  std::vector<double> true_positives;
  std::vector<double> rms_px;  ///< reprojection / Sampson / transfer rms over the true inliers
  std::vector<double> extra;   ///< solver-specific (see the field name at print time)
  int failures = 0;
};

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double worst(const std::vector<double>& v) {
  return v.empty() ? std::nan("") : *std::max_element(v.begin(), v.end());
}

void addAccuracy(JsonLine& line, const Accuracy& a, const char* rms_name, const char* extra_name) {
  if (!a.rot_err_deg.empty()) {
    line.add("rot_err_deg_median", median(a.rot_err_deg))
        .add("rot_err_deg_max", worst(a.rot_err_deg));
  }
  if (!a.t_err_deg.empty()) {
    line.add("t_err_deg_median", median(a.t_err_deg)).add("t_err_deg_max", worst(a.t_err_deg));
  }
  if (!a.inliers_found.empty()) {
    line.add("inliers_found_median", median(a.inliers_found))
        .add("inliers_true_median", median(a.inliers_true))
        .add("true_positives_median", median(a.true_positives));
  }
  if (!a.rms_px.empty()) {
    line.add(std::string(rms_name) + "_median", median(a.rms_px))
        .add(std::string(rms_name) + "_max", worst(a.rms_px));
  }
  if (extra_name != nullptr && !a.extra.empty()) {
    line.add(std::string(extra_name) + "_median", median(a.extra))
        .add(std::string(extra_name) + "_max", worst(a.extra));
  }
  line.add("failures", a.failures);
}

void countInliers(const TwoViewScene& s, const std::vector<uint8_t>& mask, Accuracy& a) {
  int found = 0, truth = 0, tp = 0;
  for (std::size_t i = 0; i < s.is_inlier.size(); ++i) {
    found += mask[i] != 0 ? 1 : 0;
    truth += s.is_inlier[i] != 0 ? 1 : 0;
    tp += (mask[i] != 0 && s.is_inlier[i] != 0) ? 1 : 0;
  }
  a.inliers_found.push_back(found);
  a.inliers_true.push_back(truth);
  a.true_positives.push_back(tp);
}

double sampsonRmsOnTrueInliers(const TwoViewScene& s, const Eigen::Matrix3d& F) {
  double sum = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < s.x1.size(); ++i) {
    if (s.is_inlier[i] == 0) continue;
    sum += sampsonSquared(F, s.x1[i], s.x2[i]);
    ++n;
  }
  return n > 0 ? std::sqrt(sum / n) : std::nan("");
}

double transferRmsOnTrueInliers(const TwoViewScene& s, const Eigen::Matrix3d& H) {
  double sum = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < s.x1.size(); ++i) {
    if (s.is_inlier[i] == 0) continue;
    sum += homographyTransferSquared(H, s.x1[i], s.x2[i]);
    ++n;
  }
  return n > 0 ? std::sqrt(sum / n) : std::nan("");
}

/// Relative pose from F with the known K (cheirality over the mask, no refinement): the measure of
/// how good an F is for what the tracker uses it for.
void poseErrorFromF(const TwoViewScene& s, const Eigen::Matrix3d& F,
                    const std::vector<uint8_t>& mask, Accuracy& a) {
  std::vector<Eigen::Vector2d> n1(s.x1.size()), n2(s.x2.size());
  for (std::size_t i = 0; i < s.x1.size(); ++i) {
    n1[i] = s.normalize(s.x1[i]);
    n2[i] = s.normalize(s.x2[i]);
  }
  RelativePoseResult rp;
  if (!recoverRelativePose(essentialFromFundamental(F, s.K(), s.K()), n1, n2, mask, rp)) return;
  a.rot_err_deg.push_back(scenes::rotationErrorDeg(rp.pose.R_cw, s.cam2.R_cw));
  a.t_err_deg.push_back(scenes::directionErrorDeg(rp.pose.t_cw, s.cam2.t_cw));
}

double reprojRmsOnTrueInliers(const TwoViewScene& s, const PoseCw& pose) {
  double sum = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < s.X.size(); ++i) {
    if (s.is_inlier[i] == 0) continue;
    const Eigen::Vector3d p = pose.toCamera(s.X[i]);
    if (!(p.z() > 0.0)) return std::nan("");
    const Eigen::Vector2d px(s.f * p.x() / p.z() + (s.width - 1) * 0.5,
                             s.f * p.y() / p.z() + (s.height - 1) * 0.5);
    sum += (px - s.x2[i]).squaredNorm();
    ++n;
  }
  return n > 0 ? std::sqrt(sum / n) : std::nan("");
}

double medianDepth(const TwoViewScene& s, const PoseCw& pose) {
  std::vector<double> z;
  z.reserve(s.X.size());
  for (const auto& X : s.X) z.push_back(pose.toCamera(X).z());
  return median(z);
}

void poseAccuracy(const TwoViewScene& s, const PoseCw& pose, const std::vector<uint8_t>& mask,
                  Accuracy& a) {
  a.rot_err_deg.push_back(scenes::rotationErrorDeg(pose.R_cw, s.cam2.R_cw));
  // PnP: the extra figure is the camera-centre error in percent of the median scene depth.
  a.extra.push_back((pose.centre() - s.cam2.centre()).norm() / medianDepth(s, s.cam2) * 100.0);
  a.rms_px.push_back(reprojRmsOnTrueInliers(s, pose));
  countInliers(s, mask, a);
}

/// One solver's figures for both implementations.
struct SolverRecord {
  std::vector<double> ms_epitrack;
  std::vector<double> ms_opencv;
  std::vector<double> ms_alt;  // F: RANSAC + eight-point refit on its inliers;
                               // triangulation: epitrack's DLT step alone
  Accuracy epitrack;
  Accuracy opencv;
  Accuracy opencv_alt;
};

struct BenchConfig {
  int repeat = 10;
  int scenes = 20;
  int points = 300;
  double outliers = 0.3;
  double noise = 0.5;
  double confidence = 0.99;
  uint64_t first_seed = 1;
};

JsonLine header(const char* solver, const char* impl, const BenchConfig& c,
                const std::vector<double>& ms) {
  const TimingStats t = summarize(ms);
  JsonLine line;
  line.add("bench", "geometry")
      .add("solver", solver)
      .add("impl", impl)
      .add("ms_median", t.median)
      .add("ms_mean", t.mean)
      .add("ms_p95", t.p95)
      .add("runs", t.n)
      .add("scenes", c.scenes)
      .add("points", c.points)
      .add("outliers", c.outliers)
      .add("noise_px", c.noise);
  return line;
}

#ifdef EPITRACK_HAVE_OPENCV
std::vector<cv::Point2d> toCv(const std::vector<Eigen::Vector2d>& v) {
  std::vector<cv::Point2d> out;
  out.reserve(v.size());
  for (const auto& p : v) out.emplace_back(p.x(), p.y());
  return out;
}

std::vector<cv::Point3d> toCv(const std::vector<Eigen::Vector3d>& v) {
  std::vector<cv::Point3d> out;
  out.reserve(v.size());
  for (const auto& p : v) out.emplace_back(p.x(), p.y(), p.z());
  return out;
}

cv::Mat toCvMat(const Eigen::Matrix3d& m) {
  cv::Mat out(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out.at<double>(r, c) = m(r, c);
  return out;
}

Eigen::Matrix3d toEigen3(const cv::Mat& m) {
  Eigen::Matrix3d out;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out(r, c) = m.at<double>(r, c);
  return out;
}

std::vector<uint8_t> maskOf(const cv::Mat& m, std::size_t n) {
  std::vector<uint8_t> out(n, 0);
  if (m.total() != n) return out;
  for (std::size_t i = 0; i < n; ++i) out[i] = m.ptr<uint8_t>()[i] != 0 ? 1 : 0;
  return out;
}
#endif

// ---- stage 1: the command line
// --------------------------------------------------------------------

/// Fills `c` from the command line. Returns the exit code when the command ends here (0 after
/// --help, 2 on a usage error), or -1 to go on.
int parseGeometryOptions(int argc, const char* const* argv, BenchConfig& c) {
  int threads = 1;
  int first_seed = 1;
  tools::CommandLine cl(
      "epitrack-bench geometry",
      "[--repeat N] [--scenes N] [--points N] [--outliers F] [--noise PX] [--confidence P]",
      "Times the geometry solvers on seeded synthetic scenes with known geometry and prints one\n"
      "JSON line per solver and implementation (fundamental, homography, essential,\n"
      "triangulation, pnp), with accuracy figures as medians over the scenes.");
  cl.integer("repeat", "N", "timed runs per scene (default 10)", &c.repeat, 1, 100000);
  cl.integer("scenes", "N", "seeded scenes (default 20)", &c.scenes, 1, 10000);
  cl.integer("seed", "S", "first scene seed (default 1)", &first_seed, 0, 1000000000);
  cl.integer("points", "N", "correspondences per scene (default 300)", &c.points, 20, 100000);
  cl.real("outliers", "F", "fraction of outliers (default 0.3)", &c.outliers, 0.0, 0.9);
  cl.real("noise", "PX", "Gaussian noise in pixels (default 0.5)", &c.noise, 0.0, 10.0);
  cl.real("confidence", "P", "RANSAC confidence for every solver (default 0.99)", &c.confidence,
          0.5, 0.999999);
  cl.integer("threads", "N", "threads (only 1 is supported: every figure is single-core)", &threads,
             1, 1);
  if (const auto r = cl.parse(argc, argv); r != tools::CommandLine::Result::kOk)
    return tools::CommandLine::exitCode(r);
  c.first_seed = static_cast<uint64_t>(first_seed);
  return -1;
}

/// The robust solvers' thresholds: 3 sigma of the Sampson distance (F, E), of the transfer error
/// (H: both views' noise), 4 sigma of the reprojection error (PnP), never below the defaults'
/// floor; the same for epitrack and OpenCV.
struct Thresholds {
  explicit Thresholds(const BenchConfig& c)
      : f(std::max(1.0, 3.0 * c.noise)),
        h(std::max(1.5, 3.0 * c.noise * std::sqrt(2.0))),
        p(std::max(1.0, 4.0 * c.noise)) {}
  double f;
  double h;
  double p;
  int max_iterations = 2000;
};

// ---- stage 2: what every scene uses, reserved once
// ------------------------------------------------

/// epitrack's solvers, their options and the buffers they write, for `c.points` correspondences.
struct EpitrackSolvers {
  EpitrackSolvers(const BenchConfig& c, const Thresholds& thr)
      : f_ransac(c.points),
        h_ransac(c.points),
        pnp(c.points),
        n1(static_cast<std::size_t>(c.points)),
        n2(static_cast<std::size_t>(c.points)),
        tri(static_cast<std::size_t>(c.points)),
        tri_dlt(static_cast<std::size_t>(c.points)) {
    f_opt.ransac.threshold = thr.f;
    f_opt.ransac.confidence = c.confidence;
    f_opt.ransac.max_iterations = thr.max_iterations;
    h_opt.ransac.threshold = thr.h;
    h_opt.ransac.confidence = c.confidence;
    h_opt.ransac.max_iterations = thr.max_iterations;
  }
  FundamentalRansac f_ransac;
  HomographyRansac h_ransac;
  PnpRansac pnp;
  FundamentalOptions f_opt;
  HomographyOptions h_opt;
  std::vector<Eigen::Vector2d> n1;  ///< normalized view-1 points (essential)
  std::vector<Eigen::Vector2d> n2;  ///< normalized view-2 points (essential, PnP)
  std::vector<TriangulationResult> tri;
  std::vector<Eigen::Vector3d> tri_dlt;
};

/// One seeded scene and what each solver takes from it.
struct GeometryScene {
  TwoViewScene s;      ///< general scene: F, E, triangulation, PnP
  TwoViewScene plane;  ///< tilted plane: H
  /// Triangulation input: the true inliers with the true poses (what triangulation sees after a
  /// solved pair), normalized coordinates.
  std::vector<std::size_t> tri_index;
  std::vector<Eigen::Vector2d> tri1;
  std::vector<Eigen::Vector2d> tri2;
  PoseCw tri_poses[2];
  TriangulationOptions t_opt;
  PnpOptions p_opt;
};

GeometryScene makeGeometryScene(uint64_t seed, const BenchConfig& c, const Thresholds& thr) {
  GeometryScene g;
  g.s = makeTwoViewScene(seed, c.points, c.noise, c.outliers);
  g.plane = makeTwoViewScene(seed, c.points, c.noise, c.outliers, Motion::kPlanarScene);
  const TwoViewScene& s = g.s;
  for (std::size_t i = 0; i < s.x1.size(); ++i)
    if (s.is_inlier[i] != 0) g.tri_index.push_back(i);
  for (const std::size_t i : g.tri_index) {
    g.tri1.push_back(s.normalize(s.x1[i]));
    g.tri2.push_back(s.normalize(s.x2[i]));
  }
  g.tri_poses[0] = s.cam1;
  g.tri_poses[1] = s.cam2;
  g.t_opt.focal_px = s.f;
  g.t_opt.max_reproj_px = 4.0 * std::max(c.noise, 0.25);
  g.t_opt.min_parallax_deg = 0.5;
  g.p_opt.ransac.threshold = thr.p;
  g.p_opt.ransac.confidence = c.confidence;
  g.p_opt.ransac.max_iterations = thr.max_iterations;
  g.p_opt.focal_px = s.f;
  g.p_opt.refine_options.focal_px = s.f;
  return g;
}

/// Pixel positions of `s` to normalized image coordinates (its centred pinhole), into `out`.
void normalizeInto(const TwoViewScene& s, const std::vector<Eigen::Vector2d>& px,
                   std::vector<Eigen::Vector2d>& out) {
  const double cx = (s.width - 1) * 0.5, cy = (s.height - 1) * 0.5;
  for (std::size_t i = 0; i < px.size(); ++i)
    out[i] = Eigen::Vector2d((px[i].x() - cx) / s.f, (px[i].y() - cy) / s.f);
}

/// Every solver's figures.
struct GeometryRecords {
  SolverRecord f, h, e, t, p;
};

// ---- stage 3: each solver on one scene; timed, or (the untimed warm-up) its accuracy recorded
// ----

void benchFundamental(EpitrackSolvers& e, const GeometryScene& g, bool timed, SolverRecord& rec) {
  const TwoViewScene& s = g.s;
  FundamentalResult fr;
  Stopwatch sw;
  const auto status = e.f_ransac.estimate(s.x1, s.x2, e.f_opt, fr);
  if (timed) {
    rec.ms_epitrack.push_back(sw.ms());
    return;
  }
  if (status != FundamentalRansac::Status::kOk) {
    ++rec.epitrack.failures;
    return;
  }
  const std::vector<uint8_t> mask(fr.mask.begin(), fr.mask.end());
  countInliers(s, mask, rec.epitrack);
  rec.epitrack.rms_px.push_back(sampsonRmsOnTrueInliers(s, fr.F));
  poseErrorFromF(s, fr.F, mask, rec.epitrack);
}

void benchHomography(EpitrackSolvers& e, const GeometryScene& g, bool timed, SolverRecord& rec) {
  const TwoViewScene& plane = g.plane;
  HomographyResult hr;
  Stopwatch sw;
  const auto status = e.h_ransac.estimate(plane.x1, plane.x2, e.h_opt, hr);
  if (timed) {
    rec.ms_epitrack.push_back(sw.ms());
    return;
  }
  if (status != HomographyRansac::Status::kOk) {
    ++rec.epitrack.failures;
    return;
  }
  countInliers(plane, std::vector<uint8_t>(hr.mask.begin(), hr.mask.end()), rec.epitrack);
  rec.epitrack.rms_px.push_back(transferRmsOnTrueInliers(plane, hr.H));
}

/// Essential: F-RANSAC, E with the known K, cheirality, refinement.
void benchEssential(EpitrackSolvers& e, const GeometryScene& g, bool timed, SolverRecord& rec) {
  const TwoViewScene& s = g.s;
  const std::size_t n = s.x1.size();
  const std::span<const Eigen::Vector2d> n1s(e.n1.data(), n), n2s(e.n2.data(), n);
  Stopwatch sw;
  FundamentalResult er;
  bool ok = e.f_ransac.estimate(s.x1, s.x2, e.f_opt, er) == FundamentalRansac::Status::kOk;
  RelativePoseResult rp;
  if (ok) {
    normalizeInto(s, s.x1, e.n1);
    normalizeInto(s, s.x2, e.n2);
    const Eigen::Matrix3d K = s.K();
    const Eigen::Matrix3d E = essentialFromFundamental(er.F, K, K);
    ok = recoverRelativePose(E, n1s, n2s, er.mask, rp) &&
         refineRelativePose(n1s, n2s, er.mask, s.f, rp.pose);
  }
  if (timed) {
    rec.ms_epitrack.push_back(sw.ms());
    return;
  }
  if (!ok) {
    ++rec.epitrack.failures;
    return;
  }
  rec.epitrack.rot_err_deg.push_back(scenes::rotationErrorDeg(rp.pose.R_cw, s.cam2.R_cw));
  rec.epitrack.t_err_deg.push_back(scenes::directionErrorDeg(rp.pose.t_cw, s.cam2.t_cw));
  countInliers(s, std::vector<uint8_t>(er.mask.begin(), er.mask.end()), rec.epitrack);
}

/// Triangulation (DLT + Gauss-Newton + checks) per true inlier, and the linear step alone (what
/// cv::triangulatePoints does), for a like-for-like figure.
void benchTriangulation(EpitrackSolvers& e, const GeometryScene& g, bool timed, SolverRecord& rec) {
  const TwoViewScene& s = g.s;
  Stopwatch sw;
  for (std::size_t j = 0; j < g.tri1.size(); ++j) {
    const Eigen::Vector2d obs[2] = {g.tri1[j], g.tri2[j]};
    e.tri[j] = triangulatePoint(g.tri_poses, obs, g.t_opt);
  }
  if (timed) rec.ms_epitrack.push_back(sw.ms());
  sw.restart();
  for (std::size_t j = 0; j < g.tri1.size(); ++j) {
    const Eigen::Vector2d obs[2] = {g.tri1[j], g.tri2[j]};
    if (!triangulateDlt(g.tri_poses, obs, e.tri_dlt[j])) e.tri_dlt[j].setConstant(std::nan(""));
  }
  if (timed) {
    rec.ms_alt.push_back(sw.ms());
    return;
  }
  double sum = 0.0;
  int ok = 0;
  std::vector<double> rel_err;
  for (std::size_t j = 0; j < g.tri1.size(); ++j) {
    if (e.tri[j].status != TriangulationStatus::kOk) continue;
    ++ok;
    for (int v = 0; v < 2; ++v) {
      const Eigen::Vector2d obs = v == 0 ? g.tri1[j] : g.tri2[j];
      sum += (g.tri_poses[v].toCamera(e.tri[j].X).hnormalized() - obs).squaredNorm() * s.f * s.f;
    }
    rel_err.push_back((e.tri[j].X - s.X[g.tri_index[j]]).norm() / s.X[g.tri_index[j]].z() * 100.0);
  }
  rec.epitrack.rms_px.push_back(ok > 0 ? std::sqrt(sum / (2.0 * ok)) : std::nan(""));
  rec.epitrack.extra.push_back(median(rel_err));
  rec.epitrack.inliers_found.push_back(ok);  // points accepted by the checks
  rec.epitrack.inliers_true.push_back(static_cast<double>(g.tri1.size()));
  rec.epitrack.true_positives.push_back(ok);
}

/// PnP: the 3D points against their projections in camera 2.
void benchPnp(EpitrackSolvers& e, const GeometryScene& g, bool timed, SolverRecord& rec) {
  const TwoViewScene& s = g.s;
  const std::span<const Eigen::Vector2d> n2s(e.n2.data(), s.x1.size());
  Stopwatch sw;
  normalizeInto(s, s.x2, e.n2);
  PnpResult pr;
  const auto status = e.pnp.estimate(s.X, n2s, g.p_opt, pr);
  if (timed) {
    rec.ms_epitrack.push_back(sw.ms());
    return;
  }
  if (status != PnpRansac::Status::kOk) {
    ++rec.epitrack.failures;
    return;
  }
  poseAccuracy(s, pr.pose, std::vector<uint8_t>(pr.mask.begin(), pr.mask.end()), rec.epitrack);
}

#ifdef EPITRACK_HAVE_OPENCV
/// One scene in OpenCV's types.
struct OpenCvScene {
  explicit OpenCvScene(const GeometryScene& g)
      : x1(toCv(g.s.x1)),
        x2(toCv(g.s.x2)),
        plane1(toCv(g.plane.x1)),
        plane2(toCv(g.plane.x2)),
        X(toCv(g.s.X)),
        K(toCvMat(g.s.K())),
        tri1(2, static_cast<int>(g.tri1.size()), CV_64F),
        tri2(2, static_cast<int>(g.tri2.size()), CV_64F),
        P1(cv::Mat::eye(3, 4, CV_64F)),
        P2(3, 4, CV_64F) {
    for (std::size_t j = 0; j < g.tri1.size(); ++j) {
      tri1.at<double>(0, static_cast<int>(j)) = g.tri1[j].x();
      tri1.at<double>(1, static_cast<int>(j)) = g.tri1[j].y();
      tri2.at<double>(0, static_cast<int>(j)) = g.tri2[j].x();
      tri2.at<double>(1, static_cast<int>(j)) = g.tri2[j].y();
    }
    for (int r = 0; r < 3; ++r) {
      for (int col = 0; col < 3; ++col) P2.at<double>(r, col) = g.s.cam2.R_cw(r, col);
      P2.at<double>(r, 3) = g.s.cam2.t_cw(r);
    }
  }
  std::vector<cv::Point2d> x1, x2, plane1, plane2;
  std::vector<cv::Point3d> X;
  cv::Mat K;
  cv::Mat tri1, tri2;  ///< normalized triangulation input, 2 x n
  cv::Mat P1, P2;      ///< the true projection matrices (normalized)
};

/// OpenCV fundamental: 7-point RANSAC, then an eight-point refit on its inliers.
void benchOpenCvFundamental(const OpenCvScene& cvs, const GeometryScene& g, const BenchConfig& c,
                            const Thresholds& thr, bool timed, SolverRecord& rec) {
  const TwoViewScene& s = g.s;
  const std::size_t n = s.x1.size();
  cv::Mat mask;
  Stopwatch sw;
  const cv::Mat F =
      cv::findFundamentalMat(cvs.x1, cvs.x2, cv::FM_RANSAC, thr.f, c.confidence, mask);
  const double ransac_ms = sw.ms();
  std::vector<cv::Point2d> in1, in2;
  const uint8_t* m = mask.empty() ? nullptr : mask.ptr<uint8_t>();
  for (std::size_t i = 0; i < n && m != nullptr; ++i) {
    if (m[i] == 0) continue;
    in1.push_back(cvs.x1[i]);
    in2.push_back(cvs.x2[i]);
  }
  cv::Mat F8;
  if (in1.size() >= 8) F8 = cv::findFundamentalMat(in1, in2, cv::FM_8POINT);
  const double refit_ms = sw.ms();
  if (timed) {
    rec.ms_opencv.push_back(ransac_ms);
    rec.ms_alt.push_back(refit_ms);
    return;
  }
  if (F.rows != 3 || F.cols != 3) {
    ++rec.opencv.failures;
    ++rec.opencv_alt.failures;
    return;
  }
  const std::vector<uint8_t> mk = maskOf(mask, n);
  const Eigen::Matrix3d Fe = toEigen3(F);
  countInliers(s, mk, rec.opencv);
  rec.opencv.rms_px.push_back(sampsonRmsOnTrueInliers(s, Fe));
  poseErrorFromF(s, Fe, mk, rec.opencv);
  if (F8.rows == 3 && F8.cols == 3) {
    const Eigen::Matrix3d F8e = toEigen3(F8);
    countInliers(s, mk, rec.opencv_alt);
    rec.opencv_alt.rms_px.push_back(sampsonRmsOnTrueInliers(s, F8e));
    poseErrorFromF(s, F8e, mk, rec.opencv_alt);
  } else {
    ++rec.opencv_alt.failures;
  }
}

/// OpenCV homography (RANSAC, then its LM refinement on the inliers).
void benchOpenCvHomography(const OpenCvScene& cvs, const GeometryScene& g, const BenchConfig& c,
                           const Thresholds& thr, bool timed, SolverRecord& rec) {
  cv::Mat mask;
  Stopwatch sw;
  const cv::Mat H = cv::findHomography(cvs.plane1, cvs.plane2, cv::RANSAC, thr.h, mask,
                                       thr.max_iterations, c.confidence);
  if (timed) {
    rec.ms_opencv.push_back(sw.ms());
    return;
  }
  if (H.rows != 3 || H.cols != 3) {
    ++rec.opencv.failures;
    return;
  }
  countInliers(g.plane, maskOf(mask, g.plane.x1.size()), rec.opencv);
  rec.opencv.rms_px.push_back(transferRmsOnTrueInliers(g.plane, toEigen3(H)));
}

/// OpenCV essential: five-point RANSAC + recoverPose.
void benchOpenCvEssential(const OpenCvScene& cvs, const GeometryScene& g, const BenchConfig& c,
                          const Thresholds& thr, bool timed, SolverRecord& rec) {
  const TwoViewScene& s = g.s;
  cv::Mat mask, R, t;
  Stopwatch sw;
  const cv::Mat E =
      cv::findEssentialMat(cvs.x1, cvs.x2, cvs.K, cv::RANSAC, c.confidence, thr.f, mask);
  cv::Mat pose_mask = mask.clone();
  int good = 0;
  if (E.rows == 3 && E.cols == 3) good = cv::recoverPose(E, cvs.x1, cvs.x2, cvs.K, R, t, pose_mask);
  if (timed) {
    rec.ms_opencv.push_back(sw.ms());
    return;
  }
  if (good <= 0) {
    ++rec.opencv.failures;
    return;
  }
  const Eigen::Matrix3d Re = toEigen3(R);
  const Eigen::Vector3d te(t.at<double>(0), t.at<double>(1), t.at<double>(2));
  rec.opencv.rot_err_deg.push_back(scenes::rotationErrorDeg(Re, s.cam2.R_cw));
  rec.opencv.t_err_deg.push_back(scenes::directionErrorDeg(te, s.cam2.t_cw));
  countInliers(s, maskOf(mask, s.x1.size()), rec.opencv);
}

/// OpenCV triangulation: linear DLT of the same observations.
void benchOpenCvTriangulation(const OpenCvScene& cvs, const GeometryScene& g, bool timed,
                              SolverRecord& rec) {
  const TwoViewScene& s = g.s;
  cv::Mat X4;
  Stopwatch sw;
  cv::triangulatePoints(cvs.P1, cvs.P2, cvs.tri1, cvs.tri2, X4);
  cv::Mat X3;
  cv::convertPointsFromHomogeneous(X4.t(), X3);
  if (timed) {
    rec.ms_opencv.push_back(sw.ms());
    return;
  }
  double sum = 0.0;
  int ok = 0;
  std::vector<double> rel_err;
  for (std::size_t j = 0; j < g.tri1.size(); ++j) {
    const cv::Point3d q = X3.at<cv::Point3d>(static_cast<int>(j));
    const Eigen::Vector3d X(q.x, q.y, q.z);
    if (!X.allFinite()) continue;
    ++ok;
    for (int v = 0; v < 2; ++v) {
      const Eigen::Vector2d obs = v == 0 ? g.tri1[j] : g.tri2[j];
      sum += (g.tri_poses[v].toCamera(X).hnormalized() - obs).squaredNorm() * s.f * s.f;
    }
    rel_err.push_back((X - s.X[g.tri_index[j]]).norm() / s.X[g.tri_index[j]].z() * 100.0);
  }
  rec.opencv.rms_px.push_back(ok > 0 ? std::sqrt(sum / (2.0 * ok)) : std::nan(""));
  rec.opencv.extra.push_back(median(rel_err));
  rec.opencv.inliers_found.push_back(ok);
  rec.opencv.inliers_true.push_back(static_cast<double>(g.tri1.size()));
  rec.opencv.true_positives.push_back(ok);
}

/// OpenCV PnP: AP3P RANSAC (EPnP refit on the inliers inside), then LM on the inliers.
void benchOpenCvPnp(const OpenCvScene& cvs, const GeometryScene& g, const BenchConfig& c,
                    const Thresholds& thr, bool timed, SolverRecord& rec) {
  const cv::Mat no_distortion;
  cv::Mat rvec, tvec;
  std::vector<int> inliers;
  Stopwatch sw;
  bool ok =
      cv::solvePnPRansac(cvs.X, cvs.x2, cvs.K, no_distortion, rvec, tvec, false, thr.max_iterations,
                         static_cast<float>(thr.p), c.confidence, inliers, cv::SOLVEPNP_AP3P);
  if (ok && inliers.size() >= 4) {
    std::vector<cv::Point3d> in_X;
    std::vector<cv::Point2d> in_x;
    for (const int i : inliers) {
      in_X.push_back(cvs.X[static_cast<std::size_t>(i)]);
      in_x.push_back(cvs.x2[static_cast<std::size_t>(i)]);
    }
    cv::solvePnPRefineLM(in_X, in_x, cvs.K, no_distortion, rvec, tvec);
  } else {
    ok = false;
  }
  if (timed) {
    rec.ms_opencv.push_back(sw.ms());
    return;
  }
  if (!ok) {
    ++rec.opencv.failures;
    return;
  }
  cv::Mat Rm;
  cv::Rodrigues(rvec, Rm);
  PoseCw pose;
  pose.R_cw = toEigen3(Rm);
  pose.t_cw = Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
  std::vector<uint8_t> mk(g.s.x1.size(), 0);
  for (const int i : inliers) mk[static_cast<std::size_t>(i)] = 1;
  poseAccuracy(g.s, pose, mk, rec.opencv);
}
#endif

// ---- stage 4: one JSON line per solver and implementation
// -----------------------------------------

void printGeometryResults(const BenchConfig& c, const GeometryRecords& rec) {
  struct Entry {
    const char* solver;
    const SolverRecord* rec;
    const char* rms_name;
    const char* extra_name;
  };
  const Entry entries[] = {
      {"fundamental", &rec.f, "sampson_rms_true_px", nullptr},
      {"homography", &rec.h, "transfer_rms_true_px", nullptr},
      {"essential", &rec.e, "rms_px", nullptr},
      {"triangulation", &rec.t, "reproj_rms_px", "point_err_pct_depth"},
      {"pnp", &rec.p, "reproj_rms_true_px", "centre_err_pct_depth"},
  };
  for (const Entry& e : entries) {
    JsonLine ours = header(e.solver, "epitrack", c, e.rec->ms_epitrack);
    if (e.rec == &rec.t) ours.timing("dlt_only_ms", summarize(e.rec->ms_alt));
    addAccuracy(ours, e.rec->epitrack, e.rms_name, e.extra_name);
    ours.print();
#ifdef EPITRACK_HAVE_OPENCV
    JsonLine theirs = header(e.solver, "opencv", c, e.rec->ms_opencv);
    if (e.rec == &rec.f) {
      theirs.add("method", "FM_RANSAC (7-point)");
      theirs.timing("refit_ms", summarize(e.rec->ms_alt));
    }
    addAccuracy(theirs, e.rec->opencv, e.rms_name, e.extra_name);
    theirs.print();
    if (e.rec == &rec.f) {
      // The same RANSAC followed by a normalized eight-point refit on its inliers.
      JsonLine refit = header(e.solver, "opencv-refit", c, e.rec->ms_alt);
      refit.add("method", "FM_RANSAC + FM_8POINT on its inliers");
      addAccuracy(refit, e.rec->opencv_alt, e.rms_name, e.extra_name);
      refit.print();
    }
    const double ours_ms = summarize(e.rec->ms_epitrack).median;
    JsonLine ratio;
    ratio.add("bench", "geometry")
        .add("solver", e.solver)
        .add("impl", "ratio")
        .add("ratio", summarize(e.rec->ms_opencv).median / ours_ms);
    if (e.rec == &rec.f) ratio.add("ratio_refit", summarize(e.rec->ms_alt).median / ours_ms);
    if (e.rec == &rec.t) {
      ratio.add("ratio_dlt_only",
                summarize(e.rec->ms_opencv).median / summarize(e.rec->ms_alt).median);
    }
    ratio.print();
#endif
  }
}

/// parse -> per scene: every solver, an untimed warm-up that records the accuracy (every solver is
/// deterministic for its input), then `--repeat` timed runs -> print.
int runGeometry(int argc, const char* const* argv) {
  BenchConfig c;
  if (const int code = parseGeometryOptions(argc, argv, c); code >= 0) return code;
  const Thresholds thr(c);
  EpitrackSolvers solvers(c, thr);
  GeometryRecords rec;
#ifdef EPITRACK_HAVE_OPENCV
  cv::setNumThreads(1);
#endif
  for (int k = 0; k < c.scenes; ++k) {
    const GeometryScene scene = makeGeometryScene(c.first_seed + static_cast<uint64_t>(k), c, thr);
#ifdef EPITRACK_HAVE_OPENCV
    const OpenCvScene cv_scene(scene);
#endif
    for (int rep = 0; rep <= c.repeat; ++rep) {
      const bool timed = rep > 0;
      benchFundamental(solvers, scene, timed, rec.f);
      benchHomography(solvers, scene, timed, rec.h);
      benchEssential(solvers, scene, timed, rec.e);
      benchTriangulation(solvers, scene, timed, rec.t);
      benchPnp(solvers, scene, timed, rec.p);
#ifdef EPITRACK_HAVE_OPENCV
      benchOpenCvFundamental(cv_scene, scene, c, thr, timed, rec.f);
      benchOpenCvHomography(cv_scene, scene, c, thr, timed, rec.h);
      benchOpenCvEssential(cv_scene, scene, c, thr, timed, rec.e);
      benchOpenCvTriangulation(cv_scene, scene, timed, rec.t);
      benchOpenCvPnp(cv_scene, scene, c, thr, timed, rec.p);
#endif
    }
  }
  printGeometryResults(c, rec);
  return 0;
}

const BenchRegistrar kRegister("geometry",
                               "geometry solvers (F, H, E, triangulation, PnP) on seeded scenes",
                               runGeometry);

}  // namespace
}  // namespace epitrack::bench

#include "tools/eval/trajectory_metrics.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>

#include "hal/io/file_util.hpp"
#include "tests/support/test_support.hpp"

namespace eval = epitrack::eval;
using epitrack::hal::TrajectoryEntry;

namespace {

// A hand-made ground truth: a camera moving along x by 1 m per frame, turning about y by 2
// deg/frame.
std::vector<TrajectoryEntry> lineTrajectory(int n) {
  std::vector<TrajectoryEntry> v;
  for (int i = 0; i < n; ++i) {
    TrajectoryEntry e;
    e.t = i;
    e.position = Eigen::Vector3d(i, 0.0, 0.0);
    e.rotation =
        Eigen::Quaterniond(Eigen::AngleAxisd(0.0349065850398866 * i, Eigen::Vector3d::UnitY()));
    v.push_back(e);
  }
  return v;
}

std::vector<TrajectoryEntry> transformed(const std::vector<TrajectoryEntry>& in, double s,
                                         const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
  std::vector<TrajectoryEntry> out = in;
  for (auto& e : out) {
    e.position = s * (R * e.position) + t;
    e.rotation = Eigen::Quaterniond(R * e.rotation.toRotationMatrix());
  }
  return out;
}

}  // namespace

TEST_CASE("Umeyama recovers a known similarity exactly", "[eval]") {
  std::vector<Eigen::Vector3d> a = {{0, 0, 0}, {1, 0, 0}, {0, 2, 0}, {0, 0, 3}, {1, 1, 1}};
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  std::vector<Eigen::Vector3d> b;
  for (const auto& p : a) b.push_back(2.5 * (R * p) + Eigen::Vector3d(1, -2, 3));
  eval::Similarity S;
  REQUIRE(eval::umeyamaAlignment(a, b, S));
  REQUIRE(S.s == Approx(2.5).epsilon(1e-12));
  REQUIRE((S.R - R).norm() < 1e-12);
  REQUIRE((S.t - Eigen::Vector3d(1, -2, 3)).norm() < 1e-12);
  // Collinear points leave the rotation about the line free: refused.
  std::vector<Eigen::Vector3d> line = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  REQUIRE_FALSE(eval::umeyamaAlignment(line, line, S));
}

TEST_CASE("A similarity-transformed copy of the ground truth scores zero", "[eval]") {
  const auto gt = lineTrajectory(20);
  // Not collinear: bend the path so the alignment is unique.
  auto bent = gt;
  for (auto& e : bent) e.position.z() = 0.05 * e.t * e.t;
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(-1.1, Eigen::Vector3d(0.3, 1, -0.2).normalized()).toRotationMatrix();
  const auto est = transformed(bent, 0.37, R, Eigen::Vector3d(5, 6, 7));
  eval::TrajectoryMetrics m;
  std::string err;
  REQUIRE(eval::evaluateTrajectory(bent, est, 1e-6, m, err));
  REQUIRE(m.matched_frames == 20);
  REQUIRE(m.aligned);
  REQUIRE(m.ate_rmse < 1e-9);
  REQUIRE(m.rot_err_deg_mean < 1e-6);
  REQUIRE(m.rpe_trans_rel < 1e-9);
  REQUIRE(m.scale == Approx(1.0 / 0.37));
}

TEST_CASE("A hand-checked zig-zag error gives the ATE it should", "[eval]") {
  // Ground truth (0,0,0), (1,0,1), (2,0,1), (3,0,0) in the plane y = 0. The estimate is off along y
  // by b * (-1/3, 1, -1, 1/3): zero mean and uncorrelated with x and z, so neither a translation
  // nor a rotation can absorb it and the best similarity is the identity (up to O(b^2) in scale).
  std::vector<TrajectoryEntry> gt(4);
  std::vector<TrajectoryEntry> est(4);
  const double z[4] = {0.0, 1.0, 1.0, 0.0};
  const double pattern[4] = {-1.0 / 3.0, 1.0, -1.0, 1.0 / 3.0};
  const double b = 0.03;
  for (int i = 0; i < 4; ++i) {
    const auto k = static_cast<std::size_t>(i);
    gt[k].t = i;
    gt[k].position = Eigen::Vector3d(i, 0.0, z[i]);
    est[k] = gt[k];
    est[k].position.y() += pattern[i] * b;
  }
  eval::TrajectoryMetrics m;
  std::string err;
  REQUIRE(eval::evaluateTrajectory(gt, est, 1e-6, m, err));
  const double expected_rmse = b * std::sqrt(5.0 / 9.0);  // sqrt(mean of pattern^2) = sqrt(5/9)
  REQUIRE(m.ate_rmse == Approx(expected_rmse).epsilon(1e-3));
  REQUIRE(m.ate_max == Approx(b).epsilon(1e-3));
  const double length =
      std::sqrt(2.0) + 1.0 + std::sqrt(2.0);  // |(1,0,1)| + |(1,0,0)| + |(1,0,-1)|
  REQUIRE(m.gt_path_length == Approx(length));
  REQUIRE(m.ate_rmse_rel == Approx(expected_rmse / length).epsilon(1e-3));
  // Relative steps are off by b * (4/3, 2, 4/3) along y.
  REQUIRE(m.rpe_trans_rel == Approx(b * (14.0 / 3.0) / length).epsilon(1e-3));
}

TEST_CASE("Association is by frame index: missing frames are skipped", "[eval]") {
  auto gt = lineTrajectory(10);
  for (auto& e : gt) e.position.y() = 0.1 * e.t * e.t;
  std::vector<TrajectoryEntry> est;
  for (const auto& e : gt) {
    if (static_cast<int>(e.t) % 3 != 1) est.push_back(e);  // frames 1, 4, 7 unsolved
  }
  est.push_back(gt[0]);
  est.back().t = 42;  // no ground truth: ignored
  eval::TrajectoryMetrics m;
  std::string err;
  REQUIRE(eval::evaluateTrajectory(gt, est, 1e-6, m, err));
  REQUIRE(m.matched_frames == 7);
  REQUIRE(m.ate_rmse < 1e-9);
  std::vector<TrajectoryEntry> one(gt.begin(), gt.begin() + 1);
  REQUIRE_FALSE(eval::evaluateTrajectory(gt, one, 1e-6, m, err));
}

TEST_CASE("A rotation error shows in rot_err_deg_mean", "[eval]") {
  auto gt = lineTrajectory(12);
  for (auto& e : gt) e.position.z() = std::sin(e.t);
  auto est = gt;
  // Every odd frame's orientation off by 1 degree about its optical axis.
  for (auto& e : est) {
    if (static_cast<int>(e.t) % 2 == 1) {
      e.rotation = Eigen::Quaterniond(
          e.rotation.toRotationMatrix() *
          Eigen::AngleAxisd(3.14159265358979323846 / 180.0, Eigen::Vector3d::UnitZ()));
    }
  }
  eval::TrajectoryMetrics m;
  std::string err;
  REQUIRE(eval::evaluateTrajectory(gt, est, 1e-6, m, err));
  // The orientations break near-ties of the alignment with a 1e-4 weight (kOrientationTieBreak):
  // the 1 degree errors tilt this planar path's alignment by about 1e-6 rad.
  REQUIRE(m.ate_rmse < 2e-5);
  REQUIRE(m.rot_err_deg_mean == Approx(0.5).epsilon(1e-3));
  REQUIRE(m.rot_err_deg_max == Approx(1.0).epsilon(1e-3));
}

TEST_CASE("A tripod or straight-line track is aligned by the camera orientations", "[eval]") {
  // A straight line (the centres leave the rotation about it free) and a tripod (all centres at
  // one point): a rotated copy must score zero rotation error once aligned by orientations.
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.3, -0.8, 0.5).normalized()).toRotationMatrix();
  for (const bool tripod : {false, true}) {
    auto gt = lineTrajectory(20);
    if (tripod)
      for (auto& e : gt) e.position.setZero();
    const auto est = transformed(gt, 2.0, R, Eigen::Vector3d(1.0, 2.0, 3.0));
    eval::TrajectoryMetrics m;
    std::string err;
    REQUIRE(eval::evaluateTrajectory(gt, est, 1e-6, m, err));
    CHECK_FALSE(m.aligned);
    CHECK(m.rot_err_deg_mean < 1e-6);
    CHECK(m.rot_err_deg_max < 1e-6);
    CHECK(m.ate_rmse < 1e-9);
    if (!tripod) CHECK(m.scale == Approx(0.5).epsilon(1e-9));
  }
  // One frame's orientation 3 degrees off: the mean over 20 frames stays near 3/20.
  auto gt = lineTrajectory(20);
  for (auto& e : gt) e.position.setZero();
  auto est = transformed(gt, 1.0, R, Eigen::Vector3d::Zero());
  est[7].rotation =
      Eigen::Quaterniond(est[7].rotation.toRotationMatrix() *
                         Eigen::AngleAxisd(3.0 * M_PI / 180.0, Eigen::Vector3d::UnitX()));
  eval::TrajectoryMetrics m;
  std::string err;
  REQUIRE(eval::evaluateTrajectory(gt, est, 1e-6, m, err));
  CHECK(m.rot_err_deg_max == Approx(2.85).margin(0.01));
  CHECK(m.rot_err_deg_mean == Approx(0.285).margin(0.005));
}

TEST_CASE("A nearly straight path takes the roll about it from the orientations", "[eval]") {
  // A car or a dolly: the centres lie within millimetres of a line, so the positions fix the
  // rotation about that line only through their noise. The estimate is an exact similarity copy
  // of the orientations with centres perturbed by a 1 mm pattern: the alignment must take the
  // roll from the orientations (zero rotation error), and the ATE must be what positions alone
  // give (the tie-break costs no position fit).
  auto gt = lineTrajectory(30);
  for (auto& e : gt) e.position.y() = 1e-6 * (std::fmod(e.t, 3.0) - 1.0);
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.9, Eigen::Vector3d(-0.2, 0.7, 0.4).normalized()).toRotationMatrix();
  auto est = transformed(gt, 0.5, R, Eigen::Vector3d(3.0, -1.0, 2.0));
  for (auto& e : est) {
    const double k = e.t;
    e.position += R * Eigen::Vector3d(0.0, 5e-4 * std::sin(1.3 * k), 5e-4 * std::cos(2.1 * k));
  }
  eval::TrajectoryMetrics m;
  std::string err;
  REQUIRE(eval::evaluateTrajectory(gt, est, 1e-6, m, err));
  CHECK(m.aligned);
  CHECK(m.rot_err_deg_mean < 0.01);
  // Positions alone: a roll chosen by the noise pattern.
  std::vector<Eigen::Vector3d> src, dst;
  for (std::size_t i = 0; i < gt.size(); ++i) {
    src.push_back(est[i].position);
    dst.push_back(gt[i].position);
  }
  eval::Similarity S;
  REQUIRE(eval::umeyamaAlignment(src, dst, S));
  const double roll_deg =
      Eigen::AngleAxisd(S.R * R).angle() * 180.0 / M_PI;  // 0 when the roll is right
  CHECK(roll_deg > 1.0);
  double sq = 0.0;
  for (std::size_t i = 0; i < src.size(); ++i) sq += (S.apply(src[i]) - dst[i]).squaredNorm();
  CHECK(m.ate_rmse == Approx(std::sqrt(sq / static_cast<double>(src.size()))).epsilon(1e-3));
}

TEST_CASE(
    "On a thin path the rotation error after alignment is bounded, the orientations' own is not",
    "[eval]") {
  // A hand-held walk: 0.5 m long, 17 mm across, exact orientations, and centres bowed by 0.5 mm
  // across the path. Aligning the centres tilts the rotation about the path by about
  // atan(0.5 / 17) — degrees of rotation error the estimate does not have: the bound must cover
  // it, and the orientations' own alignment must show it is not theirs.
  std::vector<TrajectoryEntry> gt;
  for (int i = 0; i < 100; ++i) {
    TrajectoryEntry e;
    e.t = i;
    const double u = i / 99.0;
    e.position = Eigen::Vector3d(0.5 * u, 0.024 * std::sin(3.0 * u), 0.001 * std::cos(7.0 * u));
    e.rotation =
        Eigen::Quaterniond(Eigen::AngleAxisd(0.02 * u, Eigen::Vector3d(0, 1, 0.3).normalized()));
    gt.push_back(e);
  }
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.5, 0.1, -0.8).normalized()).toRotationMatrix();
  auto est = transformed(gt, 2.0, R, Eigen::Vector3d(1.0, 0.0, -1.0));
  for (auto& e : est) {
    const double u = e.t / 99.0;
    e.position += R * Eigen::Vector3d(0.0, 0.0, 2.0 * 5e-4 * (4.0 * u * (1.0 - u) - 0.5));
  }
  eval::TrajectoryMetrics m;
  std::string err;
  REQUIRE(eval::evaluateTrajectory(gt, est, 1e-6, m, err));
  INFO("rot " << m.rot_err_deg_mean << " own " << m.rot_err_deg_mean_orient_aligned << " ate "
              << m.ate_rmse << " ate with the orientations' rotation "
              << m.ate_rmse_orient_aligned);
  CHECK(m.rot_err_deg_mean > 0.5);
  CHECK(m.ate_rmse < 1e-4);  // the tilt absorbs the bow
  CHECK(m.ate_rmse_orient_aligned > 1e-4);
  CHECK(m.ate_rmse_orient_aligned < 2.5e-4);  // the bow's RMS in GT units (0.5 mm amplitude / 2)
  CHECK(m.rot_err_deg_mean_orient_aligned < 1e-6);
  CHECK(m.rot_err_deg_max_orient_aligned < 1e-6);
}

TEST_CASE("Orientations turned against a wide path: no one alignment fits both", "[eval]") {
  // Every estimated orientation turned by 1 degree against its centres: an error of the estimate
  // (the camera looks the wrong way along its path) that the orientations' own alignment cannot
  // see and the position alignment of a wide path measures exactly.
  auto gt = lineTrajectory(20);
  for (auto& e : gt) e.position.z() = 3.0 * std::sin(0.4 * e.t);
  auto est = gt;
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(M_PI / 180.0, Eigen::Vector3d(0.2, 1.0, 0.1).normalized())
          .toRotationMatrix();
  for (auto& e : est) e.rotation = Eigen::Quaterniond(turn * e.rotation.toRotationMatrix());
  eval::TrajectoryMetrics m;
  std::string err;
  REQUIRE(eval::evaluateTrajectory(gt, est, 1e-6, m, err));
  CHECK(m.rot_err_deg_mean == Approx(1.0).epsilon(1e-3));
  CHECK(m.ate_rmse < 1e-4);  // the orientations' 1e-4 tie-break weight pulls 20 um
  CHECK(m.rot_err_deg_mean_orient_aligned < 1e-6);
  // The orientations' rotation turns the 3 m wide path by a degree: centimetres off.
  CHECK(m.ate_rmse_orient_aligned > 0.02);
}

TEST_CASE("epitrack-eval prints the contract's JSON fields and rejects bad input", "[eval][cli]") {
  epitrack::test::TempDir dir("eval");
  std::string err;
  const std::string gt =
      "# t tx ty tz qx qy qz qw\n0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n2 2 0 1 0 0 0 1\n3 3 1 1 0 0 0 "
      "1\n";
  REQUIRE(epitrack::hal::writeTextAtomic(dir.file("gt.txt"), gt, err));
  REQUIRE(epitrack::hal::writeTextAtomic(dir.file("k.txt"), "600 600 351.5 287.5 704 576\n", err));
  REQUIRE(epitrack::hal::writeTextAtomic(dir.file("k2.txt"), "606 606 351.5 287.5 704 576\n", err));
  const std::string exe = epitrack::test::binaryPath("tools/eval/epitrack-eval");
  REQUIRE(epitrack::test::run(exe + " --gt " + dir.file("gt.txt") + " --est " + dir.file("gt.txt") +
                              " --gt-intrinsics " + dir.file("k.txt") + " --est-intrinsics " +
                              dir.file("k2.txt") + " > " + dir.file("out.json")) == 0);
  std::string out;
  REQUIRE(epitrack::hal::readTextFile(dir.file("out.json"), out, err));
  for (const char* key : {"\"ate_rmse\"", "\"ate_rmse_rel\"", "\"rot_err_deg_mean\"",
                          "\"rot_err_deg_mean_orient_aligned\"", "\"ate_rmse_orient_aligned\"",
                          "\"rpe_trans_rel\"", "\"focal_err_pct\": 1", "\"matched_frames\": 4"}) {
    INFO(out);
    REQUIRE(out.find(key) != std::string::npos);
  }
  REQUIRE(epitrack::test::run(exe + " --gt /nonexistent --est " + dir.file("gt.txt") +
                              " 2>/dev/null") == 2);
  REQUIRE(epitrack::test::run(exe + " --gt " + dir.file("gt.txt") + " 2>/dev/null") == 2);
  REQUIRE(epitrack::test::run(exe + " --gt " + dir.file("gt.txt") + " --est " + dir.file("gt.txt") +
                              " --gt-intrinsics " + dir.file("k.txt") + " 2>/dev/null") == 2);
}

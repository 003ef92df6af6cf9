#include <catch2/catch.hpp>

#include <cstdint>
#include <vector>

#include "algo/geometry/essential.hpp"
#include "algo/geometry/focal_self_calibration.hpp"
#include "algo/geometry/fundamental.hpp"
#include "algo/geometry/homography.hpp"
#include "algo/geometry/pnp.hpp"
#include "algo/geometry/rolling_shutter.hpp"
#include "algo/geometry/triangulation.hpp"
#include "tests/alloc/counting_allocator.hpp"
#include "tests/geometry/two_view_scene.hpp"

// The geometry solvers run per frame (F-RANSAC and focal on new pairs, PnP and triangulation on
// every tracked frame): once constructed they must not touch the heap. Every scene is built before
// the AllocationScope opens; only the solver call is inside it.

using namespace epitrack;
using epitrack::test::AllocationScope;
using epitrack::test::makeTwoViewScene;
using epitrack::test::Motion;

namespace {

std::vector<Eigen::Vector2d> normalized(const test::TwoViewScene& s,
                                        const std::vector<Eigen::Vector2d>& px) {
  std::vector<Eigen::Vector2d> out;
  out.reserve(px.size());
  for (const auto& p : px) out.push_back(s.normalize(p));
  return out;
}

}  // namespace

TEST_CASE("F-RANSAC and H-RANSAC allocate nothing once constructed", "[alloc][geometry]") {
  FundamentalRansac f_ransac(400);
  HomographyRansac h_ransac(400);
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    const auto s = makeTwoViewScene(seed, 300, 0.5, 0.3);
    const auto plane = makeTwoViewScene(seed, 300, 0.5, 0.3, Motion::kPlanarScene);
    FundamentalOptions f_opt;
    f_opt.ransac.threshold = 1.5;
    FundamentalResult fr;
    HomographyResult hr;
    std::size_t f_allocs = 0, h_allocs = 0;
    FundamentalRansac::Status fst;
    HomographyRansac::Status hst;
    {
      AllocationScope scope;
      fst = f_ransac.estimate(s.x1, s.x2, f_opt, fr);
      f_allocs = scope.count();
    }
    {
      AllocationScope scope;
      hst = h_ransac.estimate(plane.x1, plane.x2, {}, hr);
      h_allocs = scope.count();
    }
    INFO("seed " << seed);
    REQUIRE(fst == FundamentalRansac::Status::kOk);
    REQUIRE(hst == HomographyRansac::Status::kOk);
    CHECK(f_allocs == 0);
    CHECK(h_allocs == 0);
    CHECK(fr.inliers > 180);
    CHECK(hr.inliers > 180);
  }
}

TEST_CASE("Relative pose recovery and refinement allocate nothing", "[alloc][geometry]") {
  const auto s = makeTwoViewScene(2, 300, 0.5, 0.3);
  FundamentalRansac f_ransac(400);
  FundamentalOptions f_opt;
  f_opt.ransac.threshold = 1.5;
  FundamentalResult fr;
  REQUIRE(f_ransac.estimate(s.x1, s.x2, f_opt, fr) == FundamentalRansac::Status::kOk);
  const auto n1 = normalized(s, s.x1);
  const auto n2 = normalized(s, s.x2);
  const Eigen::Matrix3d K = s.K();
  RelativePoseResult rp;
  bool recovered = false, refined = false;
  std::size_t allocs = 0;
  {
    AllocationScope scope;
    const Eigen::Matrix3d E = essentialFromFundamental(fr.F, K, K);
    recovered = recoverRelativePose(E, n1, n2, fr.mask, rp);
    refined = recovered && refineRelativePose(n1, n2, fr.mask, s.f, rp.pose);
    allocs = scope.count();
  }
  REQUIRE(recovered);
  REQUIRE(refined);
  CHECK(allocs == 0);
  CHECK(test::rotationErrorDeg(rp.pose.R_cw, s.cam2.R_cw) < 0.3);
}

TEST_CASE("Triangulation allocates nothing", "[alloc][geometry]") {
  const auto s = makeTwoViewScene(5, 100, 0.5, 0.0);
  const PoseCw poses[2] = {s.cam1, s.cam2};
  const auto n1 = normalized(s, s.x1);
  const auto n2 = normalized(s, s.x2);
  TriangulationOptions o;
  o.focal_px = s.f;
  std::vector<TriangulationResult> results(n1.size());
  std::size_t allocs = 0;
  {
    AllocationScope scope;
    for (std::size_t i = 0; i < n1.size(); ++i) {
      const Eigen::Vector2d obs[2] = {n1[i], n2[i]};
      results[i] = triangulatePoint(poses, obs, o);
    }
    allocs = scope.count();
  }
  CHECK(allocs == 0);
  int ok = 0;
  for (const auto& r : results) ok += r.status == TriangulationStatus::kOk ? 1 : 0;
  CHECK(ok >= 95);
}

TEST_CASE("PnP-RANSAC and pose refinement allocate nothing", "[alloc][geometry]") {
  PnpRansac pnp(400);
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    const auto s = makeTwoViewScene(seed, 300, 0.5, 0.3);
    const auto n2 = normalized(s, s.x2);
    PnpOptions o;
    o.focal_px = s.f;
    o.refine_options.focal_px = s.f;
    PnpResult r;
    PnpRansac::Status st;
    std::size_t allocs = 0;
    {
      AllocationScope scope;
      st = pnp.estimate(s.X, n2, o, r);
      allocs = scope.count();
    }
    INFO("seed " << seed);
    REQUIRE(st == PnpRansac::Status::kOk);
    CHECK(allocs == 0);
    CHECK(test::rotationErrorDeg(r.pose.R_cw, s.cam2.R_cw) < 0.1);
    // refinePose on its own, from a perturbed start.
    PoseCw start = s.cam2;
    start.R_cw = expSo3(Eigen::Vector3d(0.01, -0.02, 0.005)) * start.R_cw;
    start.t_cw += Eigen::Vector3d(0.05, -0.03, 0.04);
    PoseRefineSummary summary;
    bool refined = false;
    {
      AllocationScope scope;
      refined = refinePose(s.X, n2, r.mask, o.refine_options, start, &summary);
      allocs = scope.count();
    }
    REQUIRE(refined);
    CHECK(allocs == 0);
    CHECK(summary.final_rms_px < summary.initial_rms_px);
  }
}

TEST_CASE("Multi-pair focal self-calibration allocates nothing", "[alloc][geometry]") {
  std::vector<Eigen::Matrix3d> Fs;
  FundamentalRansac f_ransac(400);
  FundamentalOptions f_opt;
  f_opt.ransac.threshold = 1.5;
  for (uint64_t seed = 11; seed <= 18; ++seed) {
    const auto s = makeTwoViewScene(seed, 200, 0.5, 0.2);
    FundamentalResult fr;
    REQUIRE(f_ransac.estimate(s.x1, s.x2, f_opt, fr) == FundamentalRansac::Status::kOk);
    Fs.push_back(fr.F);
  }
  std::vector<FocalPairEstimate> per(Fs.size());
  FocalCalibrationResult r;
  std::size_t allocs = 0;
  {
    AllocationScope scope;
    r = calibrateFocalMultiPair(Fs, 640, 480, per);
    allocs = scope.count();
  }
  CHECK(allocs == 0);
  REQUIRE(r.observable);
  CHECK(r.focal_px == Approx(500.0).epsilon(0.02));
}

TEST_CASE("the rolling-shutter projection and resection allocate nothing", "[alloc][geometry]") {
  CameraIntrinsics k = CameraIntrinsics::centered(640, 480, 600.0);
  const RollingShutter rs = RollingShutter::fromReadout(0.9, 480, 239.5);
  PoseCw truth;
  truth.t_cw = Eigen::Vector3d(0.1, 0.0, 4.0);
  RollingShutterMotion motion;
  motion.angular = Eigen::Vector3d(0.0, 0.05, 0.01);
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> observed;
  for (int i = 0; i < 100; ++i) {
    const double x = -1.5 + 0.03 * i;
    const double y = -1.0 + 0.02 * ((i * 37) % 100);
    const double z = (i % 7) * 0.3;
    X.emplace_back(x, y, z);
    observed.push_back(projectRollingShutter(k, rs, truth, motion, X.back()).px);
  }
  PoseCw pose = truth;
  pose.t_cw.x() += 0.05;
  RollingShutterMotion estimated;
  RollingShutterResectionResult result;
  std::size_t allocations = 0;
  {
    AllocationScope scope;
    result = refineRollingShutterPose(k, rs, X, observed, pose, estimated);
    allocations = scope.count();
  }
  CHECK(allocations == 0);
  CHECK(result.rms_px < 1e-3);  // noise-free: the refinement reaches the truth
}

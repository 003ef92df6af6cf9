#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "algo/geometry/focal_self_calibration.hpp"
#include "algo/geometry/fundamental.hpp"
#include "algo/geometry/homography.hpp"
#include "algo/geometry/pnp.hpp"
#include "algo/geometry/resection.hpp"
#include "algo/geometry/triangulation.hpp"
#include "tests/geometry/two_view_scene.hpp"

using namespace epitrack;
using epitrack::test::makeTwoViewScene;
using epitrack::test::Motion;

namespace {

Eigen::Matrix3d estimateF(const test::TwoViewScene& s, double noise) {
  FundamentalRansac ransac(1000);
  FundamentalOptions o;
  o.ransac.threshold = std::max(1.0, 3.0 * noise);
  FundamentalResult r;
  REQUIRE(ransac.estimate(s.x1, s.x2, o, r) == FundamentalRansac::Status::kOk);
  return r.F;
}

}  // namespace

TEST_CASE("Focal self-calibration from one well-conditioned pair", "[geometry][focal]") {
  for (const double noise : {0.0, 0.5}) {
    std::vector<double> errs;
    for (uint64_t seed = 1; seed <= 8; ++seed) {
      const auto s = makeTwoViewScene(seed, 300, noise, 0.0, Motion::kGeneral, 500.0);
      const auto e = estimateFocalFromFundamental(estimateF(s, noise), s.width, s.height);
      REQUIRE(e.observable);
      errs.push_back(std::abs(e.focal_px / s.f - 1.0) * 100.0);
    }
    std::sort(errs.begin(), errs.end());
    INFO("noise " << noise << ": focal error median " << errs[4] << " % worst " << errs.back());
    CHECK(errs.back() <= (noise == 0.0 ? 0.5 : 6.0));
    CHECK(errs[4] <= (noise == 0.0 ? 0.5 : 3.0));
  }
}

TEST_CASE("Multi-pair focal beats the median single pair", "[geometry][focal]") {
  std::vector<Eigen::Matrix3d> Fs;
  std::vector<double> single;
  for (uint64_t seed = 11; seed <= 22; ++seed) {
    const auto s = makeTwoViewScene(seed, 200, 0.5, 0.2, Motion::kGeneral, 500.0);
    Fs.push_back(estimateF(s, 0.5));
  }
  std::vector<FocalPairEstimate> per(Fs.size());
  const auto r = calibrateFocalMultiPair(Fs, 640, 480, per);
  REQUIRE(r.observable);
  for (const auto& p : per)
    if (p.observable) single.push_back(std::abs(p.focal_px / 500.0 - 1.0));
  std::sort(single.begin(), single.end());
  const double median_single = single[single.size() / 2];
  const double multi = std::abs(r.focal_px / 500.0 - 1.0);
  INFO("multi " << multi * 100 << " % vs median single " << median_single * 100 << " %");
  CHECK(multi < median_single);
  CHECK(multi < 0.01);
  CHECK(r.coherent_pairs >= 8);
}

TEST_CASE("Critical motions are reported as not observable", "[geometry][focal]") {
  for (const Motion m : {Motion::kTranslation, Motion::kOrbit}) {
    for (uint64_t seed = 1; seed <= 4; ++seed) {
      const auto s = makeTwoViewScene(seed, 300, 0.3, 0.0, m, 500.0);
      const auto e = estimateFocalFromFundamental(estimateF(s, 0.3), s.width, s.height);
      INFO("motion " << static_cast<int>(m) << " seed " << seed << " f " << e.focal_px << " rise "
                     << e.rise << " cost " << e.cost);
      CHECK_FALSE(e.observable);
    }
  }
  // Pure rotation and a plane: F is not defined (any F compatible with the homography fits), so
  // the pair is classified as a homography and yields no focal from F.
  FundamentalRansac fr(500);
  HomographyRansac hr(500);
  for (const Motion m : {Motion::kRotation, Motion::kPlanarScene}) {
    for (uint64_t seed = 1; seed <= 4; ++seed) {
      const auto s = makeTwoViewScene(seed, 300, 0.3, 0.1, m, 500.0);
      const auto r = estimateFocalFromMatches(s.x1, s.x2, s.width, s.height, fr, hr, 0.3, {});
      CHECK(r.model == PairModel::kHomography);
      CHECK_FALSE(r.estimate.observable);
    }
  }
  // A general pair through the same entry point gives the focal.
  const auto g = makeTwoViewScene(3, 300, 0.3, 0.1, Motion::kGeneral, 500.0);
  const auto rg = estimateFocalFromMatches(g.x1, g.x2, g.width, g.height, fr, hr, 0.3, {});
  CHECK(rg.model == PairModel::kFundamental);
  CHECK(rg.estimate.observable);
  CHECK(rg.estimate.focal_px == Approx(500.0).epsilon(0.03));
}

TEST_CASE("Tripod focal from the homography of a rotating camera", "[geometry][focal]") {
  HomographyRansac hr(500);
  for (uint64_t seed = 1; seed <= 4; ++seed) {
    const auto s = makeTwoViewScene(seed, 300, 0.3, 0.2, Motion::kRotation, 500.0);
    HomographyResult h;
    REQUIRE(hr.estimate(s.x1, s.x2, {}, h) == HomographyRansac::Status::kOk);
    const auto e = estimateFocalFromRotation(h.H, s.width, s.height);
    CHECK(e.observable);
    CHECK(e.focal_px == Approx(500.0).epsilon(0.02));
  }
}

TEST_CASE("Triangulation returns points at the noise level and flags bad ones",
          "[geometry][triangulation]") {
  const auto s = makeTwoViewScene(5, 100, 0.0, 0.0);
  TriangulationOptions o;
  o.focal_px = s.f;
  const PoseCw poses[2] = {s.cam1, s.cam2};
  for (std::size_t i = 0; i < s.X.size(); ++i) {
    const Eigen::Vector2d obs[2] = {s.normalize(s.x1[i]), s.normalize(s.x2[i])};
    const auto r = triangulatePoint(poses, obs, o);
    CHECK(r.status == TriangulationStatus::kOk);
    CHECK((r.X - s.X[i]).norm() < 1e-8 * s.X[i].norm());
  }
  // A point behind both cameras.
  const Eigen::Vector3d behind(0.1, 0.2, -5.0);
  Eigen::Vector2d obs[2];
  for (int c = 0; c < 2; ++c) obs[c] = poses[c].toCamera(behind).hnormalized();
  CHECK(triangulatePoint(poses, obs, o).status == TriangulationStatus::kBehindCamera);
  // Identical cameras: no parallax.
  const PoseCw same[2] = {s.cam1, s.cam1};
  const Eigen::Vector2d o2[2] = {Eigen::Vector2d(0.1, 0.1), Eigen::Vector2d(0.1, 0.1)};
  CHECK(triangulatePoint(same, o2, o).status != TriangulationStatus::kOk);
  // Inconsistent observations: high reprojection error.
  const Eigen::Vector2d o3[2] = {s.normalize(s.x1[0]),
                                 s.normalize(s.x2[0] + Eigen::Vector2d(0, 25))};
  CHECK(triangulatePoint(poses, o3, o).status == TriangulationStatus::kHighReprojection);
  // NaN input.
  const Eigen::Vector2d o4[2] = {Eigen::Vector2d(std::numeric_limits<double>::quiet_NaN(), 0),
                                 Eigen::Vector2d(0, 0)};
  CHECK(triangulatePoint(poses, o4, o).status == TriangulationStatus::kDegenerate);
}

namespace {

struct PnpScene {
  PoseCw pose;
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> x;  // normalized, noisy, with outliers
  std::vector<char> inlier;
  double f = 500.0;
};

PnpScene makePnpScene(uint64_t seed, int n, double noise_px, double outliers) {
  // One draw per statement, last coordinate first (tests/support/seeded_random.hpp).
  SplitMix64 rng(seed * 31 + 7);
  PnpScene s;
  const double wy = 0.6 * rng.uniform() - 0.3;
  const double wx = 0.3 * rng.uniform() - 0.15;
  s.pose.R_cw = test::rotationScalar(Eigen::Vector3d(wx, wy, 0.2));
  const double tz = 0.2 * rng.uniform();
  const double tx = 0.5 * rng.uniform();
  s.pose.t_cw = Eigen::Vector3d(tx, -0.3, tz);
  while (static_cast<int>(s.X.size()) < n) {
    const double z = 4 + 6 * rng.uniform();
    const double y = 4 * rng.uniform() - 2;
    const double x = 6 * rng.uniform() - 3;
    const Eigen::Vector3d Xc(x, y, z);
    const Eigen::Vector3d Xw =
        test::affineScalar(s.pose.R_cw.transpose(), Xc - s.pose.t_cw, Eigen::Vector3d::Zero());
    const Eigen::Vector2d p = Xc.hnormalized();
    if (std::abs(p.x()) * s.f > 320 || std::abs(p.y()) * s.f > 240) continue;
    s.X.push_back(Xw);
    s.x.push_back(p + noise_px / s.f * test::gaussian2(rng));
    s.inlier.push_back(1);
  }
  for (int k = 0; k < static_cast<int>(outliers * n);) {
    const auto i = rng.below(static_cast<uint32_t>(n));
    if (!s.inlier[i]) continue;
    const double y = rng.uniform() * 0.9 - 0.45;
    const double x = rng.uniform() * 1.2 - 0.6;
    s.x[i] = Eigen::Vector2d(x, y);
    s.inlier[i] = 0;
    ++k;
  }
  return s;
}

}  // namespace

TEST_CASE("P3P returns the true pose among its solutions", "[geometry][pnp]") {
  for (uint64_t seed = 1; seed <= 50; ++seed) {
    const auto s = makePnpScene(seed, 3, 0.0, 0.0);
    PoseCw sols[4];
    const int n = solveP3P(s.X.data(), s.x.data(), sols);
    REQUIRE(n >= 1);
    double best = 1e9;
    for (int k = 0; k < n; ++k)
      best =
          std::min(best, (sols[k].R_cw - s.pose.R_cw).norm() + (sols[k].t_cw - s.pose.t_cw).norm());
    CHECK(best < 1e-6);
  }
}

TEST_CASE("Linear resection matches the refined pose without noise", "[geometry][pnp]") {
  const auto s = makePnpScene(3, 50, 0.0, 0.0);
  PoseCw p;
  REQUIRE(resectLinear(s.X, s.x, p));
  CHECK(test::rotationErrorDeg(p.R_cw, s.pose.R_cw) < 1e-6);
  CHECK((p.t_cw - s.pose.t_cw).norm() < 1e-6);
  PoseCw q = p;
  REQUIRE(refinePose(s.X, s.x, {}, PoseRefineOptions{10, 1.0, s.f}, q));
  CHECK(test::rotationErrorDeg(p.R_cw, q.R_cw) < 1e-6);
  // Coplanar points make the 12-unknown DLT singular: refused, not a wrong pose.
  auto flat = s;
  for (auto& X : flat.X) X.z() = 1.0;
  CHECK_FALSE(resectLinear(flat.X, flat.x, p));
  std::vector<Eigen::Vector3d> five(s.X.begin(), s.X.begin() + 5);
  std::vector<Eigen::Vector2d> five2(s.x.begin(), s.x.begin() + 5);
  CHECK_FALSE(resectLinear(five, five2, p));
}

TEST_CASE("PnP-RANSAC with refinement at 0.5 px noise and 30 % outliers", "[geometry][pnp]") {
  PnpRansac pnp(500);
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    const auto s = makePnpScene(seed, 300, 0.5, 0.3);
    PnpOptions o;
    o.focal_px = s.f;
    PnpResult r;
    REQUIRE(pnp.estimate(s.X, s.x, o, r) == PnpRansac::Status::kOk);
    const double depth = 7.0;
    INFO("seed " << seed << " rot " << test::rotationErrorDeg(r.pose.R_cw, s.pose.R_cw)
                 << " deg, centre " << (r.pose.centre() - s.pose.centre()).norm() / depth * 100
                 << " % of depth, rms " << r.rms_px);
    CHECK(test::rotationErrorDeg(r.pose.R_cw, s.pose.R_cw) < 0.05);
    CHECK((r.pose.centre() - s.pose.centre()).norm() < 0.005 * depth);
    CHECK(r.rms_px < 0.8);  // 0.5 px per coordinate: 0.71 px expected
    int tp = 0;
    for (std::size_t i = 0; i < s.X.size(); ++i) tp += (s.inlier[i] && r.mask[i]) ? 1 : 0;
    CHECK(tp >= 0.97 * 210);
  }
  // Degenerate inputs.
  PnpResult r;
  std::vector<Eigen::Vector3d> X3(3, Eigen::Vector3d(0, 0, 5));
  std::vector<Eigen::Vector2d> x3(3, Eigen::Vector2d(0, 0));
  CHECK(pnp.estimate(X3, x3, {}, r) == PnpRansac::Status::kTooFewPoints);
  std::vector<Eigen::Vector3d> Xs(10, Eigen::Vector3d(0, 0, 5));
  std::vector<Eigen::Vector2d> xs(10, Eigen::Vector2d(0, 0));
  CHECK(pnp.estimate(Xs, xs, {}, r) == PnpRansac::Status::kNoConsensus);
  xs[2].x() = std::numeric_limits<double>::infinity();
  CHECK(pnp.estimate(Xs, xs, {}, r) == PnpRansac::Status::kNonFinite);
}

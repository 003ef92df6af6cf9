#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "algo/geometry/essential.hpp"
#include "algo/geometry/fundamental.hpp"
#include "algo/geometry/homography.hpp"
#include "algo/geometry/two_view_model_selection.hpp"
#include "tests/geometry/two_view_scene.hpp"

using namespace epitrack;
using epitrack::test::makeTwoViewScene;
using epitrack::test::Motion;

namespace {

struct TwoViewOutcome {
  double rot_err_deg = 0.0;
  double t_err_deg = 0.0;
  double rms_true_inliers = 0.0;
  double recall = 0.0;     // true inliers marked inlier
  double precision = 0.0;  // marked inliers that are true inliers
};

TwoViewOutcome solveTwoView(const test::TwoViewScene& s, FundamentalRansac& ransac, double noise) {
  FundamentalResult r;
  FundamentalOptions options;
  options.ransac.threshold = std::max(1.0, 3.0 * noise);  // 3 sigma of the Sampson distance
  const auto st = ransac.estimate(s.x1, s.x2, options, r);
  REQUIRE(st == FundamentalRansac::Status::kOk);
  TwoViewOutcome o;
  int tp = 0, marked = 0, truth = 0;
  double sum = 0.0;
  for (std::size_t i = 0; i < s.x1.size(); ++i) {
    if (s.is_inlier[i]) {
      ++truth;
      sum += sampsonSquared(r.F, s.x1[i], s.x2[i]);
    }
    if (r.mask[i]) ++marked;
    if (r.mask[i] && s.is_inlier[i]) ++tp;
  }
  o.recall = static_cast<double>(tp) / truth;
  o.precision = static_cast<double>(tp) / marked;
  o.rms_true_inliers = std::sqrt(sum / truth);
  const Eigen::Matrix3d E = essentialFromFundamental(r.F, s.K(), s.K());
  std::vector<Eigen::Vector2d> n1, n2;
  for (std::size_t i = 0; i < s.x1.size(); ++i) {
    n1.push_back(s.normalize(s.x1[i]));
    n2.push_back(s.normalize(s.x2[i]));
  }
  RelativePoseResult rp;
  REQUIRE(recoverRelativePose(E, n1, n2, r.mask, rp));
  REQUIRE(refineRelativePose(n1, n2, r.mask, s.f, rp.pose));
  o.rot_err_deg = test::rotationErrorDeg(rp.pose.R_cw, s.cam2.R_cw);
  o.t_err_deg = test::directionErrorDeg(rp.pose.t_cw, s.cam2.t_cw);
  return o;
}

}  // namespace

TEST_CASE("Eight-point F from exact correspondences satisfies the epipolar constraint",
          "[geometry][fundamental]") {
  const auto s = makeTwoViewScene(1, 50, 0.0, 0.0);
  Eigen::Matrix3d F;
  REQUIRE(fitFundamentalEightPoint(s.x1, s.x2, {}, F));
  for (std::size_t i = 0; i < s.x1.size(); ++i) CHECK(sampsonSquared(F, s.x1[i], s.x2[i]) < 1e-12);
  // Rank 2 and the true F up to scale: F ~ K^-T [t]x R K^-1.
  Eigen::Matrix3d tx;
  const Eigen::Vector3d t = s.cam2.t_cw;
  tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  Eigen::Matrix3d Ft = s.K().inverse().transpose() * tx * s.cam2.R_cw * s.K().inverse();
  Ft /= Ft.norm();
  if (Ft.cwiseProduct(F).sum() < 0) Ft = -Ft;
  CHECK((F - Ft).norm() < 1e-8);
  CHECK(std::abs(F.determinant()) < 1e-12);
}

TEST_CASE("F-RANSAC recovers inliers and the relative pose across noise and outlier levels",
          "[geometry][fundamental]") {
  FundamentalRansac ransac(1000);
  for (const double noise : {0.0, 0.5, 1.0}) {
    for (const double outliers : {0.0, 0.3, 0.5}) {
      double worst_rot = 0.0, worst_t = 0.0, worst_recall = 1.0, worst_precision = 1.0;
      double worst_rms = 0.0;
      std::vector<double> rots;
      for (uint64_t seed = 1; seed <= 12; ++seed) {
        const auto s = makeTwoViewScene(seed, 300, noise, outliers);
        const auto o = solveTwoView(s, ransac, noise);
        rots.push_back(o.rot_err_deg);
        worst_rot = std::max(worst_rot, o.rot_err_deg);
        worst_t = std::max(worst_t, o.t_err_deg);
        worst_recall = std::min(worst_recall, o.recall);
        worst_precision = std::min(worst_precision, o.precision);
        worst_rms = std::max(worst_rms, o.rms_true_inliers);
      }
      std::sort(rots.begin(), rots.end());
      const double median_rot = 0.5 * (rots[5] + rots[6]);
      INFO("noise " << noise << " outliers " << outliers << ": rot median " << median_rot
                    << " worst " << worst_rot << " deg, t " << worst_t << " deg, recall "
                    << worst_recall << ", precision " << worst_precision << ", Sampson rms "
                    << worst_rms);
      // Rotation: the median over seeds meets the bound; single scenes may be worse by the
      // bas-relief ambiguity of a 300-point pair (the ML estimate from the true inliers, checked
      // by hand on these seeds, is itself up to 0.5 deg at 1 px).
      // 0.3 deg at 1 px from 300 inliers, scaled by 1/sqrt(inliers) when outliers replace some.
      CHECK(median_rot <= (noise == 0.0 ? 0.01 : 0.3 * noise / std::sqrt(1.0 - outliers) + 0.05));
      CHECK(worst_rot <= (noise == 0.0 ? 0.01 : 0.7 * noise));
      CHECK(worst_t <= 1.0);
      CHECK(worst_recall >= (noise == 0.0 ? 1.0 : 0.95));
      CHECK(worst_precision >= 0.97);
      CHECK(worst_rms <= std::max(1e-4, 1.2 * noise));
    }
  }
}

TEST_CASE("F-RANSAC is deterministic for a seed", "[geometry][fundamental]") {
  const auto s = makeTwoViewScene(3, 200, 0.5, 0.3);
  FundamentalRansac a(300), b(300);
  FundamentalResult ra, rb;
  REQUIRE(a.estimate(s.x1, s.x2, {}, ra) == FundamentalRansac::Status::kOk);
  REQUIRE(b.estimate(s.x1, s.x2, {}, rb) == FundamentalRansac::Status::kOk);
  CHECK(ra.F == rb.F);
  CHECK(ra.iterations == rb.iterations);
}

TEST_CASE("F-RANSAC refuses degenerate input with a status, never NaN", "[geometry][fundamental]") {
  FundamentalRansac ransac(100);
  FundamentalResult r;
  auto s = makeTwoViewScene(4, 20, 0.0, 0.0);
  std::vector<Eigen::Vector2d> few(s.x1.begin(), s.x1.begin() + 7);
  CHECK(ransac.estimate(few, few, {}, r) == FundamentalRansac::Status::kTooFewPoints);
  auto bad = s.x2;
  bad[5].x() = std::numeric_limits<double>::quiet_NaN();
  CHECK(ransac.estimate(s.x1, bad, {}, r) == FundamentalRansac::Status::kNonFinite);
  bad[5].x() = std::numeric_limits<double>::infinity();
  CHECK(ransac.estimate(s.x1, bad, {}, r) == FundamentalRansac::Status::kNonFinite);
  std::vector<Eigen::Vector2d> same(20, Eigen::Vector2d(10, 10));
  CHECK(ransac.estimate(same, same, {}, r) == FundamentalRansac::Status::kDegenerate);
  std::vector<Eigen::Vector2d> line1, line2;  // all points on one line in both views
  for (int i = 0; i < 20; ++i) {
    line1.emplace_back(10.0 + i, 20.0 + 2.0 * i);
    line2.emplace_back(30.0 + 1.5 * i, 5.0 + i);
  }
  const auto st = ransac.estimate(line1, line2, {}, r);
  CHECK(st == FundamentalRansac::Status::kDegenerate);
  std::vector<Eigen::Vector2d> big(101, Eigen::Vector2d(1, 1));
  CHECK(ransac.estimate(big, big, {}, r) == FundamentalRansac::Status::kTooManyPoints);
}

TEST_CASE("Homography RANSAC fits a plane seen from two views", "[geometry][homography]") {
  HomographyRansac ransac(500);
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    const auto s = makeTwoViewScene(seed, 200, 0.5, 0.3, Motion::kPlanarScene);
    HomographyResult r;
    HomographyOptions options;
    options.ransac.threshold = 3.0 * 0.5 * std::sqrt(2.0);  // transfer error: noise of both views
    REQUIRE(ransac.estimate(s.x1, s.x2, options, r) == HomographyRansac::Status::kOk);
    int tp = 0, truth = 0;
    for (std::size_t i = 0; i < s.x1.size(); ++i) {
      truth += s.is_inlier[i] ? 1 : 0;
      tp += (s.is_inlier[i] && r.mask[i]) ? 1 : 0;
    }
    CHECK(tp >= 0.95 * truth);
    CHECK(r.rms_transfer_px < 1.2);
  }
}

TEST_CASE("GRIC tells a general scene from a plane and a pure rotation", "[geometry][gric]") {
  FundamentalRansac fr(500);
  HomographyRansac hr(500);
  auto select = [&](Motion m, uint64_t seed) {
    const auto s = makeTwoViewScene(seed, 200, 0.5, 0.2, m);
    FundamentalResult f;
    HomographyResult h;
    REQUIRE(fr.estimate(s.x1, s.x2, {}, f) == FundamentalRansac::Status::kOk);
    REQUIRE(hr.estimate(s.x1, s.x2, {}, h) == HomographyRansac::Status::kOk);
    return selectTwoViewModel(f.F, h.H, s.x1, s.x2, 0.5, f.mask, h.mask).model;
  };
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    CHECK(select(Motion::kGeneral, seed) == TwoViewModel::kFundamental);
    CHECK(select(Motion::kPlanarScene, seed) == TwoViewModel::kHomography);
    CHECK(select(Motion::kRotation, seed) == TwoViewModel::kHomography);
  }
}

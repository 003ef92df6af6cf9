// The five-point essential matrix and EssentialRansac on seeded two-view scenes (known K).

#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <vector>

#include "algo/geometry/essential.hpp"
#include "algo/geometry/essential_five_point.hpp"
#include "tests/geometry/two_view_scene.hpp"

using epitrack::EssentialRansac;
using epitrack::EssentialRansacOptions;
using epitrack::EssentialRansacResult;
using epitrack::test::makeTwoViewScene;
using epitrack::test::Motion;
using epitrack::test::rotationErrorDeg;

namespace {

Eigen::Matrix3d trueEssential(const epitrack::test::TwoViewScene& s) {
  const Eigen::Vector3d& t = s.cam2.t_cw;
  Eigen::Matrix3d tx;
  tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  const Eigen::Matrix3d E = tx * s.cam2.R_cw;
  return E / E.norm();
}

}  // namespace

TEST_CASE("Five-point: the true essential matrix is among the solutions", "[geometry][essential]") {
  int found = 0, scenes = 0;
  for (uint64_t seed = 1; seed <= 200; ++seed) {
    const auto s = makeTwoViewScene(seed, 5, 0.0, 0.0);
    if (s.X.size() < 5) continue;
    ++scenes;
    Eigen::Vector2d a[5], b[5];
    for (int i = 0; i < 5; ++i) {
      a[i] = s.normalize(s.x1[static_cast<std::size_t>(i)]);
      b[i] = s.normalize(s.x2[static_cast<std::size_t>(i)]);
    }
    Eigen::Matrix3d E[10];
    const int n = epitrack::essentialFivePoint(a, b, E);
    REQUIRE(n <= 10);
    const Eigen::Matrix3d Et = trueEssential(s);
    double best = std::numeric_limits<double>::infinity();
    for (int k = 0; k < n; ++k) {
      best = std::min({best, (E[k] - Et).norm(), (E[k] + Et).norm()});
      // Every solution satisfies the five constraints and the essential constraints.
      for (int i = 0; i < 5; ++i)
        CHECK(std::abs(b[i].homogeneous().dot(E[k] * a[i].homogeneous())) < 1e-9);
      CHECK(std::abs(E[k].determinant()) < 1e-9);
    }
    found += best < 1e-7 ? 1 : 0;
  }
  CHECK(scenes >= 190);
  CHECK(found == scenes);
}

TEST_CASE("EssentialRansac: rotation, inliers and outliers at 50 % outliers",
          "[geometry][essential]") {
  EssentialRansac er(400);
  for (uint64_t seed = 1; seed <= 12; ++seed) {
    INFO("seed " << seed);
    const auto s = makeTwoViewScene(seed, 300, 0.5, 0.5);
    std::vector<Eigen::Vector2d> n1, n2;
    for (std::size_t i = 0; i < s.x1.size(); ++i) {
      n1.push_back(s.normalize(s.x1[i]));
      n2.push_back(s.normalize(s.x2[i]));
    }
    EssentialRansacOptions o;
    o.focal_px = s.f;
    o.ransac.seed = seed;
    EssentialRansacResult r;
    REQUIRE(er.estimate(n1, n2, o, r) == EssentialRansac::Status::kOk);
    int tp = 0, fp = 0, inliers = 0;
    for (std::size_t i = 0; i < s.x1.size(); ++i) {
      inliers += s.is_inlier[i] ? 1 : 0;
      if (!r.mask[i]) continue;
      tp += s.is_inlier[i] ? 1 : 0;
      fp += s.is_inlier[i] ? 0 : 1;
    }
    CHECK(tp >= 0.95 * inliers);
    CHECK(fp <= 0.03 * (tp + fp));
    const std::vector<uint8_t> mask(r.mask.begin(), r.mask.end());
    epitrack::RelativePoseResult rp;
    REQUIRE(epitrack::recoverRelativePose(r.E, n1, n2, mask, rp));
    CHECK(rotationErrorDeg(rp.pose.R_cw, s.cam2.R_cw) < 0.5);
    CHECK(epitrack::test::directionErrorDeg(rp.pose.t_cw, s.cam2.t_cw) < 3.0);
  }
}

TEST_CASE("EssentialRansac: bad input gets a status", "[geometry][essential]") {
  EssentialRansac er(10);
  EssentialRansacResult r;
  std::vector<Eigen::Vector2d> a(4, Eigen::Vector2d(0.1, 0.2)), b(4, Eigen::Vector2d(0.1, 0.2));
  CHECK(er.estimate(a, b, {}, r) == EssentialRansac::Status::kTooFewPoints);
  a.resize(11, Eigen::Vector2d(0.3, 0.1));
  b.resize(11, Eigen::Vector2d(0.3, 0.1));
  CHECK(er.estimate(a, b, {}, r) == EssentialRansac::Status::kTooManyPoints);
  a.resize(8);
  b.resize(8);
  a[3].x() = std::numeric_limits<double>::quiet_NaN();
  CHECK(er.estimate(a, b, {}, r) == EssentialRansac::Status::kNonFinite);
}

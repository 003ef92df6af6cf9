// relativePoseOverSeeds (issue 22): a relative pose its matches determine comes out the same
// whatever the RANSAC seed; one they do not (a small, nearly flat patch far away, where E's
// rotation trades against its translation) spreads over degrees, which the key-frame solve reads
// as "not determined" (SolverOptions::keyframe_max_rotation_spread_deg).
#include <catch2/catch.hpp>

#include <cstdio>
#include <vector>

#include "algo/geometry/determined_relative_pose.hpp"
#include "tests/geometry/two_view_scene.hpp"

namespace et = epitrack::test;
using epitrack::EssentialRansacOptions;
using epitrack::RelativePoseHypothesis;

namespace {

struct Matches {
  std::vector<Eigen::Vector2d> n1, n2;
  epitrack::PoseCw truth;
};

Matches normalizedMatches(const et::TwoViewScene& s) {
  Matches m;
  for (std::size_t i = 0; i < s.x1.size(); ++i) {
    m.n1.push_back(s.normalize(s.x1[i]));
    m.n2.push_back(s.normalize(s.x2[i]));
  }
  m.truth = s.cam2;
  return m;
}

// A 0.5 m patch 6 m away, 1 cm of relief, seen from two cameras 0.15 m apart turned by 6 degrees:
// the two views of a small flat patch under weak perspective.
et::TwoViewScene smallFlatPatch(uint64_t seed) {
  et::SplitMix64 rng(seed);
  et::TwoViewScene s;
  const Eigen::Vector3d target(0, 0, 6);
  s.cam2 = et::lookAt(Eigen::Vector3d(0.15, 0.02, 0.0), target + Eigen::Vector3d(0.45, 0.1, 0.0));
  while (s.X.size() < 80) {
    const double x = 0.5 * rng.uniform() - 0.25, y = 0.5 * rng.uniform() - 0.25;
    const double z = 0.01 * rng.uniform();
    const Eigen::Vector3d X = target + Eigen::Vector3d(x, y, z);
    s.X.push_back(X);
    s.x1.push_back(s.project(s.cam1, X) + 1.0 * et::gaussian2(rng));
    s.x2.push_back(s.project(s.cam2, X) + 1.0 * et::gaussian2(rng));
    s.is_inlier.push_back(1);
  }
  return s;
}

RelativePoseHypothesis overSeeds(const Matches& m, uint64_t seed) {
  EssentialRansacOptions o;
  o.focal_px = 500.0;
  o.ransac.threshold = 2.0;
  o.ransac.seed = seed;
  RelativePoseHypothesis h;
  REQUIRE(epitrack::relativePoseOverSeeds(m.n1, m.n2, o, 5, h));
  return h;
}

}  // namespace

TEST_CASE("A relative pose its matches determine does not move with the RANSAC seed",
          "[geometry][essential]") {
  for (uint64_t seed = 1; seed <= 4; ++seed) {
    const Matches m = normalizedMatches(et::makeTwoViewScene(seed, 200, 0.5, 0.2));
    const RelativePoseHypothesis h = overSeeds(m, seed);
    const double error = et::rotationErrorDeg(h.relative.pose.R_cw, m.truth.R_cw);
    std::printf("general scene %d: rotation error %.3f deg, spread over seeds %.3f deg\n",
                static_cast<int>(seed), error, h.rotation_spread_deg);
    CHECK(error < 0.5);
    CHECK(h.rotation_spread_deg < 2.0);  // the solve accepts up to 3
  }
}

TEST_CASE("A small flat patch far away leaves the relative rotation undetermined",
          "[geometry][essential]") {
  for (uint64_t seed = 1; seed <= 4; ++seed) {
    const Matches m = normalizedMatches(smallFlatPatch(seed));
    const RelativePoseHypothesis h = overSeeds(m, seed);
    const double error = et::rotationErrorDeg(h.relative.pose.R_cw, m.truth.R_cw);
    std::printf("small flat patch %d: rotation error %.2f deg, spread over seeds %.2f deg\n",
                static_cast<int>(seed), error, h.rotation_spread_deg);
    // The seeds disagree by more than the solve accepts (3 degrees), and the one with the most
    // inliers is no nearer the truth than that.
    CHECK(h.rotation_spread_deg > 3.0);
  }
}

#include <catch2/catch.hpp>

#include <Eigen/Geometry>

#include "algo/sfm/bundle_adjustment.hpp"
#include "tests/alloc/counting_allocator.hpp"

TEST_CASE("Bundle adjustment allocates nothing once constructed", "[alloc][ba]") {
  std::vector<epitrack::BaCamera> cams(6);
  std::vector<Eigen::Vector3d> pts;
  std::vector<epitrack::BaObservation> obs;
  const epitrack::BaIntrinsics k{500.0, 1.0, 320.0, 240.0, 0.0, 0.0};
  for (int i = 0; i < 60; ++i)
    pts.emplace_back(0.1 * (i % 8) - 0.4, 0.1 * (i / 8) - 0.4, 0.05 * (i % 5));
  for (int c = 0; c < 6; ++c) {
    cams[static_cast<std::size_t>(c)].R_cw =
        Eigen::AngleAxisd(0.05 * c, Eigen::Vector3d::UnitY()).toRotationMatrix();
    cams[static_cast<std::size_t>(c)].t_cw = Eigen::Vector3d(-0.2 * c, 0.0, 3.0);
    for (int i = 0; i < 60; ++i) {
      Eigen::Vector2d uv;
      epitrack::BundleAdjuster::project(cams[static_cast<std::size_t>(c)], k,
                                        pts[static_cast<std::size_t>(i)], uv);
      obs.push_back({c, i, uv + Eigen::Vector2d(0.1 * ((i + c) % 3 - 1), 0.1 * ((i * c) % 3 - 1))});
    }
  }
  for (auto& p : pts) p += Eigen::Vector3d(0.01, -0.01, 0.02);
  std::vector<uint8_t> fixed(6, 0);
  fixed[0] = 1;
  fixed[5] = 1;
  epitrack::BundleAdjuster ba(8, 100, 1000);
  epitrack::BundleAdjustmentOptions o;
  o.refine_focal = true;
  o.refine_distortion = 1;
  epitrack::BaIntrinsics kk = k;
  epitrack::test::AllocationScope scope;
  const auto s = ba.solve(cams, fixed, pts, {}, obs, kk, o);
  REQUIRE(scope.count() == 0);
  REQUIRE(s.final_rms_px < s.initial_rms_px);
}

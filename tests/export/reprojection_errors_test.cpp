#include <catch2/catch.hpp>

#include <cmath>
#include <string>

#include "algo/geometry/rolling_shutter.hpp"
#include "tests/export/export_fixture.hpp"
#include "tools/export/output_writers.hpp"
#include "tools/export/reprojection_errors.hpp"

using namespace epitrack::io;
namespace et = epitrack::test;

TEST_CASE("reprojection errors of exact observations are zero", "[export][reproj]") {
  Reconstruction rec = et::makeReconstruction(10, 4, -0.1, 0.02);
  computeReprojectionErrors(rec);
  CHECK(rec.mean_reproj_px < 1e-9);
  CHECK(rec.median_reproj_px < 1e-9);
  for (const auto& c : rec.cameras) {
    if (c.solved) {
      CHECK(c.inliers == 25);
      CHECK(c.mean_reproj_px < 1e-9);
    }
  }
  // Observations of unsolved frames get no residual; points count solved frames only.
  for (const auto& o : rec.observations) CHECK(std::isnan(o.residual_px) == (o.frame % 4 == 3));
  for (const auto& p : rec.points) CHECK(p.observations == 8);
}

TEST_CASE("reprojection errors: known offsets, mean, median and outliers", "[export][reproj]") {
  Reconstruction rec = et::makeReconstruction(4, 0);
  // Offsets 3-4-5 triangles: residual 5 px on every observation of frame 1, 1 px (x) on frame 2.
  for (auto& o : rec.observations) {
    if (o.frame == 1) {
      o.x += 3.0;
      o.y -= 4.0;
    } else if (o.frame == 2) {
      o.x += 1.0;
    }
  }
  computeReprojectionErrors(rec);
  CHECK(rec.cameras[1].mean_reproj_px == Approx(5.0));
  CHECK(rec.cameras[2].mean_reproj_px == Approx(1.0));
  CHECK(rec.cameras[0].mean_reproj_px == Approx(0.0).margin(1e-9));
  CHECK(rec.mean_reproj_px == Approx((5.0 + 1.0) / 4.0));
  CHECK(rec.median_reproj_px == Approx(0.5));  // 50 zeros, 25 ones, 25 fives: mid of 0 and 1
  for (const auto& p : rec.points) CHECK(p.reproj_px == Approx(1.5));

  computeReprojectionErrors(rec, 2.0);  // frame 1's observations are outliers now
  CHECK(rec.cameras[1].inliers == 0);
  CHECK(std::isnan(rec.cameras[1].mean_reproj_px));
  CHECK(rec.mean_reproj_px == Approx(1.0 / 3.0));
  CHECK(rec.observations[30].residual_px == Approx(5.0));  // still recorded
  // summary.json reports them, never NaN.
  const std::string json = formatSummaryJson(rec);
  CHECK(json.find("nan") == std::string::npos);
  CHECK(json.find("\"mean_reproj_px\": null") != std::string::npos);  // camera 1
}

TEST_CASE("reprojection errors of a rolling-shutter solve use each point's row",
          "[export][reproj]") {
  // Observations where a 30 ms readout (0.9 frame intervals) under a fast turn puts them: a
  // global-shutter projection misses by pixels, the rolling-shutter one by nothing (issue 27:
  // summary.json's mean_reproj_px of a rolling-shutter solve).
  Reconstruction rec = et::makeReconstruction(4, 0);
  rec.readout_frames = 0.9;
  rec.readout_reference_row = 0.5 * (rec.intrinsics.height - 1);
  const epitrack::RollingShutter shutter = epitrack::RollingShutter::fromReadout(
      rec.readout_frames, rec.intrinsics.height, rec.readout_reference_row);
  for (SolvedCamera& c : rec.cameras) {
    c.rs_angular = Eigen::Vector3d(0.01, -0.04, 0.005) * (1.0 + 0.2 * static_cast<double>(c.frame));
    c.rs_linear = Eigen::Vector3d(0.02, 0.0, -0.01);
  }
  for (PointObservation& o : rec.observations) {
    const SolvedCamera& c = rec.cameras[static_cast<std::size_t>(o.frame)];
    epitrack::PoseCw pose;
    pose.R_cw = c.R_wc.transpose();
    pose.t_cw = -pose.R_cw * c.p_wc;
    epitrack::RollingShutterMotion motion;
    motion.angular = c.rs_angular;
    motion.linear = c.rs_linear;
    const Eigen::Vector3d X = rec.points[static_cast<std::size_t>((o.point_id - 3) / 2)].X;
    const epitrack::RollingShutterPixel seen =
        epitrack::projectRollingShutter(rec.intrinsics, shutter, pose, motion, X);
    REQUIRE(seen.status == epitrack::RollingShutterProjection::kOk);
    o.x = seen.px.x();
    o.y = seen.px.y();
  }
  computeReprojectionErrors(rec);
  CHECK(rec.mean_reproj_px < 1e-6);
  CHECK(rec.cameras[3].inliers == 25);

  rec.readout_frames = 0.0;  // the same observations read as a global shutter
  computeReprojectionErrors(rec);
  CHECK(rec.mean_reproj_px > 1.0);
}

TEST_CASE("row misfit of a reconstruction: its residuals' row term",
          "[export][reproj][row-misfit]") {
  // 25 points a frame. Every observation moved right by 2 px at the bottom row and left by 2 px
  // at the top (x residual +4 px over the image height, as a missed yaw velocity under a rolling
  // shutter), with a small deterministic scatter so the frames have a residual scale.
  Reconstruction rec = et::makeReconstruction(10, 4);
  computeReprojectionErrors(rec);
  const epitrack::RowMisfit exact = rowMisfitOf(rec);
  CHECK(exact.frames_tested == 0);  // zero residuals: nothing to test against
  int k = 0;
  for (auto& o : rec.observations) {
    o.x += 4.0 * (o.y - rec.intrinsics.cy) / rec.intrinsics.height + 0.02 * ((k * 7) % 5 - 2);
    o.y += 0.02 * ((k * 3) % 5 - 2);
    ++k;
  }
  computeReprojectionErrors(rec);
  const epitrack::RowMisfit m = rowMisfitOf(rec);
  CHECK(m.frames_tested == 8);  // the solved frames (every fourth unsolved)
  CHECK(m.frames_sheared == 8);
  CHECK(m.misfit);
  CHECK(m.median_shear_px == Approx(4.0).margin(0.2));
  // summary.json carries it (epitrack-solve sets it after the reprojection errors).
  CHECK(formatSummaryJson(rec).find("\"row_misfit\"") == std::string::npos);
  rec.row_misfit = m;
  const std::string json = formatSummaryJson(rec);
  CHECK(json.find("\"row_misfit\"") != std::string::npos);
  CHECK(json.find("\"frames_sheared\": 8") != std::string::npos);
}

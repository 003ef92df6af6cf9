// The row-shear test of algo/sfm/row_misfit.hpp on synthetic residual fields: noise alone, a
// rolling shutter's row term, a zoom and a turn (set aside), and frames it cannot test.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdint>
#include <vector>

#include "algo/sfm/row_misfit.hpp"

using epitrack::measureRowMisfit;
using epitrack::RowMisfit;
using epitrack::RowResidual;

namespace {

constexpr double kWidth = 640.0, kHeight = 480.0;
constexpr double kCx = 319.5, kCy = 239.5;

// A portable generator (the same numbers on every platform): 64-bit LCG, Box-Muller.
struct Lcg {
  uint64_t s;
  double uniform() {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    return (static_cast<double>(s >> 11) + 0.5) / 9007199254740992.0;
  }
  double gauss() {
    return std::sqrt(-2.0 * std::log(uniform())) * std::cos(6.283185307179586 * uniform());
  }
};

// `frames` frames of `per_frame` observations spread over the image, Gaussian noise `sigma` per
// axis, plus the residual field `field(x, y, dx, dy)` adds.
template <typename Field>
std::vector<RowResidual> residualField(int frames, int per_frame, double sigma, Field field) {
  Lcg rng{12345};
  std::vector<RowResidual> out;
  for (int f = 0; f < frames; ++f) {
    for (int i = 0; i < per_frame; ++i) {
      RowResidual r;
      r.frame = f;
      r.x = rng.uniform() * (kWidth - 1.0);
      r.y = rng.uniform() * (kHeight - 1.0);
      r.dx = sigma * rng.gauss();
      r.dy = sigma * rng.gauss();
      field(r);
      out.push_back(r);
    }
  }
  return out;
}

}  // namespace

TEST_CASE("Row misfit: noise alone shears no frame", "[sfm][row-misfit]") {
  const auto res = residualField(100, 150, 0.3, [](RowResidual&) {});
  const RowMisfit m = measureRowMisfit(res, kCx, kCy, kHeight);
  CHECK(m.frames_tested == 100);
  CHECK(m.frames_sheared == 0);
  CHECK_FALSE(m.misfit);
  // |c| of noise: sigma * sqrt((M_uu + M_vv) / 4) per component, about 0.05 px here.
  CHECK(m.median_shear_px < 0.15);
  CHECK(m.max_shear_px < 0.4);
}

TEST_CASE("Row misfit: a rolling shutter's row term is measured and flagged", "[sfm][row-misfit]") {
  // x residual growing by 1.5 px from the top row to the bottom (a yaw velocity the model
  // missed), on frames 0-29 of 100; a vertical stretch of 1 px on frames 30-39.
  const auto res = residualField(100, 150, 0.3, [](RowResidual& r) {
    const double v = (r.y - kCy) / kHeight;
    if (r.frame < 30)
      r.dx += 1.5 * v;
    else if (r.frame < 40)
      r.dy += 1.0 * v;
  });
  const RowMisfit m = measureRowMisfit(res, kCx, kCy, kHeight);
  CHECK(m.frames_tested == 100);
  CHECK(m.frames_sheared == 40);
  CHECK(m.misfit);
  // Each component of 2|c| has a noise of sigma * sqrt(M_uu + M_vv), about 0.1 px here.
  CHECK(m.max_shear_px == Approx(1.5).margin(0.35));
  CHECK(m.p90_shear_px == Approx(1.5).margin(0.25));  // 30 frames of 1.5 px, 10 of 1 px
  CHECK(m.median_shear_px < 0.25);
  CHECK(m.max_shear_frame < 30);

  // The same field on 5 of 100 frames: significant there, but not the clip's model.
  const auto few = residualField(100, 150, 0.3, [](RowResidual& r) {
    if (r.frame < 5) r.dx += 1.5 * (r.y - kCy) / kHeight;
  });
  const RowMisfit m5 = measureRowMisfit(few, kCx, kCy, kHeight);
  CHECK(m5.frames_sheared == 5);
  CHECK_FALSE(m5.misfit);

  // Below min_shear_px (0.5 px) a significant shear does not count (600 observations a frame:
  // a noise of 0.05 px on each component of 2|c|).
  const auto small =
      residualField(100, 600, 0.3, [](RowResidual& r) { r.dx += 0.3 * (r.y - kCy) / kHeight; });
  const RowMisfit ms = measureRowMisfit(small, kCx, kCy, kHeight);
  CHECK(ms.frames_sheared == 0);
  CHECK(ms.median_shear_px == Approx(0.3).margin(0.1));
}

TEST_CASE("Row misfit: a zoom and a turn are set aside", "[sfm][row-misfit]") {
  // 2 % zoom (a focal error: 4.8 px at the top and bottom rows) and a 0.3 degree turn about the
  // principal point: a pose or the focal explains them, so no frame is sheared.
  const double s = 0.02, t = 0.3 * 3.141592653589793 / 180.0;
  const auto res = residualField(50, 150, 0.3, [&](RowResidual& r) {
    const double u = r.x - kCx, v = r.y - kCy;
    r.dx += s * u - t * v;
    r.dy += t * u + s * v;
  });
  const RowMisfit m = measureRowMisfit(res, kCx, kCy, kHeight);
  CHECK(m.frames_tested == 50);
  CHECK(m.frames_sheared == 0);
  CHECK(m.median_shear_px < 0.15);
}

TEST_CASE("Row misfit: frames too thin to test are left out", "[sfm][row-misfit]") {
  auto res = residualField(3, 150, 0.3, [](RowResidual& r) {
    if (r.frame == 1) r.y = 100.0;  // every observation on one row: no row term to fit
  });
  std::vector<RowResidual> thin = residualField(1, 10, 0.3, [](RowResidual& r) { r.frame = 3; });
  res.insert(res.end(), thin.begin(), thin.end());
  const RowMisfit m = measureRowMisfit(res, kCx, kCy, kHeight);
  CHECK(m.frames_tested == 2);
  CHECK(measureRowMisfit({}, kCx, kCy, kHeight).frames_tested == 0);
  CHECK_FALSE(measureRowMisfit({}, kCx, kCy, kHeight).misfit);
  CHECK(measureRowMisfit(res, kCx, kCy, 0.0).frames_tested == 0);
}

// The affine LK kernels (128-bit SSE2 / NEON, AVX2 and AVX-512 where the processor has them)
// against the scalar reference: the same sums, bit for bit, for random warps (near the identity,
// rotated, scaled, sheared, mirrored), windows of 1-80 pixels, the extreme values of every
// fixed-point format, and windows touching the image's last row and column (each image holds
// exactly the pixels the kernels may read, so a read outside it shows under the sanitizers).
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "algo/flow/lk_kernels.hpp"
#include "algo/math/random.hpp"

using epitrack::LkAffineSums;
using epitrack::LkAffineWarp;
using epitrack::SplitMix64;

namespace {

bool same(const LkAffineSums& a, const LkAffineSums& b) {
  return a.gx_e == b.gx_e && a.gy_e == b.gy_e && a.ugx_e == b.ugx_e && a.vgx_e == b.vgx_e &&
         a.ugy_e == b.ugy_e && a.vgy_e == b.vgy_e && a.sum_e == b.sum_e && a.sum_sq == b.sum_sq;
}

std::string describe(const LkAffineSums& s) {
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%lld %lld %lld %lld %lld %lld %lld %lld",
                static_cast<long long>(s.gx_e), static_cast<long long>(s.gy_e),
                static_cast<long long>(s.ugx_e), static_cast<long long>(s.vgx_e),
                static_cast<long long>(s.ugy_e), static_cast<long long>(s.vgy_e),
                static_cast<long long>(s.sum_e), static_cast<long long>(s.sum_sq));
  return buf;
}

int16_t uniformI16(SplitMix64& rng, int lo, int hi) {
  return static_cast<int16_t>(lo + static_cast<int>(rng.below(static_cast<uint32_t>(hi - lo + 1))));
}

/// One random case: a warp, an image holding exactly the pixels it reads (plus a random margin,
/// sometimes none, so that windows touch the last row and column), a template.
struct AffineCase {
  LkAffineWarp warp;
  std::vector<int32_t> row_x, row_y;
  int width = 0;
  int height = 0;
  int stride = 0;
  std::vector<uint8_t> image;
  std::vector<int16_t> T, Sx, Sy;
  int tstride = 0;
};

AffineCase makeCase(SplitMix64& rng, int side, int mode) {
  AffineCase c;
  // Shape: near the identity most of the time, else any rotation, scale 0.5-2 and shear.
  double a00 = 1.0, a01 = 0.0, a10 = 0.0, a11 = 1.0;
  const int kind = static_cast<int>(rng.below(4));
  if (kind == 0) {
    a00 = 1.0 + 0.1 * (rng.uniform() - 0.5);
    a01 = 0.1 * (rng.uniform() - 0.5);
    a10 = 0.1 * (rng.uniform() - 0.5);
    a11 = 1.0 + 0.1 * (rng.uniform() - 0.5);
  } else if (kind >= 2) {
    const double angle = 6.283185307179586 * rng.uniform();
    const double sx = 0.5 + 1.5 * rng.uniform();
    const double sy = 0.5 + 1.5 * rng.uniform();
    const double shear = kind == 3 ? rng.uniform() - 0.5 : 0.0;
    const double c0 = std::cos(angle), s0 = std::sin(angle);
    a00 = c0 * sx;
    a01 = -s0 * sy + shear;
    a10 = s0 * sx;
    a11 = c0 * sy;
    if (rng.below(8) == 0) {  // mirrored
      a01 = -a01;
      a11 = -a11;
    }
  }  // kind 1: exactly the identity (whole-pixel steps)
  // Rows start where the warp puts them, each rounded to 16.16 on its own (as PyramidalLk does),
  // sometimes one unit off; the steps along a row are rounded once.
  const auto fixed = [](double v) { return static_cast<int32_t>(std::lround(v * 65536.0)); };
  c.warp.xu = fixed(a00);
  c.warp.yu = fixed(a10);
  const double x0 = rng.uniform(), y0 = rng.uniform();
  c.row_x.resize(static_cast<std::size_t>(side));
  c.row_y.resize(static_cast<std::size_t>(side));
  for (int v = 0; v < side; ++v) {
    const auto k = static_cast<std::size_t>(v);
    c.row_x[k] = fixed(x0 + a01 * v) + static_cast<int32_t>(rng.below(3)) - 1;
    c.row_y[k] = fixed(y0 + a11 * v) + static_cast<int32_t>(rng.below(3)) - 1;
  }
  // Bounding box of the positions (each row's first and last pixel), then shift it into the image.
  int ix_min = 1 << 30, ix_max = -(1 << 30), iy_min = 1 << 30, iy_max = -(1 << 30);
  for (int v = 0; v < side; ++v) {
    for (const int u : {0, side - 1}) {
      const auto k = static_cast<std::size_t>(v);
      const int32_t X = c.row_x[k] + u * c.warp.xu;
      const int32_t Y = c.row_y[k] + u * c.warp.yu;
      ix_min = std::min(ix_min, X >> 16);
      ix_max = std::max(ix_max, X >> 16);
      iy_min = std::min(iy_min, Y >> 16);
      iy_max = std::max(iy_max, Y >> 16);
    }
  }
  const int left = static_cast<int>(rng.below(3));
  const int top = static_cast<int>(rng.below(3));
  // Margins: none, a few pixels, or enough for the AVX2 kernel's row loads (16 columns, 3 rows).
  const auto margin = [&](int few, int enough) {
    const uint32_t k = rng.below(3);
    return k == 0 ? 0 : k == 1 ? static_cast<int>(rng.below(static_cast<uint32_t>(few))) : enough;
  };
  const int right = margin(6, 16 + static_cast<int>(rng.below(4)));
  const int bottom = margin(3, 3 + static_cast<int>(rng.below(3)));
  for (auto& x : c.row_x) x += (left - ix_min) * 65536;
  for (auto& y : c.row_y) y += (top - iy_min) * 65536;
  c.warp.row_x = c.row_x.data();
  c.warp.row_y = c.row_y.data();
  c.width = left + (ix_max - ix_min) + 2 + right;
  c.height = top + (iy_max - iy_min) + 2 + bottom;
  c.stride = c.width + (rng.below(2) == 0 ? 0 : static_cast<int>(rng.below(9)));
  // The last row holds only `width` pixels: nothing of its stride padding is allocated.
  c.image.resize(static_cast<std::size_t>(c.stride) * static_cast<std::size_t>(c.height - 1) +
                 static_cast<std::size_t>(c.width));
  for (auto& p : c.image) {
    p = mode == 1 ? uint8_t{255} : mode == 2 ? uint8_t{0} : static_cast<uint8_t>(rng.below(256));
  }
  c.tstride = (side + 7) / 8 * 8;
  c.T.assign(static_cast<std::size_t>(side * c.tstride), 0);
  c.Sx.assign(c.T.size(), 0);
  c.Sy.assign(c.T.size(), 0);
  for (int v = 0; v < side; ++v) {
    for (int u = 0; u < side; ++u) {
      const auto i = static_cast<std::size_t>(v * c.tstride + u);
      if (mode == 1) {  // e = +8160 everywhere, gradients at their extremes
        c.T[i] = 0;
        c.Sx[i] = 4080;
        c.Sy[i] = -4080;
      } else if (mode == 2) {  // e = -8160
        c.T[i] = 8160;
        c.Sx[i] = -4080;
        c.Sy[i] = 4080;
      } else {
        c.T[i] = uniformI16(rng, 0, 8160);
        c.Sx[i] = uniformI16(rng, -4080, 4080);
        c.Sy[i] = uniformI16(rng, -4080, 4080);
      }
    }
  }
  return c;
}

}  // namespace

TEST_CASE("The affine LK kernels give the scalar kernel's sums bit for bit",
          "[tracker][lk][simd]") {
  std::printf("LK affine vector kernel: %s (128-bit: %s)\n", epitrack::lkAffineVectorIsa(),
              epitrack::lkVectorIsa());
  SplitMix64 rng(20261201);
  int cases = 0;
  for (int side = 1; side <= 80; ++side) {
    const int per_side = side <= 41 ? 40 : 6;
    for (int k = 0; k < per_side; ++k) {
      const int mode = k % 5 == 1 ? 1 : k % 5 == 3 ? 2 : 0;
      AffineCase c = makeCase(rng, side, mode);
      c.warp.row_x = c.row_x.data();  // (the vectors moved)
      c.warp.row_y = c.row_y.data();
      const epitrack::ImageView<const uint8_t> image(c.image.data(), c.width, c.height, c.stride);
      LkAffineSums scalar, v128, avx2, avx512, best;
      epitrack::lkAffineSumsScalar(image, c.warp, side, c.T.data(), c.Sx.data(), c.Sy.data(),
                                   c.tstride, scalar);
      epitrack::lkAffineSums128(image, c.warp, side, c.T.data(), c.Sx.data(), c.Sy.data(),
                                c.tstride, v128);
      epitrack::lkAffineSumsAvx2(image, c.warp, side, c.T.data(), c.Sx.data(), c.Sy.data(),
                                 c.tstride, avx2);
      epitrack::lkAffineSumsAvx512(image, c.warp, side, c.T.data(), c.Sx.data(), c.Sy.data(),
                                   c.tstride, avx512);
      epitrack::lkAffineSumsVector(image, c.warp, side, c.T.data(), c.Sx.data(), c.Sy.data(),
                                   c.tstride, best);
      INFO("side " << side << " case " << k << " mode " << mode << ": scalar " << describe(scalar));
      if (!same(scalar, v128)) FAIL("128-bit " << describe(v128));
      if (!same(scalar, avx2)) FAIL("avx2 " << describe(avx2));
      if (!same(scalar, avx512)) FAIL("avx512 " << describe(avx512));
      if (!same(scalar, best)) FAIL("vector " << describe(best));
      ++cases;
    }
  }
  CHECK(cases == 41 * 40 + 39 * 6);
}

TEST_CASE("The affine sample is the translation kernel's bilinear sample", "[tracker][lk][simd]") {
  // The same fixed point as lkTranslationSumsScalar at its sub-pixel position: a 1x1 window.
  SplitMix64 rng(8);
  for (int k = 0; k < 20000; ++k) {
    uint8_t px[4];
    for (auto& p : px) p = static_cast<uint8_t>(rng.below(256));
    const auto X = static_cast<int32_t>(rng.below(1 << 16));
    const auto Y = static_cast<int32_t>(rng.below(1 << 16));
    const epitrack::LkBilinear w = epitrack::lkBilinear(X >> 2, Y >> 2);
    const int16_t zero = 0;
    epitrack::LkWindowSums sums;
    epitrack::lkTranslationSumsScalar(px, 2, 1, w, &zero, &zero, &zero, 1, sums);
    REQUIRE(epitrack::lkAffineSample(px, 2, X, Y) == sums.sum_e);
  }
}

TEST_CASE("The affine sample interpolates exactly at whole pixels and within the pixel values",
          "[tracker][lk][simd]") {
  // 2 x 2 pixels: a whole-pixel position gives the pixel (x 32); any position gives a value
  // between the smallest and the largest of the four (a convex combination, rounded).
  SplitMix64 rng(7);
  for (int k = 0; k < 20000; ++k) {
    uint8_t px[6];
    for (auto& p : px) p = static_cast<uint8_t>(rng.below(256));
    const auto X = static_cast<int32_t>(rng.below(1 << 16));
    const auto Y = static_cast<int32_t>(rng.below(1 << 16));
    // Rows of stride 3: (px0, px1), (px3, px4).
    const int32_t s = epitrack::lkAffineSample(px, 3, X, Y);
    const int lo = std::min({px[0], px[1], px[3], px[4]}) * 32;
    const int hi = std::max({px[0], px[1], px[3], px[4]}) * 32;
    REQUIRE(s >= lo);
    REQUIRE(s <= hi);
    REQUIRE(epitrack::lkAffineSample(px, 3, 0, 0) == px[0] * 32);
    REQUIRE(epitrack::lkAffineSample(px, 3, 1 << 16, 0) == px[1] * 32);
  }
}

// The vector LK kernel (SSE2 / NEON) against the scalar reference: the same sums, bit for bit,
// for random windows, sub-pixel weights and templates, including the extreme values of every
// fixed-point format; and whole PyramidalLk alignments agree with either kernel.
#include "algo/flow/lk_kernels.hpp"

#include <catch2/catch.hpp>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "algo/math/random.hpp"

using epitrack::LkBilinear;
using epitrack::lkBilinear;
using epitrack::LkWindowSums;
using epitrack::SplitMix64;

namespace {

bool same(const LkWindowSums& a, const LkWindowSums& b) {
  return a.gx_e == b.gx_e && a.gy_e == b.gy_e && a.sum_e == b.sum_e && a.sum_sq == b.sum_sq;
}

int16_t uniformI16(SplitMix64& rng, int lo, int hi) {
  return static_cast<int16_t>(lo + static_cast<int>(rng.below(static_cast<uint32_t>(hi - lo + 1))));
}

}  // namespace

TEST_CASE("The LK kernels chosen are the machine's", "[tracker][lk][simd]") {
  // EPITRACK_EXPECT_LK_ISA: what the caller knows the machine has (.ci/cross_armhf.sh runs this
  // binary on an emulated ARMv7 with NEON, expecting "neon", and without, expecting "scalar").
  const std::string isa = epitrack::lkVectorIsa();
  std::printf("LK kernels: %s (NEON: %s)\n", isa.c_str(), epitrack::lkHaveNeon() ? "yes" : "no");
  CHECK((isa == "neon") == epitrack::lkHaveNeon());
#if defined(__aarch64__)
  CHECK(epitrack::lkHaveNeon());
#endif
  if (const char* expected = std::getenv("EPITRACK_EXPECT_LK_ISA")) CHECK(isa == expected);
}

TEST_CASE("The vector LK kernel gives the scalar kernel's sums bit for bit",
          "[tracker][lk][simd]") {
  std::printf("LK vector kernel: %s\n", epitrack::lkVectorIsa());
  SplitMix64 rng(20261123);
  // Windows up to 41 (odd and even), each case with its own image block, weights and template.
  int cases = 0;
  for (int side = 1; side <= 41; ++side) {
    const int tstride = (side + 7) / 8 * 8;
    const int stride = side + 1 + static_cast<int>(rng.below(9));
    for (int k = 0; k < 60; ++k) {
      // The image block holds exactly the (side + 1)^2 pixels the kernel may read, so a read
      // outside it would show under the sanitizers.
      std::vector<uint8_t> image(static_cast<std::size_t>(stride) * static_cast<std::size_t>(side) +
                                 static_cast<std::size_t>(side + 1));
      std::vector<int16_t> T(static_cast<std::size_t>(side * tstride), 0);
      std::vector<int16_t> Sx(T.size(), 0);
      std::vector<int16_t> Sy(T.size(), 0);
      const int mode = k % 4;  // 0: random, 1: extremes that maximise the sums, 2/3: mixed
      for (auto& p : image) {
        p = mode == 1 ? uint8_t{255} : static_cast<uint8_t>(rng.below(256));
      }
      for (int v = 0; v < side; ++v) {
        for (int u = 0; u < side; ++u) {
          const auto i = static_cast<std::size_t>(v * tstride + u);
          if (mode == 1) {
            T[i] = 0;
            Sx[i] = 4080;
            Sy[i] = -4080;
          } else {
            T[i] = uniformI16(rng, 0, 8160);
            Sx[i] = uniformI16(rng, -4080, 4080);
            Sy[i] = uniformI16(rng, -4080, 4080);
          }
        }
      }
      const auto ax = static_cast<int32_t>(mode == 2 ? 0 : rng.below((1 << 14) + 1));
      const auto ay = static_cast<int32_t>(mode == 3 ? 1 << 14 : rng.below((1 << 14) + 1));
      const LkBilinear w = lkBilinear(ax, ay);
      REQUIRE(w.w00 + w.w01 + w.w10 + w.w11 == 1 << 14);
      LkWindowSums scalar, vector;
      epitrack::lkTranslationSumsScalar(image.data(), stride, side, w, T.data(), Sx.data(),
                                        Sy.data(), tstride, scalar);
      epitrack::lkTranslationSumsVector(image.data(), stride, side, w, T.data(), Sx.data(),
                                        Sy.data(), tstride, vector);
      if (!same(scalar, vector)) {
        FAIL("side " << side << " case " << k << ": scalar " << scalar.gx_e << " " << scalar.gy_e
                     << " " << scalar.sum_e << " " << scalar.sum_sq << ", vector " << vector.gx_e
                     << " " << vector.gy_e << " " << vector.sum_e << " " << vector.sum_sq);
      }
      ++cases;
    }
  }
  CHECK(cases == 41 * 60);
}

#include <cmath>

#include "algo/flow/pyramidal_lk.hpp"
#include "algo/image/image.hpp"
#include "algo/image/pyramid.hpp"

TEST_CASE("PyramidalLk tracks identically with the vector and the scalar kernel",
          "[tracker][lk][simd]") {
  const int w = 320;
  const int h = 240;
  epitrack::Image<uint8_t> a(w, h);
  epitrack::Image<uint8_t> b(w, h);
  // Smooth texture plus pixel noise; b is a moved by (2.6, -1.3) with a brightness offset.
  SplitMix64 rng(5);
  const auto pattern = [](double x, double y) {
    return 128.0 + 50.0 * std::sin(0.23 * x + 0.11 * y) + 40.0 * std::cos(0.19 * y - 0.07 * x) +
           25.0 * std::sin(0.41 * x) * std::cos(0.37 * y);
  };
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double n = static_cast<double>(rng.below(9)) - 4.0;
      a(x, y) = static_cast<uint8_t>(std::clamp(std::lround(pattern(x, y) + n), 0L, 255L));
      b(x, y) = static_cast<uint8_t>(
          std::clamp(std::lround(pattern(x - 2.6, y + 1.3) + n + 7.0), 0L, 255L));
    }
  }
  epitrack::Pyramid pa(w, h, 4);
  epitrack::Pyramid pb(w, h, 4);
  pa.build(a.constView());
  pb.build(b.constView());
  // Affine with the central residual window (the default, its zero-padded template copy), the
  // whole window, and translation only.
  for (const int mode : {0, 1, 2}) {
    epitrack::LkOptions o;
    o.affine = mode != 2;
    o.residual_radius = mode == 1 ? 0 : -1;
    epitrack::LkOptions o_scalar = o;
    o_scalar.vector_kernels = false;
    epitrack::PyramidalLk vec(o, 64);
    epitrack::PyramidalLk sca(o_scalar, 64);
    int tracked = 0;
    for (int i = 0; i < 64; ++i) {
      const float x0 = 30.0f + static_cast<float>(rng.below(260));
      const float y0 = 30.0f + static_cast<float>(rng.below(180));
      const auto s1 = vec.setTemplate(i, pa, x0, y0);
      const auto s2 = sca.setTemplate(i, pa, x0, y0);
      REQUIRE(s1 == s2);
      if (s1 != epitrack::LkStatus::kTracked) continue;
      float xv = x0, yv = y0, rv = 0.0f, xs = x0, ys = y0, rs = 0.0f;
      const auto t1 = vec.align(i, pb, xv, yv, rv);
      const auto t2 = sca.align(i, pb, xs, ys, rs);
      CHECK(t1 == t2);
      CHECK(xv == xs);
      CHECK(yv == ys);
      CHECK(rv == rs);
      if (t1 == epitrack::LkStatus::kTracked) ++tracked;
    }
    CHECK(tracked > 40);
    CHECK(vec.iterations() == sca.iterations());
  }
}

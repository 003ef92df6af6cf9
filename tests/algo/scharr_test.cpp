#include "algo/image/scharr.hpp"

#include <catch2/catch.hpp>

#include "algo/image/border.hpp"
#include "algo/image/image.hpp"
#include "tests/support/test_support.hpp"

using epitrack::Image;
using epitrack::reflect101;

namespace {
void naiveScharr(epitrack::ImageView<const uint8_t> s, epitrack::ImageView<int16_t> dx,
                 epitrack::ImageView<int16_t> dy) {
  static constexpr int kX[3][3] = {{-3, 0, 3}, {-10, 0, 10}, {-3, 0, 3}};
  for (int y = 0; y < s.height; ++y) {
    for (int x = 0; x < s.width; ++x) {
      int gx = 0;
      int gy = 0;
      for (int j = -1; j <= 1; ++j) {
        for (int i = -1; i <= 1; ++i) {
          const int p = s(reflect101(x + i, s.width), reflect101(y + j, s.height));
          gx += kX[j + 1][i + 1] * p;
          gy += kX[i + 1][j + 1] * p;
        }
      }
      dx(x, y) = static_cast<int16_t>(gx);
      dy(x, y) = static_cast<int16_t>(gy);
    }
  }
}
}  // namespace

TEST_CASE("Scharr gradients are bit-exact against the naive 3x3 reference", "[image][gradient]") {
  const int sizes[][2] = {{1, 1}, {2, 2}, {3, 1}, {1, 4}, {7, 5}, {64, 33}, {321, 240}};
  uint32_t seed = 10;
  for (const auto& s : sizes) {
    Image<uint8_t> src(s[0], s[1]);
    epitrack::test::fillRandom(src.view(), seed++);
    Image<int16_t> dx(s[0], s[1]);
    Image<int16_t> dy(s[0], s[1]);
    Image<int16_t> rx(s[0], s[1]);
    Image<int16_t> ry(s[0], s[1]);
    epitrack::scharrGradients(src.constView(), dx.view(), dy.view());
    naiveScharr(src.constView(), rx.view(), ry.view());
    INFO("size " << s[0] << "x" << s[1]);
    for (int y = 0; y < s[1]; ++y) {
      for (int x = 0; x < s[0]; ++x) {
        REQUIRE(dx(x, y) == rx(x, y));
        REQUIRE(dy(x, y) == ry(x, y));
      }
    }
  }
}

TEST_CASE("Scharr gradients (SSE2 / NEON) equal the scalar reference for every width",
          "[image][gradient][simd]") {
  uint32_t seed = 77;
  for (int w = 1; w <= 70; ++w) {
    for (const int h : {1, 2, 3, 6}) {
      Image<uint8_t> src(w, h);
      epitrack::test::fillRandom(src.view(), seed++);
      if (w % 7 == 0) {  // extremes: a 0/255 checkerboard of 2x2 cells (gradients of +-4080)
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) src(x, y) = ((x / 2 + y / 2) % 2 == 0) ? 255 : 0;
      }
      Image<int16_t> dx(w, h), dy(w, h), rx(w, h), ry(w, h);
      epitrack::scharrGradients(src.constView(), dx.view(), dy.view());
      epitrack::scharrGradientsScalar(src.constView(), rx.view(), ry.view());
      INFO("size " << w << "x" << h);
      for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
          REQUIRE(dx(x, y) == rx(x, y));
          REQUIRE(dy(x, y) == ry(x, y));
        }
      }
    }
  }
}

TEST_CASE("Scharr of a linear ramp is 32 times its slope", "[image][gradient]") {
  Image<uint8_t> ramp(20, 10);
  for (int y = 0; y < 10; ++y)
    for (int x = 0; x < 20; ++x) ramp(x, y) = static_cast<uint8_t>(3 * x + 5 * y);
  Image<int16_t> dx(20, 10);
  Image<int16_t> dy(20, 10);
  epitrack::scharrGradients(ramp.constView(), dx.view(), dy.view());
  for (int y = 1; y < 9; ++y) {
    for (int x = 1; x < 19; ++x) {
      REQUIRE(dx(x, y) == 32 * 3);
      REQUIRE(dy(x, y) == 32 * 5);
    }
  }
  // Reflect-101 makes the derivative vanish across the border.
  REQUIRE(dx(0, 5) == 0);
  REQUIRE(dy(5, 0) == 0);
}

#include "algo/image/pyramid.hpp"

#include <catch2/catch.hpp>

#include "algo/image/border.hpp"
#include "algo/image/image.hpp"
#include "tests/support/test_support.hpp"

using epitrack::Image;
using epitrack::ImageView;
using epitrack::Pyramid;
using epitrack::reflect101;

namespace {

// Naive reference: the full 5x5 kernel w_i * w_j / 256 at every second pixel, reflect-101 border.
void naivePyrDown(ImageView<const uint8_t> src, ImageView<uint8_t> dst) {
  static constexpr int kW[5] = {1, 4, 6, 4, 1};
  for (int y = 0; y < dst.height; ++y) {
    for (int x = 0; x < dst.width; ++x) {
      int sum = 0;
      for (int j = -2; j <= 2; ++j) {
        for (int i = -2; i <= 2; ++i) {
          sum += kW[i + 2] * kW[j + 2] *
                 src(reflect101(2 * x + i, src.width), reflect101(2 * y + j, src.height));
        }
      }
      dst(x, y) = static_cast<uint8_t>((sum + 128) >> 8);
    }
  }
}

}  // namespace

TEST_CASE("reflect101 mirrors without repeating the edge pixel", "[image][border]") {
  REQUIRE(reflect101(-1, 5) == 1);
  REQUIRE(reflect101(-2, 5) == 2);
  REQUIRE(reflect101(5, 5) == 3);
  REQUIRE(reflect101(6, 5) == 2);
  REQUIRE(reflect101(0, 1) == 0);
  REQUIRE(reflect101(-3, 1) == 0);
  REQUIRE(reflect101(-1, 2) == 1);
  REQUIRE(reflect101(2, 2) == 0);
  REQUIRE(reflect101(3, 2) == 1);
  for (int n = 1; n < 9; ++n)
    for (int i = -20; i < 20; ++i) REQUIRE((reflect101(i, n) >= 0 && reflect101(i, n) < n));
}

TEST_CASE("pyrDown is bit-exact against the naive 5x5 reference", "[image][pyramid]") {
  const int sizes[][2] = {{1, 1},   {2, 3},   {3, 2},    {5, 7},    {8, 8},
                          {33, 17}, {64, 48}, {101, 67}, {640, 480}};
  uint32_t seed = 1;
  for (const auto& s : sizes) {
    Image<uint8_t> src(s[0], s[1]);
    epitrack::test::fillRandom(src.view(), seed++);
    Image<uint8_t> fast((s[0] + 1) / 2, (s[1] + 1) / 2);
    Image<uint8_t> ref((s[0] + 1) / 2, (s[1] + 1) / 2);
    std::vector<uint16_t> scratch(static_cast<std::size_t>(s[0]));
    epitrack::pyrDown(src.constView(), fast.view(), scratch.data());
    naivePyrDown(src.constView(), ref.view());
    INFO("size " << s[0] << "x" << s[1]);
    for (int y = 0; y < ref.height(); ++y)
      for (int x = 0; x < ref.width(); ++x) REQUIRE(fast(x, y) == ref(x, y));
    epitrack::pyrDownScalar(src.constView(), fast.view(), scratch.data());
    for (int y = 0; y < ref.height(); ++y)
      for (int x = 0; x < ref.width(); ++x) REQUIRE(fast(x, y) == ref(x, y));
  }
}

TEST_CASE("pyrDown (SSE2 / NEON) gives the scalar reference's bytes for every width",
          "[image][pyramid][simd]") {
  // Widths around the vector steps (16 columns, 8 outputs) and the borders; scratch rows of
  // exactly the source width, so a read beyond them shows under the sanitizers.
  uint32_t seed = 100;
  for (int w = 1; w <= 90; ++w) {
    for (const int h : {1, 2, 5, 9}) {
      Image<uint8_t> src(w, h);
      epitrack::test::fillRandom(src.view(), seed++);
      Image<uint8_t> fast((w + 1) / 2, (h + 1) / 2);
      Image<uint8_t> ref((w + 1) / 2, (h + 1) / 2);
      std::vector<uint16_t> scratch(static_cast<std::size_t>(w));
      epitrack::pyrDown(src.constView(), fast.view(), scratch.data());
      epitrack::pyrDownScalar(src.constView(), ref.view(), scratch.data());
      INFO("size " << w << "x" << h);
      for (int y = 0; y < ref.height(); ++y)
        for (int x = 0; x < ref.width(); ++x) REQUIRE(fast(x, y) == ref(x, y));
    }
  }
  for (const int w : {703, 704, 705, 1241}) {
    Image<uint8_t> src(w, 37);
    Image<uint8_t> fast((w + 1) / 2, 19);
    Image<uint8_t> ref((w + 1) / 2, 19);
    std::vector<uint16_t> scratch(static_cast<std::size_t>(w));
    for (const int mode : {0, 1}) {  // random, then all 255 (the largest sums)
      if (mode == 0) {
        epitrack::test::fillRandom(src.view(), seed++);
      } else {
        for (int y = 0; y < 37; ++y)
          for (int x = 0; x < w; ++x) src(x, y) = 255;
      }
      epitrack::pyrDown(src.constView(), fast.view(), scratch.data());
      epitrack::pyrDownScalar(src.constView(), ref.view(), scratch.data());
      for (int y = 0; y < ref.height(); ++y)
        for (int x = 0; x < ref.width(); ++x) REQUIRE(fast(x, y) == ref(x, y));
    }
  }
}

TEST_CASE("pyrDown reads a strided sub-view correctly", "[image][pyramid]") {
  Image<uint8_t> big(90, 70);
  epitrack::test::fillRandom(big.view(), 42);
  const ImageView<const uint8_t> sub = big.constView().subView(7, 3, 41, 29);
  Image<uint8_t> packed(41, 29);
  epitrack::copyPixels(sub, packed.view());
  Image<uint8_t> a(21, 15);
  Image<uint8_t> b(21, 15);
  std::vector<uint16_t> scratch(41);
  epitrack::pyrDown(sub, a.view(), scratch.data());
  naivePyrDown(packed.constView(), b.view());
  for (int y = 0; y < 15; ++y)
    for (int x = 0; x < 21; ++x) REQUIRE(a(x, y) == b(x, y));
}

TEST_CASE("Pyramid levels have ceil-halved sizes and match repeated pyrDown", "[image][pyramid]") {
  Pyramid pyr(705, 577, 5);
  REQUIRE(pyr.levelCount() == 5);
  Image<uint8_t> img(705, 577);
  epitrack::test::fillRandom(img.view(), 3);
  REQUIRE(pyr.build(img.constView()) == Pyramid::Status::kOk);
  const int widths[] = {705, 353, 177, 89, 45};
  const int heights[] = {577, 289, 145, 73, 37};
  Image<uint8_t> ref;
  Image<uint8_t> prev(705, 577);
  epitrack::copyPixels(img.constView(), prev.view());
  for (int l = 0; l < 5; ++l) {
    REQUIRE(pyr.level(l).width == widths[l]);
    REQUIRE(pyr.level(l).height == heights[l]);
    REQUIRE(reinterpret_cast<std::uintptr_t>(pyr.level(l).data) % 64 == 0);
    if (l > 0) {
      ref.allocate(widths[l], heights[l]);
      naivePyrDown(prev.constView(), ref.view());
      for (int y = 0; y < heights[l]; ++y)
        for (int x = 0; x < widths[l]; ++x) REQUIRE(pyr.level(l)(x, y) == ref(x, y));
      prev.allocate(widths[l], heights[l]);
      epitrack::copyPixels(ref.constView(), prev.view());
    }
  }
}

TEST_CASE("Pyramid refuses a frame of another size and bad configurations", "[image][pyramid]") {
  Pyramid unconfigured;
  Image<uint8_t> img(32, 32);
  img.fill(1);
  REQUIRE(unconfigured.build(img.constView()) == Pyramid::Status::kNotConfigured);
  Pyramid pyr(64, 64, 3);
  REQUIRE(pyr.build(img.constView()) == Pyramid::Status::kSizeMismatch);
  REQUIRE_FALSE(pyr.configure(0, 10, 3));
  REQUIRE_FALSE(pyr.configure(10, 10, 0));
  REQUIRE_FALSE(pyr.configure(10, 10, Pyramid::kMaxLevels + 1));
}

TEST_CASE("A constant image stays constant through the pyramid", "[image][pyramid]") {
  Pyramid pyr(50, 30, 4);
  Image<uint8_t> img(50, 30);
  img.fill(200);
  REQUIRE(pyr.build(img.constView()) == Pyramid::Status::kOk);
  for (int l = 0; l < 4; ++l) {
    const auto v = pyr.level(l);
    for (int y = 0; y < v.height; ++y)
      for (int x = 0; x < v.width; ++x) REQUIRE(v(x, y) == 200);
  }
}

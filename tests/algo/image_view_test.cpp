#include "algo/image/image_view.hpp"

#include <catch2/catch.hpp>

#include "algo/image/image.hpp"

using epitrack::Image;
using epitrack::ImageView;

TEST_CASE("Image rows are 64-byte aligned and the stride covers the width", "[image]") {
  for (int w : {1, 3, 63, 64, 65, 641}) {
    Image<uint8_t> img(w, 5);
    REQUIRE(img.width() == w);
    REQUIRE(img.stride() >= w);
    for (int y = 0; y < 5; ++y) REQUIRE(reinterpret_cast<std::uintptr_t>(img.row(y)) % 64 == 0);
    Image<int16_t> g(w, 3);
    for (int y = 0; y < 3; ++y) REQUIRE(reinterpret_cast<std::uintptr_t>(g.row(y)) % 64 == 0);
  }
}

TEST_CASE("Image reuses its buffer for a same or smaller size", "[image]") {
  Image<uint8_t> img(100, 80);
  const uint8_t* before = img.row(0);
  REQUIRE(img.allocate(100, 80));
  REQUIRE(img.row(0) == before);
  REQUIRE(img.allocate(50, 40));
  REQUIRE(img.row(0) == before);
  REQUIRE(img.width() == 50);
  REQUIRE_FALSE(img.allocate(-1, 3));
  REQUIRE(img.width() == 50);
}

TEST_CASE("Sub-views share memory and stride, at odd offsets and sizes", "[image]") {
  Image<uint8_t> img(37, 23);
  for (int y = 0; y < 23; ++y)
    for (int x = 0; x < 37; ++x) img(x, y) = static_cast<uint8_t>(x + 37 * y);
  const ImageView<uint8_t> v = img.view().subView(5, 7, 11, 3);
  REQUIRE(v.width == 11);
  REQUIRE(v.height == 3);
  REQUIRE(v.stride == img.stride());
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 11; ++x) REQUIRE(v(x, y) == static_cast<uint8_t>((x + 5) + 37 * (y + 7)));
  v(0, 0) = 0xAB;  // writes through
  REQUIRE(img(5, 7) == 0xAB);
  const ImageView<const uint8_t> cv = v;  // implicit const conversion
  REQUIRE(cv(0, 0) == 0xAB);
  const auto nested = v.subView(10, 2, 1, 1);
  REQUIRE(nested(0, 0) == img(15, 9));
  REQUIRE(v.contains(10, 2));
  REQUIRE_FALSE(v.contains(11, 0));
  REQUIRE_FALSE(v.contains(-1, 0));
}

TEST_CASE("copyPixels copies between different strides", "[image]") {
  Image<uint8_t> a(13, 4);
  a.fill(7);
  a(12, 3) = 9;
  uint8_t dense[13 * 4] = {};
  epitrack::copyPixels(a.constView(), ImageView<uint8_t>(dense, 13, 4));
  REQUIRE(dense[0] == 7);
  REQUIRE(dense[13 * 4 - 1] == 9);
}

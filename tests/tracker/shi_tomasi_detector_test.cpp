#include "algo/features/shi_tomasi_detector.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

#include "tests/support/test_support.hpp"
#include "tests/tracker/orbit_clip.hpp"

using epitrack::Corner;
using epitrack::Image;
using epitrack::Point2f;
using epitrack::ShiTomasiDetector;
using epitrack::ShiTomasiOptions;

namespace {

struct DetectionError {
  double mean = 0.0;
  double stddev = 0.0;
  int matched = 0;
  int corners = 0;
  int detected = 0;
};

/// The paper's Table 1 measure: for each visible, well-conditioned scene corner (cells >= 9 px on
/// screen, edges >= 45 degrees apart), the nearest detection within 2 px.
DetectionError measureDetection(int width, int height, double focal, double noise) {
  epitrack::synth::SynthOptions o;
  o.frames = 1;
  o.width = width;
  o.height = height;
  o.focal = focal;
  o.noise_sigma = noise;
  o.seed = 3;
  const auto clip = epitrack::test::renderClip(o);
  ShiTomasiOptions d;
  d.max_features = 2000;
  d.min_distance = 4.0;
  ShiTomasiDetector det(d, width, height);
  std::vector<Corner> out(2000);
  int found = 0;
  REQUIRE(det.detect(clip.frames[0].constView(), {}, {}, 2000, out, found) ==
          ShiTomasiDetector::Status::kOk);
  DetectionError e;
  e.detected = found;
  double sum = 0.0;
  double sum2 = 0.0;
  double sum_dx = 0.0;
  double sum_dy = 0.0;
  for (std::size_t li = 0; li < clip.landmarks[0].size(); ++li) {
    const auto& l = clip.landmarks[0][li];
    if (clip.well_conditioned[0][li] == 0) continue;
    if (l.x < 16 || l.y < 16 || l.x > width - 17 || l.y > height - 17) continue;
    ++e.corners;
    double best = 4.0;
    double bdx = 0.0;
    double bdy = 0.0;
    for (int i = 0; i < found; ++i) {
      const double dx = static_cast<double>(out[static_cast<std::size_t>(i)].x) - l.x;
      const double dy = static_cast<double>(out[static_cast<std::size_t>(i)].y) - l.y;
      if (dx * dx + dy * dy < best) {
        best = dx * dx + dy * dy;
        bdx = dx;
        bdy = dy;
      }
    }
    if (best < 4.0) {
      sum_dx += bdx;
      sum_dy += bdy;
      const double err = std::sqrt(best);
      sum += err;
      sum2 += err * err;
      ++e.matched;
    }
  }
  if (e.matched > 0) {
    e.mean = sum / e.matched;
    e.stddev = std::sqrt(std::max(0.0, sum2 / e.matched - e.mean * e.mean));
  }
  std::printf(
      "detection %dx%d noise %4.1f: %d detected, %d/%d corners matched, error mean %.3f std %.3f "
      "px (bias %.3f %.3f)\n",
      width, height, noise, e.detected, e.matched, e.corners, e.mean, e.stddev,
      sum_dx / std::max(1, e.matched), sum_dy / std::max(1, e.matched));
  return e;
}

}  // namespace

TEST_CASE("Shi-Tomasi finds the corners of a rendered scene with sub-pixel accuracy (Table 1)",
          "[tracker][detector]") {
  for (const auto& [w, h, f] : {std::tuple{320, 240, 280.0}, std::tuple{640, 480, 560.0}}) {
    for (const double noise : {0.0, 2.0, 5.0, 10.0}) {
      const DetectionError e = measureDetection(w, h, f, noise);
      REQUIRE(e.corners > 20);
      CHECK(e.matched >= e.corners / 2);
      if (noise == 0.0) CHECK(e.mean < 0.1);
      if (noise <= 5.0) CHECK(e.mean < 0.3);
      if (noise == 10.0) CHECK(e.mean < 0.6);
    }
  }
}

TEST_CASE("Detection keeps the minimum distance, avoids existing features and honours the mask",
          "[tracker][detector]") {
  const int w = 320;
  const int h = 240;
  // A checkerboard of 16 px cells: corners every 16 px.
  Image<uint8_t> img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) img(x, y) = ((x / 16 + y / 16) % 2 == 0) ? 40 : 210;
  ShiTomasiOptions o;
  o.min_distance = 20.0;
  ShiTomasiDetector det(o, w, h);
  std::vector<Corner> out(300);
  int found = 0;
  REQUIRE(det.detect(img.constView(), {}, {}, 300, out, found) == ShiTomasiDetector::Status::kOk);
  REQUIRE(found > 20);
  for (int i = 0; i < found; ++i) {
    for (int j = i + 1; j < found; ++j) {
      const float dx = out[static_cast<std::size_t>(i)].x - out[static_cast<std::size_t>(j)].x;
      const float dy = out[static_cast<std::size_t>(i)].y - out[static_cast<std::size_t>(j)].y;
      CHECK(dx * dx + dy * dy >= 400.0f);
    }
    // Checkerboard corners lie between pixels 15 and 16 of a cell: x = 16 k - 0.5.
    const double fx =
        std::fmod(static_cast<double>(out[static_cast<std::size_t>(i)].x) + 0.5, 16.0);
    const double fy =
        std::fmod(static_cast<double>(out[static_cast<std::size_t>(i)].y) + 0.5, 16.0);
    CHECK(std::min(fx, 16.0 - fx) < 0.05);
    CHECK(std::min(fy, 16.0 - fy) < 0.05);
  }
  // Existing features block their neighbourhood.
  const std::vector<Point2f> existing = {{out[0].x, out[0].y}};
  int found2 = 0;
  std::vector<Corner> out2(300);
  REQUIRE(det.detect(img.constView(), existing, {}, 300, out2, found2) ==
          ShiTomasiDetector::Status::kOk);
  for (int i = 0; i < found2; ++i) {
    const float dx = out2[static_cast<std::size_t>(i)].x - out[0].x;
    const float dy = out2[static_cast<std::size_t>(i)].y - out[0].y;
    CHECK(dx * dx + dy * dy >= 400.0f);
  }
  // Mask: the left half is forbidden.
  Image<uint8_t> mask(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) mask(x, y) = x < w / 2 ? 0 : 255;
  REQUIRE(det.detect(img.constView(), {}, mask.constView(), 300, out2, found2) ==
          ShiTomasiDetector::Status::kOk);
  REQUIRE(found2 > 5);
  for (int i = 0; i < found2; ++i) CHECK(out2[static_cast<std::size_t>(i)].x >= w / 2 - 1);
  // Requesting fewer returns the strongest few; a wrong size is refused.
  REQUIRE(det.detect(img.constView(), {}, {}, 5, out2, found2) == ShiTomasiDetector::Status::kOk);
  CHECK(found2 == 5);
  Image<uint8_t> small(100, 100);
  CHECK(det.detect(small.constView(), {}, {}, 5, out2, found2) ==
        ShiTomasiDetector::Status::kSizeMismatch);
}

TEST_CASE("The vector detector finds the scalar detector's corners, bit for bit",
          "[tracker][detector][simd]") {
  // Rendered frames and random noise of odd sizes, every block radius, with existing features and
  // a mask: the same corners (position, response) in the same order and the same quality.
  // (One rendered frame each of the orbit and the hand-held scene: rendering is slow under qemu.)
  std::vector<Image<uint8_t>> inputs;
  for (const auto kind :
       {epitrack::synth::SceneKind::kOrbit, epitrack::synth::SceneKind::kHandheld}) {
    epitrack::synth::SynthOptions so;
    so.kind = kind;
    so.frames = 1;
    auto clip = epitrack::test::renderClip(so);
    inputs.push_back(std::move(clip.frames[0]));
  }
  for (const auto& [w, h] : {std::pair{101, 67}, std::pair{333, 250}}) {
    Image<uint8_t> noise(w, h);
    epitrack::test::fillRandom(noise.view(), static_cast<uint32_t>(w));
    inputs.push_back(std::move(noise));
  }
  int compared = 0;
  for (const Image<uint8_t>& image : inputs) {
    const int w = image.width();
    const int h = image.height();
    Image<uint8_t> mask(w, h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) mask(x, y) = (x / 37 + y / 29) % 3 == 0 ? 0 : 255;
    const auto fw = static_cast<float>(w);
    const auto fh = static_cast<float>(h);
    const std::vector<Point2f> existing = {{0.3f * fw, 0.4f * fh}, {0.7f * fw, 0.6f * fh}};
    for (const int radius : {1, 2, 3}) {
      for (const bool masked : {false, true}) {
        ShiTomasiOptions o;
        o.block_radius = radius;
        o.max_features = 500;
        ShiTomasiOptions o_scalar = o;
        o_scalar.vector_kernels = false;
        ShiTomasiDetector vec(o, w, h);
        ShiTomasiDetector sca(o_scalar, w, h);
        std::vector<Corner> a(500), b(500);
        int na = 0, nb = 0;
        const epitrack::ImageView<const uint8_t> m =
            masked ? mask.constView() : epitrack::ImageView<const uint8_t>{};
        REQUIRE(vec.detect(image.constView(), existing, m, 500, a, na) ==
                ShiTomasiDetector::Status::kOk);
        REQUIRE(sca.detect(image.constView(), existing, m, 500, b, nb) ==
                ShiTomasiDetector::Status::kOk);
        INFO("image " << w << "x" << h << " radius " << radius << " masked " << masked);
        REQUIRE(na == nb);
        REQUIRE(na > 0);
        for (int i = 0; i < na; ++i) {
          const auto k = static_cast<std::size_t>(i);
          REQUIRE(a[k].x == b[k].x);
          REQUIRE(a[k].y == b[k].y);
          REQUIRE(a[k].response == b[k].response);
        }
        CHECK(vec.lastQuality() == sca.lastQuality());
        ++compared;
      }
    }
  }
  CHECK(compared == 4 * 3 * 2);
}

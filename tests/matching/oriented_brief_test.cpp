// Oriented BRIEF and the multi-scale extractor: in-plane rotation and scale change of a rendered
// textured frame, the seeded pattern's determinism, and the matcher's ratio and mutual checks.

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdint>
#include <vector>

#include "algo/image/image.hpp"
#include "algo/matching/descriptor_matcher.hpp"
#include "algo/matching/feature_extractor.hpp"
#include "algo/matching/scale_pyramid.hpp"
#include "tools/synth/synthetic_sequence.hpp"

using epitrack::BinaryDescriptor;
using epitrack::DescriptorMatch;
using epitrack::DescriptorMatcher;
using epitrack::DescriptorMatchOptions;
using epitrack::FeatureExtractor;
using epitrack::FeatureExtractorOptions;
using epitrack::Image;
using epitrack::Keypoint;

namespace {

// One rendered frame of the synthetic handheld scene (textured planes and boxes), 640x480.
const Image<uint8_t>& texturedFrame() {
  static const Image<uint8_t> frame = [] {
    epitrack::synth::SynthOptions o;
    o.kind = epitrack::synth::SceneKind::kHandheld;
    o.frames = 10;
    o.width = 640;
    o.height = 480;
    o.focal = 500.0;
    const epitrack::synth::SyntheticSequence seq(o);
    epitrack::synth::FrameRenderer r(seq);
    Image<uint8_t> img;
    r.render(5, img);
    return img;
  }();
  return frame;
}

// `src` rotated by `deg` about its centre (bilinear; outside: mid gray). Point p of src lands at
// c + R (p - c).
Image<uint8_t> rotated(const Image<uint8_t>& src, double deg) {
  const int w = src.width(), h = src.height();
  Image<uint8_t> out(w, h);
  const double a = deg * M_PI / 180.0, c = std::cos(a), s = std::sin(a);
  const double cx = (w - 1) * 0.5, cy = (h - 1) * 0.5;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      // Inverse map: q = c + R^T (p - c).
      const double dx = x - cx, dy = y - cy;
      const double sx = cx + c * dx + s * dy, sy = cy - s * dx + c * dy;
      const int x0 = static_cast<int>(std::floor(sx)), y0 = static_cast<int>(std::floor(sy));
      if (x0 < 0 || y0 < 0 || x0 + 1 >= w || y0 + 1 >= h) {
        out(x, y) = 128;
        continue;
      }
      const double fx = sx - x0, fy = sy - y0;
      const double v = (1 - fy) * ((1 - fx) * src(x0, y0) + fx * src(x0 + 1, y0)) +
                       fy * ((1 - fx) * src(x0, y0 + 1) + fx * src(x0 + 1, y0 + 1));
      out(x, y) = static_cast<uint8_t>(std::lround(v));
    }
  }
  return out;
}

struct Features {
  std::vector<Keypoint> keypoints;
  std::vector<BinaryDescriptor> upright, oriented;
};

Features extract(const Image<uint8_t>& img, const FeatureExtractorOptions& o) {
  FeatureExtractor fx(o, img.width(), img.height());
  Features f;
  f.keypoints.resize(static_cast<std::size_t>(o.max_features));
  f.upright.resize(f.keypoints.size());
  f.oriented.resize(f.keypoints.size());
  int n = 0;
  REQUIRE(fx.extract(img.constView(), {}, f.keypoints, f.upright, f.oriented, n) ==
          FeatureExtractor::Status::kOk);
  f.keypoints.resize(static_cast<std::size_t>(n));
  f.upright.resize(static_cast<std::size_t>(n));
  f.oriented.resize(static_cast<std::size_t>(n));
  return f;
}

// Matches a -> b with the chosen descriptor; counts those landing within 2 px of `expected`.
template <typename Map>
void matchAndScore(const Features& a, const Features& b, bool oriented,
                   const DescriptorMatchOptions& mo, Map expected, int& matches, int& correct) {
  DescriptorMatcher m(static_cast<int>(std::max(a.keypoints.size(), b.keypoints.size())));
  std::vector<DescriptorMatch> out(a.keypoints.size());
  m.match(a.keypoints, oriented ? a.oriented : a.upright, b.keypoints,
          oriented ? b.oriented : b.upright, mo, out, matches);
  correct = 0;
  for (int i = 0; i < matches; ++i) {
    const Keypoint& p = a.keypoints[static_cast<std::size_t>(out[static_cast<std::size_t>(i)].a)];
    const Keypoint& q = b.keypoints[static_cast<std::size_t>(out[static_cast<std::size_t>(i)].b)];
    double ex = 0.0, ey = 0.0;
    expected(static_cast<double>(p.x), static_cast<double>(p.y), ex, ey);
    correct += std::hypot(static_cast<double>(q.x) - ex, static_cast<double>(q.y) - ey) < 2.0;
  }
}

}  // namespace

TEST_CASE("Oriented BRIEF matches across in-plane rotation", "[matching][descriptor]") {
  const Image<uint8_t>& img = texturedFrame();
  FeatureExtractorOptions o;
  o.max_features = 1000;
  const Features a = extract(img, o);
  REQUIRE(a.keypoints.size() >= 800);
  const double cx = (img.width() - 1) * 0.5, cy = (img.height() - 1) * 0.5;
  for (const double deg : {0.0, 30.0, 90.0, 180.0, -135.0}) {
    INFO("rotation " << deg << " deg");
    const Features b = extract(rotated(img, deg), o);
    const double r = deg * M_PI / 180.0;
    const auto expected = [&](double x, double y, double& ex, double& ey) {
      ex = cx + std::cos(r) * (x - cx) - std::sin(r) * (y - cy);
      ey = cy + std::sin(r) * (x - cx) + std::cos(r) * (y - cy);
    };
    int matches = 0, correct = 0;
    matchAndScore(a, b, true, {}, expected, matches, correct);
    INFO("oriented: " << correct << " of " << matches << " correct");
    CHECK(correct >= 150);
    CHECK(correct >= 0.8 * matches);  // putative matches, before any geometric check
    // The upright descriptor holds for small rolls only.
    int up_matches = 0, up_correct = 0;
    matchAndScore(a, b, false, {}, expected, up_matches, up_correct);
    INFO("upright: " << up_correct << " of " << up_matches << " correct");
    if (deg == 0.0) CHECK(up_correct >= correct);
    if (std::abs(deg) >= 90.0) CHECK(up_correct < 0.2 * correct);
  }
}

TEST_CASE("The scale pyramid matches across a moderate scale change", "[matching][descriptor]") {
  const Image<uint8_t>& img = texturedFrame();
  FeatureExtractorOptions o;
  o.max_features = 1500;
  const Features a = extract(img, o);
  for (const double scale : {1.2, 1.5}) {
    INFO("downscaled by " << scale);
    const int w = static_cast<int>((img.width() - 1) / scale) + 1;
    const int h = static_cast<int>((img.height() - 1) / scale) + 1;
    Image<uint8_t> blurred(img.width(), img.height()), small(w, h);
    epitrack::resizeDown(img.constView(), scale, blurred.view(), small.view());
    const Features b = extract(small, o);
    const auto expected = [&](double x, double y, double& ex, double& ey) {
      ex = x / scale;
      ey = y / scale;
    };
    DescriptorMatchOptions mo;
    mo.max_level_diff = 1;  // a scale change moves a corner to the next level
    int matches = 0, correct = 0;
    matchAndScore(a, b, true, mo, expected, matches, correct);
    INFO(correct << " of " << matches << " correct");
    CHECK(correct >= 100);
    CHECK(correct >= 0.7 * matches);
  }
}

TEST_CASE("Oriented BRIEF is a pure function of the pattern seed and the pixels",
          "[matching][descriptor]") {
  // Integer arithmetic only (the detector's float response aside, which is exact on integer
  // sums): the same bits on every platform. The checksum pins them.
  const Image<uint8_t>& img = texturedFrame();
  FeatureExtractorOptions o;
  o.max_features = 300;
  const Features a = extract(img, o);
  const Features b = extract(img, o);
  REQUIRE(a.keypoints.size() == b.keypoints.size());
  uint64_t hash = 1469598103934665603ULL;
  for (std::size_t i = 0; i < a.keypoints.size(); ++i) {
    CHECK(epitrack::hammingDistance(a.oriented[i], b.oriented[i]) == 0);
    for (const uint64_t w : a.oriented[i].bits) hash = (hash ^ w) * 1099511628211ULL;
    for (const uint64_t w : a.upright[i].bits) hash = (hash ^ w) * 1099511628211ULL;
    hash = (hash ^ static_cast<uint64_t>(a.keypoints[i].angle_bin)) * 1099511628211ULL;
  }
  INFO("checksum " << hash);
  CHECK(hash == 12912137586250151377ULL);
  // Another seed, another pattern.
  FeatureExtractorOptions o2 = o;
  o2.pattern_seed = 12345;
  const Features c = extract(img, o2);
  int differing = 0;
  for (std::size_t i = 0; i < c.keypoints.size(); ++i)
    differing += epitrack::hammingDistance(a.upright[i], c.upright[i]) > 64 ? 1 : 0;
  CHECK(differing > 0.8 * static_cast<double>(c.keypoints.size()));
}

TEST_CASE("The matcher's ratio test and mutual check", "[matching][descriptor]") {
  // Three descriptors in a, three in b: b0 = a0 exactly; b1 and b2 both 2 bits from a1
  // (ambiguous); a2 far from everything.
  std::vector<Keypoint> ka(3), kb(3);
  std::vector<BinaryDescriptor> da(3), db(3);
  da[0].bits = {0x0123456789abcdefULL, 0xfedcba9876543210ULL, 0x0f0f0f0f0f0f0f0fULL, 0ULL};
  da[1].bits = {~0ULL, 0ULL, ~0ULL, 0ULL};
  da[2].bits = {0x5555555555555555ULL, 0x5555555555555555ULL, 0ULL, ~0ULL};
  db[0] = da[0];
  db[1] = da[1];
  db[1].bits[0] ^= 0x3ULL;  // 2 bits off
  db[2] = da[1];
  db[2].bits[1] ^= 0x5ULL;  // 2 other bits off
  DescriptorMatcher m(3);
  std::vector<DescriptorMatch> out(3);
  int n = 0;
  DescriptorMatchOptions mo;
  mo.max_distance = 40;
  m.match(ka, da, kb, db, mo, out, n);
  REQUIRE(n == 1);  // a1 fails the ratio test (2 vs 2), a2 is too far
  CHECK(out[0].a == 0);
  CHECK(out[0].b == 0);
  CHECK(out[0].distance == 0);
  mo.ratio = 0.0;  // no ratio test: a1 -> b1, the first of the two (mutual: b1's best is a1)
  m.match(ka, da, kb, db, mo, out, n);
  CHECK(n == 2);
  CHECK(out[1].a == 1);
  CHECK(out[1].b == 1);
}

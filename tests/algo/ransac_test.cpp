#include <catch2/catch.hpp>

#include <cmath>
#include <span>
#include <vector>

#include "algo/math/random.hpp"
#include "algo/robust/ransac.hpp"
#include "tests/support/seeded_random.hpp"

// The generic RANSAC/MSAC loop (algo/robust/ransac.hpp) on a toy kernel: a 2D line through two
// points. What it must do does not depend on the geometry: find the model of the inliers among
// outliers, stop by the iteration bound of H&Z eq. 4.18, skip degenerate samples, and be a pure
// function of its seed.

namespace {

struct Line {
  double a = 0.0;  // y = a x + b
  double b = 0.0;
};

struct LineKernel {
  static constexpr int kMinSamples = 2;
  static constexpr int kMaxModels = 1;
  using Model = Line;
  std::span<const double> xs;
  std::span<const double> ys;
  mutable int degenerate_samples = 0;

  int fit(std::span<const int> s, Line* models) const {
    const double dx = xs[s[1]] - xs[s[0]];
    models[0].a = (ys[s[1]] - ys[s[0]]) / dx;
    models[0].b = ys[s[0]] - models[0].a * xs[s[0]];
    return 1;
  }
  double squaredError(int i, const Line& m) const {
    const double r = ys[i] - (m.a * xs[i] + m.b);
    return r * r;
  }
  bool sampleIsDegenerate(std::span<const int> s) const {
    const bool degenerate = std::abs(xs[s[1]] - xs[s[0]]) < 1e-9;
    degenerate_samples += degenerate ? 1 : 0;
    return degenerate;
  }
};

struct LineData {
  std::vector<double> xs, ys;
  std::vector<bool> inlier;
};

// `n` points, a fraction `outliers` of them uniform in the box, the rest on y = 0.5 x + 2 with
// Gaussian noise of sigma 0.1.
LineData makeLine(int n, double outliers, uint64_t seed) {
  epitrack::SplitMix64 rng(seed);
  LineData d;
  for (int i = 0; i < n; ++i) {
    const double x = 100.0 * rng.uniform();
    const bool out = rng.uniform() < outliers;
    const double y =
        out ? 60.0 * rng.uniform() : 0.5 * x + 2.0 + 0.1 * epitrack::test::standardNormal(rng);
    d.xs.push_back(x);
    d.ys.push_back(y);
    d.inlier.push_back(out ? false : std::abs(y - (0.5 * x + 2.0)) < 0.5);
  }
  return d;
}

}  // namespace

TEST_CASE("RANSAC finds the line among 40 % outliers, with the support it counts",
          "[algo][ransac]") {
  const LineData d = makeLine(200, 0.4, 7);
  LineKernel kernel{d.xs, d.ys};
  epitrack::RansacOptions options;
  options.threshold = 0.5;
  options.seed = 3;
  epitrack::Ransac<LineKernel> ransac;
  Line best;
  epitrack::RansacSummary summary;
  REQUIRE(ransac.run(kernel, 200, options, best, summary));
  CHECK(best.a == Approx(0.5).margin(0.01));
  CHECK(best.b == Approx(2.0).margin(0.3));
  // The reported support is the number of data within the threshold of the returned model.
  int within = 0;
  for (int i = 0; i < 200; ++i) within += kernel.squaredError(i, best) < 0.25 ? 1 : 0;
  CHECK(summary.inliers == within);
  int true_inliers = 0;
  for (const bool in : d.inlier) true_inliers += in ? 1 : 0;
  CHECK(std::abs(summary.inliers - true_inliers) <= 3);  // an outlier may fall on the line
  // Stopped by eq. 4.18 for the found inlier ratio (at the first iteration past the bound of its
  // best model), far before max_iterations.
  const int bound = epitrack::ransacIterationsNeeded(static_cast<double>(summary.inliers) / 200, 2,
                                                     options.confidence, options.max_iterations);
  CHECK(summary.iterations >= std::max(bound, options.min_iterations));
  CHECK(summary.iterations < 100);
}

TEST_CASE("RANSAC is a pure function of its seed", "[algo][ransac]") {
  const LineData d = makeLine(150, 0.5, 11);
  LineKernel kernel{d.xs, d.ys};
  epitrack::RansacOptions options;
  options.threshold = 0.5;
  epitrack::Ransac<LineKernel> ransac;
  Line a, b;
  epitrack::RansacSummary sa, sb;
  options.seed = 42;
  REQUIRE(ransac.run(kernel, 150, options, a, sa));
  REQUIRE(ransac.run(kernel, 150, options, b, sb));
  CHECK(a.a == b.a);
  CHECK(a.b == b.b);
  CHECK(sa.iterations == sb.iterations);
  CHECK(sa.score == sb.score);
}

TEST_CASE("RANSAC iteration bound (H&Z eq. 4.18) and its edge cases", "[algo][ransac]") {
  // w = 0.5, s = 2, p = 0.99: log(0.01) / log(0.75) = 16.01 -> 17.
  CHECK(epitrack::ransacIterationsNeeded(0.5, 2, 0.99, 1000) == 17);
  // w = 0.5, s = 8 (eight-point F): log(0.01) / log(1 - 1/256) = 1176.6 -> 1177.
  CHECK(epitrack::ransacIterationsNeeded(0.5, 8, 0.99, 5000) == 1177);
  CHECK(epitrack::ransacIterationsNeeded(0.5, 8, 0.99, 500) == 500);  // capped
  CHECK(epitrack::ransacIterationsNeeded(0.0, 2, 0.99, 300) == 300);
  CHECK(epitrack::ransacIterationsNeeded(1.0, 8, 0.99, 300) == 1);
}

TEST_CASE("RANSAC refuses too few data and skips degenerate samples", "[algo][ransac]") {
  epitrack::Ransac<LineKernel> ransac;
  epitrack::RansacOptions options;
  Line best;
  epitrack::RansacSummary summary;
  const std::vector<double> one_x{1.0}, one_y{2.0};
  LineKernel one{one_x, one_y};
  CHECK_FALSE(ransac.run(one, 1, options, best, summary));
  CHECK(summary.iterations == 0);
  // Every point at the same x: every sample is degenerate, no model is fitted.
  const std::vector<double> xs(20, 5.0),
      ys{0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
  LineKernel vertical{xs, ys};
  options.max_iterations = 50;
  CHECK_FALSE(ransac.run(vertical, 20, options, best, summary));
  CHECK(vertical.degenerate_samples == 50);
}

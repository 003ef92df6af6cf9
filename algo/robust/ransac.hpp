#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>

#include "algo/math/random.hpp"

namespace epitrack {

struct RansacOptions {
  double threshold = 1.0;    ///< inlier threshold on the kernel's residual (pixels)
  double confidence = 0.99;  ///< stop when a better model is this unlikely to exist
  int min_iterations = 8;
  int max_iterations = 2000;
  uint64_t seed = 1;  ///< samples are a pure function of the seed (SplitMix64)
};

struct RansacSummary {
  int iterations = 0;
  int inliers = 0;
  double score = 0.0;  ///< MSAC cost of the best model (lower is better)
};

/// Number of iterations so that, with inlier ratio `w` and `s` samples, an all-inlier sample is
/// drawn with probability `confidence` (Hartley & Zisserman §4.7.1, eq. 4.18).
inline int ransacIterationsNeeded(double inlier_ratio, int samples, double confidence,
                                  int max_iterations) {
  if (inlier_ratio <= 0.0) return max_iterations;
  const double p_good = std::pow(inlier_ratio, samples);
  if (p_good >= 1.0 - 1e-12) return 1;
  const double n = std::log(1.0 - confidence) / std::log(1.0 - p_good);
  if (!std::isfinite(n) || n > max_iterations) return max_iterations;
  return std::max(1, static_cast<int>(std::ceil(n)));
}

/// Generic RANSAC with MSAC scoring (Torr & Zisserman 2000: truncated quadratic cost, which ranks
/// models by fit quality, not only inlier count) over a kernel:
///   static constexpr int kMinSamples, kMaxModels;  using Model = ...;
///   int fit(std::span<const int> sample, Model* models) const;   // minimal solver, 0..kMaxModels
///   double squaredError(int i, const Model& m) const;            // residual^2 of datum i
///   bool sampleIsDegenerate(std::span<const int>) const;         // rejection of bad samples
///   bool localOptimize(Model& m, double t2) const;               // optional: refit on inliers
/// Buffers (sample indices) are members sized at construction; `run` never allocates.
template <typename Kernel>
class Ransac {
 public:
  using Model = typename Kernel::Model;

  Ransac() = default;

  /// Returns false when fewer than kMinSamples data; `best` and the summary hold the winner.
  bool run(const Kernel& kernel, int count, const RansacOptions& options, Model& best,
           RansacSummary& summary) const {
    summary = {};
    if (count < Kernel::kMinSamples) return false;
    SplitMix64 rng(options.seed);
    const double t2 = options.threshold * options.threshold;
    int needed = options.max_iterations;
    double best_score = std::numeric_limits<double>::infinity();
    double best_raw = std::numeric_limits<double>::infinity();  // best score before LO
    constexpr int kMaxExtraLo = 50;
    int lo_runs = 0;
    int best_inliers = 0;
    bool found = false;
    int sample[Kernel::kMinSamples];
    Model models[Kernel::kMaxModels];
    int it = 0;
    for (; it < needed || it < options.min_iterations; ++it) {
      if (it >= options.max_iterations) break;
      drawSample(rng, count, sample);
      const std::span<const int> s(sample, Kernel::kMinSamples);
      if (kernel.sampleIsDegenerate(s)) continue;
      const int n_models = kernel.fit(s, models);
      for (int m = 0; m < n_models; ++m) {
        double score = 0.0;
        int inliers = 0;
        for (int i = 0; i < count; ++i) {
          const double e2 = kernel.squaredError(i, models[m]);
          if (e2 < t2) {
            score += e2;
            ++inliers;
          } else {
            score += t2;
          }
          if (score >= best_raw && score >= best_score && lo_runs >= kMaxExtraLo)
            break;  // cannot win any more
        }
        // LO is tried when the raw minimal model beats every raw model so far, or reaches half
        // the best support (a bounded number of times): a clean but noisy sample scores worse
        // than an optimised contaminated model, yet refits to the true one.
        const bool raw_record = score < best_raw;
        if (raw_record) best_raw = score;
        const bool promising =
            lo_runs < kMaxExtraLo && inliers > Kernel::kMinSamples && 2 * inliers >= best_inliers;
        if (!raw_record && promising && score >= best_score) ++lo_runs;
        if (raw_record || promising || score < best_score) {
          if constexpr (requires(Model & mm) { kernel.localOptimize(mm, t2); }) {
            // LO-RANSAC (Chum, Matas & Kittler 2003): refit the new best model on its inliers,
            // which turns a noisy minimal sample into a model that sees all of its support.
            Model refined = models[m];
            if (kernel.localOptimize(refined, t2)) {
              double s2 = 0.0;
              int in2 = 0;
              for (int i = 0; i < count; ++i) {
                const double e2 = kernel.squaredError(i, refined);
                s2 += e2 < t2 ? e2 : t2;
                in2 += e2 < t2 ? 1 : 0;
              }
              if (s2 < score) {
                score = s2;
                inliers = in2;
                models[m] = refined;
              }
            }
          }
          if (score >= best_score) continue;
          best_score = score;
          best_inliers = inliers;
          best = models[m];
          found = true;
          needed = ransacIterationsNeeded(static_cast<double>(inliers) / count, Kernel::kMinSamples,
                                          options.confidence, options.max_iterations);
        }
      }
    }
    summary.iterations = it;
    summary.inliers = best_inliers;
    summary.score = best_score;
    return found;
  }

 private:
  static void drawSample(SplitMix64& rng, int count, int* sample) {
    for (int k = 0; k < Kernel::kMinSamples; ++k) {
      bool again = true;
      while (again) {
        sample[k] = static_cast<int>(rng.below(static_cast<uint32_t>(count)));
        again = false;
        for (int j = 0; j < k; ++j) again = again || sample[j] == sample[k];
      }
    }
  }
};

}  // namespace epitrack

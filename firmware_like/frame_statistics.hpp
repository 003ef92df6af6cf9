#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

namespace epitrack::device {

/// Frame counts and processing-time order statistics over an unbounded run in fixed memory: a
/// histogram of 10 µs bins up to 500 ms (one overflow bin), the exact maximum. Percentiles are
/// the upper edge of their bin (at most 10 µs above the true value).
class FrameStatistics {
 public:
  static constexpr double kBinMs = 0.01;
  static constexpr int kBins = 50000;

  FrameStatistics() : bins_(kBins + 1, 0) {}

  void addTiming(double ms) {
    const double b = ms / kBinMs;
    const int bin = b >= kBins ? kBins : static_cast<int>(std::max(0.0, b));
    ++bins_[static_cast<std::size_t>(bin)];
    ++timed_;
    max_ms_ = std::max(max_ms_, ms);
  }
  /// Time under which a fraction `q` (0..1) of the timed frames fall.
  [[nodiscard]] double percentile(double q) const {
    if (timed_ == 0) return 0.0;
    const auto rank = static_cast<int64_t>(q * static_cast<double>(timed_ - 1));
    int64_t seen = 0;
    for (int i = 0; i <= kBins; ++i) {
      seen += bins_[static_cast<std::size_t>(i)];
      if (seen > rank) return i == kBins ? max_ms_ : std::min(max_ms_, (i + 1) * kBinMs);
    }
    return max_ms_;
  }
  [[nodiscard]] double maxMs() const { return max_ms_; }
  [[nodiscard]] int64_t timed() const { return timed_; }

  int64_t frames = 0;        ///< processed
  int64_t tracking = 0;      ///< with a pose
  int64_t initializing = 0;  ///< before a map existed
  int64_t lost = 0;          ///< tracking lost (map restarted)
  int64_t dropped = 0;       ///< arrived while processing lagged (or skipped by the device)
  int64_t corrupt = 0;       ///< could not be decoded
  int64_t initializations = 0;

 private:
  std::vector<int64_t> bins_;
  int64_t timed_ = 0;
  double max_ms_ = 0.0;
};

}  // namespace epitrack::device

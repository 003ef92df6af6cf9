#pragma once

#include <string>
#include <vector>

#include "algo/image/image.hpp"
#include "algo/sfm/track_table.hpp"
#include "algo/tracking/feature_tracker.hpp"

namespace epitrack::bench {

/// Loads up to `max_frames` frames of an INPUT into memory (so benchmarks time computation, not
/// decoding). An empty INPUT renders a synthetic 704x576 orbit (focal 600) instead.
bool loadBenchFrames(const std::string& input, int max_frames, std::vector<Image<uint8_t>>& frames,
                     std::string& error);

/// The 2D tracks of `frames` (FeatureTracker with `options`), finalized for a Solver.
TrackTable trackFrames(const std::vector<Image<uint8_t>>& frames,
                       const FeatureTrackerOptions& options);

}  // namespace epitrack::bench

#pragma once

#include <string>
#include <vector>

#include "algo/image/image.hpp"

namespace epitrack::bench {

/// Loads up to `max_frames` frames of an INPUT into memory (so benchmarks time computation, not
/// decoding). An empty INPUT renders a synthetic 704x576 orbit (focal 600) instead.
bool loadBenchFrames(const std::string& input, int max_frames, std::vector<Image<uint8_t>>& frames,
                     std::string& error);

}  // namespace epitrack::bench

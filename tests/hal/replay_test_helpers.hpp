#pragma once

// Helpers for the replay tests: synthetic frames and writers for Y4M and concatenated JPEG.

#include <cstdint>
#include <string>
#include <vector>

#include "algo/image/image.hpp"

namespace epitrack::test {

/// `count` frames of the synthetic orbit scene at w x h (deterministic).
std::vector<Image<uint8_t>> syntheticFrames(int width, int height, int count);

/// A Y4M stream of `frames` with colour space tag `chroma` (420jpeg, 422, 444, mono, 420p10, ...):
/// luma from the frames (shifted up for high bit depths), chroma planes filled with a pattern.
std::vector<uint8_t> makeY4m(const std::vector<Image<uint8_t>>& frames, const std::string& chroma,
                             int fps_num = 25, int fps_den = 1);

/// Concatenated gray JPEGs of `frames` at `quality`; `offsets` receives each frame's first byte.
std::vector<uint8_t> makeMjpeg(const std::vector<Image<uint8_t>>& frames, int quality,
                               std::vector<std::size_t>* offsets = nullptr);

/// Largest and mean absolute difference between two same-size views.
struct ImageDifference {
  int max_abs = 0;
  double mean_abs = 0.0;
};
ImageDifference imageDifference(ImageView<const uint8_t> a, ImageView<const uint8_t> b);

bool sameImage(ImageView<const uint8_t> a, ImageView<const uint8_t> b);

}  // namespace epitrack::test

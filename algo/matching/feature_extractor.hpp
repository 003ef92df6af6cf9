#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "algo/features/shi_tomasi_detector.hpp"
#include "algo/image/image.hpp"
#include "algo/image/image_view.hpp"
#include "algo/matching/oriented_brief.hpp"
#include "algo/matching/scale_pyramid.hpp"

namespace epitrack {

/// A multi-scale keypoint with its descriptor.
struct Keypoint {
  float x = 0.0f;  ///< level-0 pixel coordinates
  float y = 0.0f;
  float response = 0.0f;  ///< Shi-Tomasi response at its level
  int16_t level = 0;      ///< pyramid level (scale 2^(level/2))
  int16_t angle_bin = 0;  ///< OrientedBrief orientation bin
};

struct FeatureExtractorOptions {
  int max_features = 2000;  ///< keypoints per frame over every level (capacity)
  int levels = 5;           ///< scale levels (factor sqrt(2)), level 0 included
  /// Shi-Tomasi settings per level. The threshold is adaptive (the strongest `wanted` corners,
  /// down to min_quality of the strongest): a low floor keeps corners on weak texture.
  double min_quality = 0.0005;
  double min_distance = 7.0;  ///< px at each level
  int block_radius = 2;       ///< structure tensor over 5x5: steadier on JPEG blocks
  uint64_t pattern_seed = 0x6272696566ULL;
};

/// Detects Shi-Tomasi corners on every level of a sqrt(2) scale pyramid (ShiTomasiDetector per
/// level; ORB's share per level, proportional to the level's area), orients each by its intensity
/// centroid and describes it with oriented BRIEF on the level it was found on (so a corner seen at
/// another distance is described at a matching scale on another level). Buffers (pyramid,
/// integral images, detectors, corner lists) are sized at construction; `extract` never
/// allocates.
class FeatureExtractor {
 public:
  enum class Status { kOk, kSizeMismatch };

  FeatureExtractor(const FeatureExtractorOptions& options, int width, int height);
  ~FeatureExtractor();
  FeatureExtractor(const FeatureExtractor&) = delete;
  FeatureExtractor& operator=(const FeatureExtractor&) = delete;

  /// Extracts up to min(max_features, keypoints.size()) features of `image` (configured size).
  /// `mask` empty or the image size (0: no feature there). Keypoints are grouped by level,
  /// strongest first within a level; `found` receives the count. Each keypoint gets two
  /// descriptors when their spans are given (either may be empty: not computed): `upright` with
  /// the pattern unrotated (more distinctive when the camera does not roll between the views) and
  /// `oriented`, rotated to the keypoint's orientation (invariant to in-plane rotation). The
  /// spans, when given, must be as long as `keypoints`.
  Status extract(ImageView<const uint8_t> image, ImageView<const uint8_t> mask,
                 std::span<Keypoint> keypoints, std::span<BinaryDescriptor> upright,
                 std::span<BinaryDescriptor> oriented, int& found);

  /// Describes the level-0 position (x, y) of the last extracted image (a point found otherwise,
  /// e.g. tracked into it): orientation bin and the descriptors asked for (nullptr: not wanted).
  /// Returns false when (x, y) is closer than OrientedBrief::kBorder to an edge.
  bool describeAt(float x, float y, BinaryDescriptor* upright, BinaryDescriptor* oriented,
                  int16_t& angle_bin) const;

  [[nodiscard]] const FeatureExtractorOptions& options() const { return options_; }
  [[nodiscard]] int levelCount() const { return pyramid_.levelCount(); }
  [[nodiscard]] const ScalePyramid& pyramid() const { return pyramid_; }

 private:
  FeatureExtractorOptions options_;
  int width_ = 0, height_ = 0;
  ScalePyramid pyramid_;
  OrientedBrief brief_;
  std::vector<std::unique_ptr<ShiTomasiDetector>> detectors_;
  std::vector<Image<uint32_t>> integrals_;
  std::vector<Image<uint8_t>> masks_;  // the mask sampled at each level
  std::vector<int> wanted_;            // per level
  AlignedBuffer<Corner> corners_;
};

}  // namespace epitrack

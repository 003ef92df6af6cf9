#include "algo/matching/feature_extractor.hpp"

#include <algorithm>
#include <cmath>

namespace epitrack {

FeatureExtractor::FeatureExtractor(const FeatureExtractorOptions& options, int width, int height)
    : options_(options),
      width_(width),
      height_(height),
      pyramid_(width, height, options.levels),
      brief_(options.pattern_seed) {
  options_.max_features = std::max(1, options_.max_features);
  const int levels = pyramid_.levelCount();
  // ORB's distribution: the share of level l proportional to its area (1 / scale^2).
  double total = 0.0;
  for (int l = 0; l < levels; ++l) total += 1.0 / (pyramid_.scale(l) * pyramid_.scale(l));
  int assigned = 0;
  for (int l = 0; l < levels; ++l) {
    const ImageView<const uint8_t> v = pyramid_.level(l);
    const double share = 1.0 / (pyramid_.scale(l) * pyramid_.scale(l)) / total;
    int n = l + 1 == levels ? options_.max_features - assigned
                            : static_cast<int>(std::lround(share * options_.max_features));
    n = std::max(0, std::min(n, options_.max_features - assigned));
    assigned += n;
    wanted_.push_back(n);
    ShiTomasiOptions so;
    so.max_features = std::max(1, n);
    so.min_quality = options_.min_quality;
    so.min_distance = options_.min_distance;
    so.block_radius = options_.block_radius;
    so.border = OrientedBrief::kBorder + 1;
    detectors_.push_back(std::make_unique<ShiTomasiDetector>(so, v.width, v.height));
    integrals_.emplace_back(v.width + 1, v.height + 1);
    masks_.emplace_back(l == 0 ? 0 : v.width, l == 0 ? 0 : v.height);
  }
  corners_.reserve(static_cast<std::size_t>(options_.max_features));
}

FeatureExtractor::~FeatureExtractor() = default;

FeatureExtractor::Status FeatureExtractor::extract(
    ImageView<const uint8_t> image, ImageView<const uint8_t> mask, std::span<Keypoint> keypoints,
    std::span<BinaryDescriptor> upright, std::span<BinaryDescriptor> oriented, int& found) {
  found = 0;
  if (image.width != width_ || image.height != height_) return Status::kSizeMismatch;
  if (!mask.empty() && !sameSize(mask, image)) return Status::kSizeMismatch;
  if (pyramid_.build(image) != ScalePyramid::Status::kOk) return Status::kSizeMismatch;
  EPITRACK_ASSERT((upright.empty() || upright.size() >= keypoints.size()) &&
                  (oriented.empty() || oriented.size() >= keypoints.size()));
  const int capacity =
      static_cast<int>(std::min(keypoints.size(), static_cast<std::size_t>(options_.max_features)));
  integralImage(pyramid_.level(0), integrals_[0].view());
  for (int l = 0; l < pyramid_.levelCount() && found < capacity; ++l) {
    const ImageView<const uint8_t> level = pyramid_.level(l);
    const double scale = pyramid_.scale(l);
    ImageView<const uint8_t> level_mask;
    if (!mask.empty()) {
      if (l == 0) {
        level_mask = mask;
      } else {
        // Nearest sample of the mask at the level's pixel centres (16.16 fixed point).
        ImageView<uint8_t> m = masks_[static_cast<std::size_t>(l)].view();
        const int64_t step = std::llround(scale * 65536.0);
        for (int y = 0; y < m.height; ++y) {
          const int y0 = std::min(mask.height - 1, static_cast<int>((y * step + 32768) >> 16));
          const uint8_t* src = mask.row(y0);
          uint8_t* dst = m.row(y);
          for (int x = 0; x < m.width; ++x)
            dst[x] = src[std::min(mask.width - 1, static_cast<int>((x * step + 32768) >> 16))];
        }
        level_mask = m;
      }
    }
    const int wanted = std::min(wanted_[static_cast<std::size_t>(l)], capacity - found);
    if (wanted <= 0) continue;
    int n = 0;
    const std::span<Corner> corners(corners_.data(), static_cast<std::size_t>(wanted));
    if (detectors_[static_cast<std::size_t>(l)]->detect(level, {}, level_mask, wanted, corners,
                                                        n) != ShiTomasiDetector::Status::kOk)
      continue;
    ImageView<uint32_t> integral = integrals_[static_cast<std::size_t>(l)].view();
    if (l > 0) integralImage(level, integral);
    const int lo = OrientedBrief::kBorder;
    const int hi_x = level.width - 1 - OrientedBrief::kBorder;
    const int hi_y = level.height - 1 - OrientedBrief::kBorder;
    if (hi_x < lo || hi_y < lo) continue;
    for (int i = 0; i < n && found < capacity; ++i) {
      const Corner& c = corners[static_cast<std::size_t>(i)];
      const int px = std::clamp(static_cast<int>(std::lround(c.x)), lo, hi_x);
      const int py = std::clamp(static_cast<int>(std::lround(c.y)), lo, hi_y);
      Keypoint& k = keypoints[static_cast<std::size_t>(found)];
      k.x = static_cast<float>(static_cast<double>(c.x) * scale);
      k.y = static_cast<float>(static_cast<double>(c.y) * scale);
      k.response = c.response;
      k.level = static_cast<int16_t>(l);
      k.angle_bin = static_cast<int16_t>(brief_.orientationBin(level, px, py));
      if (!upright.empty())
        brief_.describe(integral, px, py, 0, upright[static_cast<std::size_t>(found)]);
      if (!oriented.empty())
        brief_.describe(integral, px, py, k.angle_bin, oriented[static_cast<std::size_t>(found)]);
      ++found;
    }
  }
  return Status::kOk;
}

bool FeatureExtractor::describeAt(float x, float y, BinaryDescriptor* upright,
                                  BinaryDescriptor* oriented, int16_t& angle_bin) const {
  const ImageView<const uint8_t> level = pyramid_.level(0);
  const int px = static_cast<int>(std::lround(x));
  const int py = static_cast<int>(std::lround(y));
  if (px < OrientedBrief::kBorder || py < OrientedBrief::kBorder ||
      px > level.width - 1 - OrientedBrief::kBorder ||
      py > level.height - 1 - OrientedBrief::kBorder)
    return false;
  const ImageView<const uint32_t> integral = integrals_[0].constView();
  angle_bin = static_cast<int16_t>(brief_.orientationBin(level, px, py));
  if (upright != nullptr) brief_.describe(integral, px, py, 0, *upright);
  if (oriented != nullptr) brief_.describe(integral, px, py, angle_bin, *oriented);
  return true;
}

}  // namespace epitrack

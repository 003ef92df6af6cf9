#pragma once

#include <cstdint>
#include <span>

#include "algo/core/aligned_buffer.hpp"
#include "algo/image/image.hpp"
#include "algo/image/image_view.hpp"

namespace epitrack {

/// A detected corner in pixel coordinates of the image it was found in.
struct Corner {
  float x = 0.0f;
  float y = 0.0f;
  float response = 0.0f;  ///< minimum eigenvalue of the structure tensor (Scharr units)
};

/// A half-open pixel rectangle [x0, x1) x [y0, y1).
struct PixelRect {
  int x0 = 0;
  int y0 = 0;
  int x1 = 0;
  int y1 = 0;
};

/// Where detectInRegions looks, and how many corners it may take there at most.
struct DetectionRegion {
  PixelRect area;
  int wanted = 0;  ///< at most this many corners here; < 0: no cap, the call's budget is shared
};

/// A 2-D point (an existing feature the detector must keep away from).
struct Point2f {
  float x = 0.0f;
  float y = 0.0f;
};

struct ShiTomasiOptions {
  int max_features = 300;       ///< capacity of one detection call
  int block_radius = 1;         ///< structure tensor summed over (2r+1)^2 pixels
  double min_quality = 0.001;   ///< floor of the adaptive threshold, relative to the strongest
  double min_distance = 10.0;   ///< minimum distance between features (and to existing ones), px
  int border = 12;              ///< corners closer than this to the image edge are ignored
  bool subpixel = true;         ///< Foerstner refinement of each accepted corner
  int subpixel_radius = 4;      ///< refinement window (2r+1)^2
  int subpixel_dead_zone = 2;   ///< pixels within this (Chebyshev) distance of the centre unused
  int subpixel_iterations = 5;  ///< re-centring passes of the refinement
  bool vector_kernels = true;   ///< SIMD response and maxima where available (same corners)
};

/// Grid of cells of side min_distance holding up to kPerCell points each, so the minimum-distance
/// test looks at a 3x3 block of cells instead of every feature (not O(n^2)). Points spaced at
/// least min_distance apart never exceed 4 per cell; extra points (existing features that crowd
/// together) are dropped from the grid, which only weakens the test locally.
class FeatureGrid {
 public:
  FeatureGrid() = default;
  FeatureGrid(int width, int height, double min_distance) {
    configure(width, height, min_distance);
  }
  void configure(int width, int height, double min_distance);
  void clear();
  /// True when no point in the grid lies closer than min_distance to (x, y).
  [[nodiscard]] bool isFree(float x, float y) const;
  /// Adds a point (without testing).
  void insert(float x, float y);
  static constexpr int kPerCell = 4;

 private:
  [[nodiscard]] int cellIndex(int cx, int cy) const { return cy * cols_ + cx; }
  AlignedBuffer<Point2f> points_;
  AlignedBuffer<uint8_t> count_;
  int cols_ = 0;
  int rows_ = 0;
  float cell_ = 1.0f;
  float min_distance2_ = 0.0f;
};

/// Shi-Tomasi ("Good features to track", Shi & Tomasi 1994; the paper §4.1) corner detector.
/// Response: the minimum eigenvalue of the Scharr-gradient structure tensor summed over a
/// (2r+1)^2 block, integer sums (int32). Candidates are 3x3 local maxima; they are accepted in
/// decreasing response while at least `min_distance` from every accepted or existing feature and
/// on a non-zero mask pixel, until `wanted` are found. The effective threshold therefore drops
/// until the requested count is reached (the paper: the fewer found, the lower the threshold),
/// down to `min_quality` times the strongest response. Buffers are sized at construction;
/// `detect` never allocates.
class ShiTomasiDetector {
 public:
  enum class Status { kOk, kSizeMismatch, kNotConfigured };

  ShiTomasiDetector(const ShiTomasiOptions& options, int width, int height);

  /// Detects up to min(wanted, out.size(), max_features) corners of `image` (configured size).
  /// `existing`: features to keep `min_distance` away from. `mask`: empty, or the image size with
  /// 0 = never detect here. `found` receives the number written to `out`, strongest first.
  Status detect(ImageView<const uint8_t> image, std::span<const Point2f> existing,
                ImageView<const uint8_t> mask, int wanted, std::span<Corner> out, int& found);

  /// As `detect`, but corners only inside the regions' areas (candidate positions; clipped to the
  /// border), at most each region's `wanted` there (strongest first, region by region, all kept
  /// min_distance apart; regions without a cap first, together, strongest first): the gradients and
  /// the response are computed over those rectangles and the margins the block sums, the 3x3 maxima
  /// and the sub-pixel refinement read, nothing else. Inside a region the responses equal
  /// `detect`'s; the adaptive threshold is relative to the strongest response in the regions. The
  /// tracker re-detects so in the cells that lost tracks.
  Status detectInRegions(ImageView<const uint8_t> image, std::span<const Point2f> existing,
                         ImageView<const uint8_t> mask, std::span<const DetectionRegion> regions,
                         int wanted, std::span<Corner> out, int& found);

  /// The relative threshold reached by the last call (response of the weakest accepted corner
  /// divided by the strongest response in the image).
  [[nodiscard]] double lastQuality() const { return last_quality_; }
  [[nodiscard]] const ShiTomasiOptions& options() const { return options_; }

  /// Foerstner sub-pixel corner position (least-squares intersection of the gradient lines,
  /// Foerstner & Guelch 1987) around (x, y) from the gradients of the last `detect` image.
  void refine(float& x, float& y) const;

 private:
  /// The response over `r` (gradients there and r.block_radius around must be current); raises
  /// max_response_ to the largest response in `r`.
  void computeResponse(const PixelRect& r);
  void computeResponseScalar(const PixelRect& r);
  void computeResponseVector(const PixelRect& r);
  /// 3x3 local maxima of the response above `floor_response` on row y, columns [x0, x1),
  /// appended to the n candidates in increasing x; returns the new count.
  std::size_t rowMaximaScalar(int y, int x0, int x1, float floor_response, const uint8_t* mask,
                              std::size_t n);
  std::size_t rowMaximaVector(int y, int x0, int x1, float floor_response, const uint8_t* mask,
                              std::size_t n);
  /// Appends the 3x3 maxima of the candidate rectangle `r` (response computed around it).
  std::size_t collectMaxima(const PixelRect& r, float floor_response, ImageView<const uint8_t> mask,
                            std::size_t n);
  /// Accepts the n candidates strongest first while free of the grid's points (inserted), until
  /// `found` reaches `limit`.
  void selectCorners(std::size_t n, int limit, std::span<Corner> out, int& found);
  /// The grid holds `existing` only.
  void resetGrid(std::span<const Point2f> existing);
  /// The configuration, image and mask sizes; `too_small`: the image has no corner area.
  Status checkInput(ImageView<const uint8_t> image, ImageView<const uint8_t> mask,
                    bool& too_small) const;
  /// `r` clipped to the rectangle where corners may lie (the border left out); may be empty.
  [[nodiscard]] PixelRect clipToCornerArea(const PixelRect& r) const;

  ShiTomasiOptions options_;
  int width_ = 0;
  int height_ = 0;
  Image<int16_t> dx_;
  Image<int16_t> dy_;
  Image<float> response_;
  AlignedBuffer<int32_t> row_sums_;  // 3 products x (2r+1) rows x width, horizontal sums
  AlignedBuffer<int32_t> products_;  // 3 products x width of one row (the vector path)
  AlignedBuffer<Corner> candidates_;
  std::size_t candidate_capacity_ = 0;
  FeatureGrid grid_;
  float max_response_ = 0.0f;
  double last_quality_ = 0.0;
};

}  // namespace epitrack

#pragma once

#include <cstdint>
#include <vector>

namespace epitrack {

/// The image motion the camera causes between two frames, as a similarity:
/// x' = a x - b y + tx, y' = b x + a y + ty (a rotation by atan2(b, a), a scale by hypot(a, b),
/// a translation). Hand-held shake and pans are mostly rotation about the optical centre, which
/// moves a distant scene by nearly a similarity; what a similarity cannot explain (parallax,
/// perspective) is left to each track's own motion model.
struct SimilarityMotion {
  double a = 1.0;
  double b = 0.0;
  double tx = 0.0;
  double ty = 0.0;
  void apply(double x, double y, double& ox, double& oy) const {
    ox = a * x - b * y + tx;
    oy = b * x + a * y + ty;
  }
  /// The identity (no motion).
  [[nodiscard]] bool isIdentity() const { return a == 1.0 && b == 0.0 && tx == 0.0 && ty == 0.0; }
};

struct GlobalMotionOptions {
  int max_points = 64;               ///< capacity (correspondences beyond it are refused by add)
  int iterations = 48;               ///< RANSAC samples (2 points each)
  double inlier_px = 2.0;            ///< a correspondence agrees with the model within this, px
  int min_inliers = 5;               ///< fewer inliers than this: no model
  double min_inlier_fraction = 0.4;  ///< ... or fewer than this fraction of the points
  double min_pair_px = 8.0;  ///< a sample's two points at least this far apart (conditioning)
  uint64_t seed = 0x5eed;    ///< the sampler's seed: the same input gives the same model
};

/// Robust similarity between two point sets (correspondences p -> q): 2-point RANSAC with MSAC
/// scoring (Torr & Zisserman 2000), then least squares over the inliers, re-classified and
/// solved once more. Points are added one by one into buffers allocated at construction;
/// `estimate` never allocates. The sampler restarts from the seed on every call, so the result
/// depends only on the points and their order.
class GlobalMotionEstimator {
 public:
  enum class Status { kOk, kTooFewPoints, kNoConsensus };

  explicit GlobalMotionEstimator(const GlobalMotionOptions& options = {});

  void clear() { count_ = 0; }
  /// Adds the correspondence (x0, y0) -> (x1, y1); false when the capacity is reached.
  bool add(double x0, double y0, double x1, double y1);
  [[nodiscard]] int size() const { return count_; }

  /// Fits the similarity; on kOk `motion` holds it and inlier(i) tells which points agree.
  /// On failure `motion` is left unchanged.
  Status estimate(SimilarityMotion& motion);
  [[nodiscard]] int inlierCount() const { return inlier_count_; }
  [[nodiscard]] bool inlier(int i) const { return inliers_[static_cast<std::size_t>(i)] != 0; }
  [[nodiscard]] const GlobalMotionOptions& options() const { return options_; }

 private:
  /// Least squares over the points flagged in inliers_ (closed form about the centroids);
  /// false when they are degenerate (fewer than 2, or all at one place).
  bool fitInliers(SimilarityMotion& motion) const;
  /// Flags the points within inlier_px of `motion`; returns their count.
  int classify(const SimilarityMotion& motion);

  GlobalMotionOptions options_;
  std::vector<double> x0_, y0_, x1_, y1_;
  std::vector<uint8_t> inliers_;
  int count_ = 0;
  int inlier_count_ = 0;
};

}  // namespace epitrack

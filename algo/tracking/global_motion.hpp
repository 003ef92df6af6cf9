#pragma once

#include <cstdint>
#include <vector>

namespace epitrack {

/// The image motion the camera causes between two frames, as a similarity:
/// x' = a x - b y + tx, y' = b x + a y + ty (a rotation by atan2(b, a), a scale by hypot(a, b),
/// a translation). Hand-held shake and pans are mostly rotation about the optical centre, which
/// moves a distant scene by nearly a similarity; what a similarity cannot explain (parallax,
/// perspective) is left to each track's own motion model.
///
/// With a rolling shutter each row is exposed at its own time, and a camera that jerks moves the
/// rows by different amounts: the row term (rx, ry) adds a displacement proportional to the row,
/// x' += rx y, y' += ry y (GlobalMotionOptions::row_term). Similarity plus row term is the
/// affine map x' = a x + (rx - b) y + tx, y' = b x + (a + ry) y + ty.
struct SimilarityMotion {
  double a = 1.0;
  double b = 0.0;
  double tx = 0.0;
  double ty = 0.0;
  double rx = 0.0;  ///< row term, px per row (0 unless GlobalMotionOptions::row_term)
  double ry = 0.0;
  void apply(double x, double y, double& ox, double& oy) const {
    ox = a * x - b * y + tx + rx * y;
    oy = b * x + a * y + ty + ry * y;
  }
  /// The identity (no motion).
  [[nodiscard]] bool isIdentity() const {
    return a == 1.0 && b == 0.0 && tx == 0.0 && ty == 0.0 && rx == 0.0 && ry == 0.0;
  }
};

struct GlobalMotionOptions {
  int max_points = 64;               ///< capacity (correspondences beyond it are refused by add)
  int iterations = 48;               ///< RANSAC samples (2 points each)
  double inlier_px = 2.0;            ///< a correspondence agrees with the model within this, px
  int min_inliers = 5;               ///< fewer inliers than this: no model
  double min_inlier_fraction = 0.4;  ///< ... or fewer than this fraction of the points
  double min_pair_px = 8.0;  ///< a sample's two points at least this far apart (conditioning)
  uint64_t seed = 0x5eed;    ///< the sampler's seed: the same input gives the same model
  /// Rolling shutter: when the similarity leaves more than row_term_below of the points out, a
  /// similarity with a row term (3-point RANSAC) is fitted too, and kept when it takes in at
  /// least row_term_gain of the points more. Off by default: an affine map also fits parallax
  /// (a turntable, forward motion), and kept on every frame it moved templeRing 12-30's
  /// self-calibrated focal from 1522 to 1536 px; epitrack-solve turns it on with a readout
  /// (--readout-ms, --readout auto), epitrack-track with --motion-rows.
  bool row_term = false;
  double row_term_below = 0.9;
  double row_term_gain = 0.15;
  double max_row_term = 0.05;  ///< px per row: beyond, a sample is two objects, not the rows
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
  /// The centroids of the points flagged in inliers_, before (mx0, my0) and after (mx1, my1);
  /// returns their count (0: centroids zero).
  int inlierCentroids(double& mx0, double& my0, double& mx1, double& my1) const;
  /// Flags the points within inlier_px of `motion`; returns their count.
  int classify(const SimilarityMotion& motion);
  /// MSAC cost of `motion` over every point (squared errors capped at inlier_px^2).
  [[nodiscard]] double msacCost(const SimilarityMotion& motion) const;
  /// The similarity with a row term: 3-point RANSAC, then least squares over its inliers
  /// (re-classified); false when no sample gives a plausible model.
  bool estimateWithRows(SimilarityMotion& motion, int& inliers);
  /// Least squares of the affine map over the points flagged in inliers_.
  bool fitInliersWithRows(SimilarityMotion& motion) const;
  /// The row (sample) term in the consensus loop: the model through points i, j, k.
  [[nodiscard]] bool affineThrough(std::size_t i, std::size_t j, std::size_t k,
                                   SimilarityMotion& motion) const;

  GlobalMotionOptions options_;
  std::vector<double> x0_, y0_, x1_, y1_;
  std::vector<uint8_t> inliers_;
  int count_ = 0;
  int inlier_count_ = 0;
};

}  // namespace epitrack

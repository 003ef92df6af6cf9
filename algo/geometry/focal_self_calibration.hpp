#pragma once

#include <span>

#include <Eigen/Core>

namespace epitrack {

struct FocalSearchOptions {
  double min_focal_widths =
      0.3;  ///< search range, in image widths (paper §5.2: f is unknown but bounded)
  double max_focal_widths = 5.0;
  int grid_samples = 96;  ///< log-spaced coarse samples before the golden-section refinement
  /// A pair is "observable" when the cost rises, at f * (1 +- flatness_step), by at least
  /// min_rise over its minimum and by min_rise_ratio times the minimum itself (flat cost curves
  /// are the critical motions: intersecting optical axes, pure translation, rotation, no parallax).
  double flatness_step = 0.2;
  double min_rise = 2e-3;
  double min_rise_ratio = 1.0;
  /// Multi-pair: estimates farther than this (relative) from the median are "incoherent".
  double coherence_tolerance = 0.1;
};

/// The single-pair result of the self-calibration.
struct FocalPairEstimate {
  double focal_px = 0.0;  ///< meaningful only when observable
  double cost = 0.0;      ///< singular-value gap at the minimum
  double rise = 0.0;      ///< min of the cost at f*(1 +- step) minus the minimum: the sharpness
  bool observable = false;
  bool coherent = false;  ///< filled by the multi-pair combination
};

/// Mendonça & Cipolla (1999) cost for one F: with K = [f 0 cx; 0 f cy; 0 0 1] (principal point at
/// the image centre, no skew, paper §5.2), E(f) = K^T F K must have two equal non-zero singular
/// values; cost(f) = (s1 - s2) / (s1 + s2), in [0, 1].
double focalCost(const Eigen::Matrix3d& F, double cx, double cy, double f);

/// Minimises focalCost over f in the configured range (coarse log grid, then golden section) and
/// measures the flatness around the minimum. A minimum on the search bound is never an answer:
/// it is reported as not observable.
FocalPairEstimate estimateFocalFromFundamental(const Eigen::Matrix3d& F, int width, int height,
                                               const FocalSearchOptions& options = {});

struct FocalCalibrationResult {
  double focal_px = 0.0;
  bool observable = false;
  int pairs = 0;             ///< pairs given
  int observable_pairs = 0;  ///< pairs whose own cost curve has a clear minimum
  int coherent_pairs = 0;    ///< observable pairs that agree with the median
  double spread = 0.0;       ///< median absolute deviation of the coherent estimates / focal
};

/// Combines many pairs (the paper averages the "coherent" estimates; here the coherent pairs'
/// cost curves are summed and minimised jointly, which weighs well-conditioned pairs more than
/// flat ones). Writes each pair's estimate into `per_pair` (same size as `Fs`). Observable only
/// when at least one pair is and the coherent pairs form the majority of the observable ones.
FocalCalibrationResult calibrateFocalMultiPair(std::span<const Eigen::Matrix3d> Fs, int width,
                                               int height, std::span<FocalPairEstimate> per_pair,
                                               const FocalSearchOptions& options = {});

/// Why a pair gave no focal: its correspondences fit a homography better than F (GRIC), i.e. a
/// pure rotation, a plane or no motion, where every F compatible with H fits and F says nothing.
enum class PairModel { kFundamental, kHomography, kFailed };

struct FocalFromMatches {
  PairModel model = PairModel::kFailed;
  FocalPairEstimate estimate;  ///< observable only for kFundamental with a clear minimum
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();
};

class FundamentalRansac;
class HomographyRansac;
struct FundamentalOptions;

/// The paper's §5.2 per pair with the model selection first: F and H by RANSAC, GRIC decides; only
/// a pair that needs F (general motion, 3D scene) yields a focal estimate.
FocalFromMatches estimateFocalFromMatches(std::span<const Eigen::Vector2d> x1,
                                          std::span<const Eigen::Vector2d> x2, int width,
                                          int height, FundamentalRansac& f_ransac,
                                          HomographyRansac& h_ransac, double sigma_px,
                                          const FundamentalOptions& f_options,
                                          const FocalSearchOptions& options = {});

/// Focal from the homography of a purely rotating camera (the "tripod" case, Hartley 1997
/// "Self-calibration of stationary cameras"): H ~ K R K^-1, so K^-1 H K must be a rotation; the
/// cost is the normalized spread of its singular values, minimised over f like the F cost.
FocalPairEstimate estimateFocalFromRotation(const Eigen::Matrix3d& H, int width, int height,
                                            const FocalSearchOptions& options = {});

}  // namespace epitrack

#pragma once

// Does the camera model explain the image rows? (issue 27: a status that reads a model misfit.)
//
// A rolling shutter exposes each row at its own time. When a solve's model of that is wrong (a
// rolling-shutter clip solved as a global shutter, a wrong readout, or jitter faster than the
// model's motion within a readout), every frame keeps a residual that grows with the row: the
// rows' unexplained motion shears the image (x residual proportional to the row) or stretches it
// (y residual proportional to the row). A pose cannot absorb it (a rotation about the optical axis
// turns x by y *and* y by x), the points cannot either (they are shared between frames whose
// shear differs), so it stays in the residuals however long the adjustment runs.
//
// The test, per frame: the residuals (observed - projected, pixels) are fitted by an affine field
// r = a + B [u v]^T, u = (x - cx) / H, v = (y - cy) / H (H the image height), by least squares.
// B's similarity part (a zoom and a turn: what a focal error or a frame's pose produce) is set
// aside; what is left, c = ((b_yv - b_xu) / 2, (b_xv + b_yu) / 2), is the rows' own: a row term
// of k pixels from the top row to the bottom (x or y) gives 2|c| = k, the frame's "row shear".
// Under a right model c is noise: its two components are uncorrelated with variance
// sigma^2 (M_uu + M_vv) / 4 (M = (A^T A)^-1, sigma the frame's residual scale after the fit),
// so chi2 = |c|^2 / var follows a chi-square with 2 degrees of freedom. A frame is "sheared"
// when chi2 exceeds RowMisfitOptions::chi2_threshold (significant) and 2|c| exceeds
// min_shear_px (large enough to matter for an inserted object: a long clip's noise-level shears
// are significant but harmless). The clip's model misfits when more than max_sheared_fraction of
// the tested frames are sheared.

#include <cstdint>
#include <span>

namespace epitrack {

/// One observation's residual: where it was seen and observed minus projected, pixels.
struct RowResidual {
  int64_t frame = 0;
  double x = 0.0, y = 0.0;
  double dx = 0.0, dy = 0.0;
};

struct RowMisfitOptions {
  /// Frames with fewer observations are not tested (the fit has 3 parameters per axis).
  int min_observations = 20;
  /// chi-square (2 degrees of freedom) above which a frame's shear is significant: 18.4 is a
  /// false-alarm rate of 1e-4 per frame for Gaussian noise.
  double chi2_threshold = 18.4;
  /// A significant shear counts when 2|c| is at least this, pixels from the top row to the bottom.
  double min_shear_px = 0.5;
  /// The model misfits when more than this fraction of the tested frames are sheared. A fifth:
  /// the real global-shutter sequences shear up to 10 % of their frames (KITTI highway, 5 of 51,
  /// self-calibrated), a rolling shutter the model misses shears most (docs/rolling-shutter.md).
  double max_sheared_fraction = 0.2;
};

struct RowMisfit {
  int frames_tested = 0;
  int frames_sheared = 0;
  double median_shear_px = 0.0;  ///< median over tested frames of the row shear 2|c|
  double p90_shear_px = 0.0;     ///< 90th percentile of it
  double max_shear_px = 0.0;
  int64_t max_shear_frame = -1;  ///< the frame of max_shear_px (-1: none tested)
  bool misfit = false;
};

/// The row-shear test over a clip. `residuals` sorted by frame (outliers already left out);
/// `cx`, `cy` the principal point and `height` the image height in pixels. Allocates (a sort of
/// the per-frame shears): a once-per-solve diagnostic, not per-frame code.
RowMisfit measureRowMisfit(std::span<const RowResidual> residuals, double cx, double cy,
                           double height, const RowMisfitOptions& options = {});

}  // namespace epitrack

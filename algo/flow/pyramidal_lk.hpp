#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "algo/core/aligned_buffer.hpp"
#include "algo/flow/lk_kernels.hpp"
#include "algo/image/image_view.hpp"
#include "algo/image/pyramid.hpp"

namespace epitrack {

/// Why a feature was kept or lost by the Lucas-Kanade step.
enum class LkStatus : uint8_t {
  kTracked,          ///< converged inside the image
  kLeftImage,        ///< the window left the image at the finest level
  kLowTexture,       ///< the template's gradient matrix is (near) singular
  kNoConvergence,    ///< the update did not settle within max_iterations, or diverged
  kResidualTooHigh,  ///< aligned, but the patch no longer looks like its template
  kForwardBackward,  ///< tracking back did not return to the start
};
const char* lkStatusName(LkStatus status);

/// The linear part of the affine warp from a feature's template to the current image
/// (identity when the template was just taken).
struct PatchShape {
  float a00 = 1.0f;
  float a01 = 0.0f;
  float a10 = 0.0f;
  float a11 = 1.0f;
};

struct LkOptions {
  int window = 21;             ///< odd window side in pixels (Bouguet 2000: 2w+1)
  int levels = 3;              ///< pyramid levels beyond the base
  int max_iterations = 10;     ///< per level
  double epsilon = 0.01;       ///< stop when the update is smaller than this (pixels of the level)
  double min_eigen = 4.0;      ///< minimum eigenvalue of the mean gradient matrix, (gray/px)^2
  double max_residual = 1e9;   ///< kResidualTooHigh beyond this relative residual (see align)
  bool affine = true;          ///< base level: affine warp + bias instead of translation + bias
  bool vector_kernels = true;  ///< SIMD inner loops where available (same results as scalar)
  /// The residual is measured over the central (2 r + 1)^2 pixels of the window, r this radius
  /// (-1: a quarter of the window side, 5 for 21x21; 0 or >= half the window: all of it). The
  /// point is visible when its neighbourhood matches: structure entering the window's rim (an
  /// occluder approaching, the background beside a box edge, perspective beyond the affine
  /// warp) must not kill a track whose centre still follows its template.
  int residual_radius = -1;
};

/// Pyramidal Lucas-Kanade tracking of translation plus an intensity offset (bias), after
/// Bouguet 2000 ("Pyramidal implementation of the Lucas Kanade feature tracker": coarse to fine,
/// iterative per level, 2x2 solve per iteration), in the inverse-compositional form (Baker &
/// Matthews 2004 §3.2): each feature owns a *template* per level, the patch around it in the
/// image where the template was taken, with its Scharr gradients and the Gauss-Newton Hessian
/// precomputed, so an iteration is one pass of bilinear sampling over the window.
///
/// Aligning against the template (the patch at detection) instead of the previous frame does not
/// accumulate frame-to-frame error (drift); the caller refreshes a template when its residual
/// grows (appearance change) with `setTemplate` at the tracked position.
///
/// Fixed point: bilinear weights in kWeightBits = 14 bits, the last weight the remainder so the
/// four sum exactly to 1 << 14; samples and template values carry kValueBits = 5 fractional bits;
/// products accumulate in int32 per row and int64 per window (algo/flow/lk_kernels.hpp; the
/// translation iterations use its vector kernel, bit-identical to the scalar one). Capacity
/// (feature slots) is fixed at construction; no call allocates afterwards.
class PyramidalLk {
 public:
  static constexpr int kWeightBits = kLkWeightBits;
  static constexpr int kValueBits = kLkValueBits;
  static constexpr int kMaxLevels = Pyramid::kMaxLevels;

  PyramidalLk(const LkOptions& options, int capacity);

  /// Takes the template of slot `slot` from `pyramid` around (x, y) (base-level pixels) on every
  /// level where the window fits. Returns kTracked, kLeftImage (window outside the base level) or
  /// kLowTexture (base-level gradient matrix below min_eigen).
  LkStatus setTemplate(int slot, const Pyramid& pyramid, float x, float y);
  /// Copies slot `from`'s template (every level) into slot `to`.
  void copyTemplate(int from, int to);

  /// Aligns slot `slot`'s template in `pyramid` starting from the guess (x, y) (base level),
  /// coarse to fine. On kTracked or kResidualTooHigh, (x, y) is the aligned position and
  /// `residual` the RMS error at the base level after removing the intensity offset over the
  /// central residual window (LkOptions::residual_radius), divided by the template's intensity
  /// standard deviation there (0: identical; about 1.4: unrelated patches).
  LkStatus align(int slot, const Pyramid& pyramid, float& x, float& y, float& residual) const {
    PatchShape shape;
    return align(slot, pyramid, x, y, shape, residual);
  }
  /// As above, with the affine shape of the template in the image (in: the previous frame's,
  /// out: the aligned one). The base level estimates an affine warp (Baker & Matthews 2004 §2-3,
  /// inverse compositional with a bias term); coarser levels a translation.
  /// `start_level` (default: the coarsest) lets a caller with a good prediction (a Kalman filter)
  /// skip the coarse levels.
  LkStatus align(int slot, const Pyramid& pyramid, float& x, float& y, PatchShape& shape,
                 float& residual, int start_level = kMaxLevels) const;

  [[nodiscard]] const LkOptions& options() const { return options_; }
  [[nodiscard]] int capacity() const { return capacity_; }
  /// Iterations spent by the last `align` calls (summed; reset by resetCounters).
  [[nodiscard]] long iterations() const { return iterations_; }
  void resetCounters() const { iterations_ = 0; }

 private:
  struct LevelTemplate {
    double offset_x = 0.0;  ///< feature position minus the template's integer centre (level px)
    double offset_y = 0.0;
    bool valid = false;
    double contrast = 1.0;         ///< standard deviation of the template intensities (gray levels)
    double centre_contrast = 1.0;  ///< ... over the residual's central window (base level)
    std::array<double, 9> H_inv{};  ///< inverse of the 3x3 Gauss-Newton Hessian (x, y, bias)
  };
  [[nodiscard]] std::size_t patchIndex(int slot, int level) const {
    return (static_cast<std::size_t>(slot) * static_cast<std::size_t>(level_count_) +
            static_cast<std::size_t>(level)) *
           static_cast<std::size_t>(patch_size_);
  }
  void setAffineHessian(int slot);
  /// Relative residual (see align) over the central residual window of slot `slot`'s base
  /// template placed at centre (cx, cy) with shape A in `image`; negative when outside.
  double centreResidual(int slot, ImageView<const uint8_t> image, double cx, double cy,
                        const double (&A)[4]) const;
  /// Affine inverse-compositional iterations on the base level: (cx, cy) the template centre in
  /// the image and A its shape, updated in place.
  LkStatus alignAffine(int slot, ImageView<const uint8_t> image, double& cx, double& cy,
                       double (&A)[4], double& bias, double& residual) const;
  /// Iterates on one level; (cx, cy) is the template centre in level pixels, updated in place.
  LkStatus alignLevel(int slot, int level, ImageView<const uint8_t> image, double& cx, double& cy,
                      double& bias, double& residual, bool want_residual) const;

  LkOptions options_;
  int capacity_ = 0;
  int level_count_ = 0;
  int half_ = 0;
  int side_ = 0;
  int area_ = 0;
  int tstride_ = 0;     // template row stride: side_ rounded up to 8 (zero padding, for vectors)
  int patch_size_ = 0;  // side_ * tstride_
  int residual_radius_ = 0;
  int centre_stride_ = 0;  // row stride of the central residual window's copy (zero padding)
  int centre_size_ = 0;    // (2 r + 1) * centre_stride_, 0 when the residual is the whole window
  AlignedBuffer<int16_t> value_;   // template values << kValueBits
  AlignedBuffer<int16_t> grad_x_;  // Scharr (unnormalised, 32 x intensity per pixel)
  AlignedBuffer<int16_t> grad_y_;
  // The base template's central (2r+1)^2 window again, zero-padded to centre_stride_ so the
  // vector kernels (which rely on zero padding) compute the centre residual.
  AlignedBuffer<int16_t> centre_value_;
  AlignedBuffer<int16_t> centre_grad_x_;
  AlignedBuffer<int16_t> centre_grad_y_;
  std::vector<LevelTemplate> levels_;  // sized at construction
  struct AffineTemplate {
    bool valid = false;
    std::array<double, 49> H_inv{};  ///< inverse 7x7 Hessian over (dx, dy, d00, d01, d10, d11, b)
  };
  std::vector<AffineTemplate> affine_;    // one per slot (base level)
  mutable AlignedBuffer<int32_t> row_x_;  // the affine warp's row positions (scratch, side_)
  mutable AlignedBuffer<int32_t> row_y_;
  mutable long iterations_ = 0;
};

}  // namespace epitrack

#include "algo/flow/pyramidal_lk.hpp"

#include <algorithm>
#include <cmath>

namespace epitrack {

const char* lkStatusName(LkStatus status) {
  switch (status) {
    case LkStatus::kTracked:
      return "tracked";
    case LkStatus::kLeftImage:
      return "left-image";
    case LkStatus::kLowTexture:
      return "low-texture";
    case LkStatus::kNoConvergence:
      return "no-convergence";
    case LkStatus::kResidualTooHigh:
      return "residual-too-high";
    case LkStatus::kForwardBackward:
      return "forward-backward";
  }
  return "unknown";
}

PyramidalLk::PyramidalLk(const LkOptions& options, int capacity)
    : options_(options), capacity_(std::max(capacity, 0)) {
  options_.window = std::max(3, options_.window | 1);
  options_.levels = std::clamp(options_.levels, 0, kMaxLevels - 1);
  options_.max_iterations = std::max(1, options_.max_iterations);
  level_count_ = options_.levels + 1;
  half_ = options_.window / 2;
  side_ = options_.window;
  area_ = side_ * side_;
  const std::size_t total = static_cast<std::size_t>(capacity_) *
                            static_cast<std::size_t>(level_count_) *
                            static_cast<std::size_t>(area_);
  value_.reserve(std::max<std::size_t>(total, 1));
  grad_x_.reserve(std::max<std::size_t>(total, 1));
  grad_y_.reserve(std::max<std::size_t>(total, 1));
  levels_.assign(static_cast<std::size_t>(capacity_) * static_cast<std::size_t>(level_count_),
                 LevelTemplate{});
}

namespace {

/// Inverse of a symmetric 3x3 matrix by cofactors; false when (near) singular.
bool invertSymmetric3(const double (&m)[3][3], std::array<double, 9>& inv) {
  const double c00 = m[1][1] * m[2][2] - m[1][2] * m[2][1];
  const double c01 = m[1][2] * m[2][0] - m[1][0] * m[2][2];
  const double c02 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
  const double det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02;
  const double scale = std::abs(m[0][0] * m[1][1] * m[2][2]);
  if (!(std::abs(det) > 1e-12 * scale) || !std::isfinite(det)) return false;
  const double c11 = m[0][0] * m[2][2] - m[0][2] * m[2][0];
  const double c12 = m[0][1] * m[2][0] - m[0][0] * m[2][1];
  const double c22 = m[0][0] * m[1][1] - m[0][1] * m[1][0];
  const double id = 1.0 / det;
  inv = {c00 * id, c01 * id, c02 * id, c01 * id, c11 * id, c12 * id, c02 * id, c12 * id, c22 * id};
  return true;
}

}  // namespace

LkStatus PyramidalLk::setTemplate(int slot, const Pyramid& pyramid, float x, float y) {
  EPITRACK_ASSERT(slot >= 0 && slot < capacity_);
  const int levels = std::min(level_count_, pyramid.levelCount());
  LkStatus base_status = LkStatus::kTracked;
  for (int l = 0; l < level_count_; ++l) {
    LevelTemplate& lt = levels_[static_cast<std::size_t>(slot * level_count_ + l)];
    lt.valid = false;
    if (l >= levels) continue;
    const ImageView<const uint8_t> img = pyramid.level(l);
    const double scale = 1.0 / static_cast<double>(1 << l);
    const double px = static_cast<double>(x) * scale;
    const double py = static_cast<double>(y) * scale;
    const int cx = static_cast<int>(std::lround(px));
    const int cy = static_cast<int>(std::lround(py));
    // The window plus one pixel for the Scharr stencil must lie inside the level.
    if (cx - half_ - 1 < 0 || cy - half_ - 1 < 0 || cx + half_ + 1 >= img.width ||
        cy + half_ + 1 >= img.height) {
      if (l == 0) base_status = LkStatus::kLeftImage;
      continue;
    }
    const std::size_t base = patchIndex(slot, l);
    int16_t* T = value_.data() + base;
    int16_t* Sx = grad_x_.data() + base;
    int16_t* Sy = grad_y_.data() + base;
    double sxx = 0.0, sxy = 0.0, syy = 0.0, sx = 0.0, sy = 0.0;
    for (int v = 0; v < side_; ++v) {
      const int yy = cy - half_ + v;
      const uint8_t* r0 = img.row(yy - 1);
      const uint8_t* r1 = img.row(yy);
      const uint8_t* r2 = img.row(yy + 1);
      for (int u = 0; u < side_; ++u) {
        const int xx = cx - half_ + u;
        // Scharr 2000 kernel, unnormalised (32 x the intensity gradient).
        const int gx = 3 * (r0[xx + 1] - r0[xx - 1]) + 10 * (r1[xx + 1] - r1[xx - 1]) +
                       3 * (r2[xx + 1] - r2[xx - 1]);
        const int gy =
            3 * (r2[xx - 1] - r0[xx - 1]) + 10 * (r2[xx] - r0[xx]) + 3 * (r2[xx + 1] - r0[xx + 1]);
        const int i = v * side_ + u;
        T[i] = static_cast<int16_t>(r1[xx] << kValueBits);
        Sx[i] = static_cast<int16_t>(gx);
        Sy[i] = static_cast<int16_t>(gy);
        sxx += gx * gx;
        sxy += gx * gy;
        syy += gy * gy;
        sx += gx;
        sy += gy;
      }
    }
    // Gauss-Newton Hessian of the residual e = I(W(x; p)) - T(x) - b over [dx, dy, b], with the
    // Jacobian row [Sx, Sy, 32] in the units of e (1/32 gray levels); Baker & Matthews 2004 eq. 36.
    const double n = static_cast<double>(area_);
    const double one = static_cast<double>(1 << kValueBits);
    const double H[3][3] = {
        {sxx, sxy, one * sx}, {sxy, syy, one * sy}, {one * sx, one * sy, one * one * n}};
    // Texture test on the bias-free translation block (Schur complement), in (gray/px)^2 per pixel.
    const double a = (sxx - sx * sx / n) / (n * 1024.0);
    const double b = (sxy - sx * sy / n) / (n * 1024.0);
    const double c = (syy - sy * sy / n) / (n * 1024.0);
    const double min_eig = 0.5 * ((a + c) - std::sqrt((a - c) * (a - c) + 4.0 * b * b));
    if (min_eig < options_.min_eigen || !invertSymmetric3(H, lt.H_inv)) {
      if (l == 0) base_status = LkStatus::kLowTexture;
      continue;
    }
    lt.offset_x = px - cx;
    lt.offset_y = py - cy;
    lt.valid = true;
  }
  return base_status;
}

LkStatus PyramidalLk::alignLevel(int slot, int level, ImageView<const uint8_t> image, double& cx,
                                 double& cy, double& residual, bool want_residual) const {
  const LevelTemplate& lt = levels_[static_cast<std::size_t>(slot * level_count_ + level)];
  const std::size_t base = patchIndex(slot, level);
  const int16_t* T = value_.data() + base;
  const int16_t* Sx = grad_x_.data() + base;
  const int16_t* Sy = grad_y_.data() + base;
  const auto& Hi = lt.H_inv;
  const double eps2 = options_.epsilon * options_.epsilon;
  constexpr int kOne = 1 << kWeightBits;
  constexpr int kShift = kWeightBits - kValueBits;
  constexpr int kRound = 1 << (kShift - 1);
  int32_t bias_fixed = 0;  // previous bias estimate in 1/32 gray levels (for the residual)
  double last_step2 = 0.0;
  for (int it = 0; it < options_.max_iterations; ++it) {
    const double fx_floor = std::floor(cx);
    const double fy_floor = std::floor(cy);
    const int ix = static_cast<int>(fx_floor);
    const int iy = static_cast<int>(fy_floor);
    if (ix - half_ < 0 || iy - half_ < 0 || ix + half_ + 1 >= image.width ||
        iy + half_ + 1 >= image.height) {
      return LkStatus::kLeftImage;
    }
    ++iterations_;
    const int ax = static_cast<int>(std::lround((cx - fx_floor) * kOne));
    const int ay = static_cast<int>(std::lround((cy - fy_floor) * kOne));
    const int32_t w00 = ((kOne - ax) * (kOne - ay) + (kOne >> 1)) >> kWeightBits;
    const int32_t w01 = (ax * (kOne - ay) + (kOne >> 1)) >> kWeightBits;
    const int32_t w10 = ((kOne - ax) * ay + (kOne >> 1)) >> kWeightBits;
    const int32_t w11 = kOne - w00 - w01 - w10;  // the four sum exactly to 1 << kWeightBits
    int64_t gx_e = 0, gy_e = 0, sum_e = 0, sum_abs = 0;
    for (int v = 0; v < side_; ++v) {
      const uint8_t* r0 = image.row(iy - half_ + v) + (ix - half_);
      const uint8_t* r1 = r0 + image.stride;
      const int16_t* t = T + v * side_;
      const int16_t* sx = Sx + v * side_;
      const int16_t* sy = Sy + v * side_;
      // Per row in int32: |Sx| <= 4080, |e| <= 8160, 21 terms < 7e8 < 2^31.
      int32_t row_gx = 0, row_gy = 0, row_e = 0, row_abs = 0;
      for (int u = 0; u < side_; ++u) {
        const int32_t sample =
            (w00 * r0[u] + w01 * r0[u + 1] + w10 * r1[u] + w11 * r1[u + 1] + kRound) >> kShift;
        const int32_t e = sample - t[u];
        row_gx += sx[u] * e;
        row_gy += sy[u] * e;
        row_e += e;
        const int32_t eb = e - bias_fixed;
        row_abs += eb < 0 ? -eb : eb;
      }
      gx_e += row_gx;
      gy_e += row_gy;
      sum_e += row_e;
      sum_abs += row_abs;
    }
    const double g0 = static_cast<double>(gx_e);
    const double g1 = static_cast<double>(gy_e);
    const double g2 = static_cast<double>(sum_e) * (1 << kValueBits);
    const double dx = Hi[0] * g0 + Hi[1] * g1 + Hi[2] * g2;
    const double dy = Hi[3] * g0 + Hi[4] * g1 + Hi[5] * g2;
    const double bias = Hi[6] * g0 + Hi[7] * g1 + Hi[8] * g2;  // gray levels
    if (want_residual) {
      residual = static_cast<double>(sum_abs) / (static_cast<double>(area_) * (1 << kValueBits));
    }
    if (!std::isfinite(dx) || !std::isfinite(dy) || std::abs(dx) > half_ || std::abs(dy) > half_) {
      return LkStatus::kNoConvergence;
    }
    bias_fixed =
        static_cast<int32_t>(std::lround(std::clamp(bias, -255.0, 255.0) * (1 << kValueBits)));
    // Inverse compositional update of a translation: W(x; p) <- W(x; p) o W(x; dp)^-1.
    cx -= dx;
    cy -= dy;
    last_step2 = dx * dx + dy * dy;
    if (last_step2 < eps2) return LkStatus::kTracked;
  }
  // Bouguet's tracker accepts the last estimate after max_iterations; we accept it only when the
  // last step was already small (an oscillation of a tenth of a pixel at most).
  return last_step2 < 0.01 ? LkStatus::kTracked : LkStatus::kNoConvergence;
}

LkStatus PyramidalLk::align(int slot, const Pyramid& pyramid, float& x, float& y,
                            float& residual) const {
  EPITRACK_ASSERT(slot >= 0 && slot < capacity_);
  const int levels = std::min(level_count_, pyramid.levelCount());
  double px = x;
  double py = y;
  double res = 0.0;
  for (int l = levels - 1; l >= 0; --l) {
    const LevelTemplate& lt = levels_[static_cast<std::size_t>(slot * level_count_ + l)];
    if (!lt.valid) {
      if (l == 0) return LkStatus::kLowTexture;
      continue;
    }
    const double scale = static_cast<double>(1 << l);
    double cx = px / scale - lt.offset_x;
    double cy = py / scale - lt.offset_y;
    const LkStatus s = alignLevel(slot, l, pyramid.level(l), cx, cy, res, l == 0);
    if (s != LkStatus::kTracked) {
      if (l == 0) return s;
      continue;  // a coarse level that fails leaves the guess to the finer levels
    }
    px = (cx + lt.offset_x) * scale;
    py = (cy + lt.offset_y) * scale;
  }
  x = static_cast<float>(px);
  y = static_cast<float>(py);
  residual = static_cast<float>(res);
  return res > options_.max_residual ? LkStatus::kResidualTooHigh : LkStatus::kTracked;
}

}  // namespace epitrack

#include "algo/flow/pyramidal_lk.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "algo/flow/simd_int16.hpp"

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
  tstride_ = (side_ + 7) / 8 * 8;
  patch_size_ = side_ * tstride_;
  residual_radius_ = options_.residual_radius < 0 ? side_ / 4 : options_.residual_radius;
  if (residual_radius_ == 0 || residual_radius_ > half_) residual_radius_ = half_;
  if (residual_radius_ < half_) {
    centre_stride_ = (2 * residual_radius_ + 1 + 7) / 8 * 8;
    centre_size_ = (2 * residual_radius_ + 1) * centre_stride_;
    const std::size_t centre_total =
        std::max<std::size_t>(static_cast<std::size_t>(capacity_) * centre_size_, 1);
    centre_value_.reserve(centre_total);
    centre_grad_x_.reserve(centre_total);
    centre_grad_y_.reserve(centre_total);
  }
  const std::size_t total = static_cast<std::size_t>(capacity_) *
                            static_cast<std::size_t>(level_count_) *
                            static_cast<std::size_t>(patch_size_);
  value_.reserve(std::max<std::size_t>(total, 1));
  grad_x_.reserve(std::max<std::size_t>(total, 1));
  grad_y_.reserve(std::max<std::size_t>(total, 1));
  levels_.assign(static_cast<std::size_t>(capacity_) * static_cast<std::size_t>(level_count_),
                 LevelTemplate{});
  affine_.assign(static_cast<std::size_t>(capacity_), AffineTemplate{});
  row_x_.reserve(static_cast<std::size_t>(side_));
  row_y_.reserve(static_cast<std::size_t>(side_));
}

namespace {

/// Root mean square of the error after removing its mean (the intensity offset), in gray levels,
/// from the window sums of e and e^2 (e in 1/32 gray levels).
double rmsAfterBias(int64_t sum_e, int64_t sum_sq, int area) {
  const double n = area;
  const double mean = static_cast<double>(sum_e) / n;
  const double var = static_cast<double>(sum_sq) / n - mean * mean;
  return std::sqrt(std::max(var, 0.0)) / static_cast<double>(1 << PyramidalLk::kValueBits);
}

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

/// std::lround for |value| < 2^31 (half away from zero) without the library call or a branch: the
/// difference of a double and its truncation is exact.
inline int32_t roundHalfAway(double value) {
  const auto i = static_cast<int32_t>(value);
  const double f = value - static_cast<double>(i);
  return i + static_cast<int32_t>(f >= 0.5) - static_cast<int32_t>(f <= -0.5);
}

/// The 16.16 positions of a side x side window (half = side / 2) with centre (cx, cy) and shape A
/// (template to image) for the affine kernels: each row's first pixel rounded from the warp, the
/// step per column rounded once (Bouguet-style fixed point, as the scalar loop before the vector
/// kernels). False when the window leaves the image: its corners with their bilinear neighbours in
/// floating point, then, exactly, every row's first and last pixel.
bool rowWarp(double cx, double cy, const double (&A)[4], int half, int side, int width, int height,
             int32_t* row_x, int32_t* row_y, LkAffineWarp& warp) {
  constexpr double kPosOne = static_cast<double>(1 << kLkPosBits);
  const double h = half;
  double min_x = 1e30, max_x = -1e30, min_y = 1e30, max_y = -1e30;
  for (const double su : {-h, h}) {
    for (const double sv : {-h, h}) {
      const double wx = cx + A[0] * su + A[1] * sv;
      const double wy = cy + A[2] * su + A[3] * sv;
      min_x = std::min(min_x, wx);
      max_x = std::max(max_x, wx);
      min_y = std::min(min_y, wy);
      max_y = std::max(max_y, wy);
    }
  }
  if (!(min_x >= 0.0 && min_y >= 0.0 && max_x < width - 1 && max_y < height - 1)) return false;
  warp.xu = roundHalfAway(A[0] * kPosOne);
  warp.yu = roundHalfAway(A[2] * kPosOne);
  const int32_t x_limit = (width - 1) << kLkPosBits;  // X >> 16 <= width - 2
  const int32_t y_limit = (height - 1) << kLkPosBits;
  for (int v = 0; v < side; ++v) {
    const double dv = v - h;
    row_x[v] = roundHalfAway((cx - A[0] * h + A[1] * dv) * kPosOne);
    row_y[v] = roundHalfAway((cy - A[2] * h + A[3] * dv) * kPosOne);
  }
  const int32_t du = (side - 1) * warp.xu;
  const int32_t eu = (side - 1) * warp.yu;
  int32_t x_lo = row_x[0], x_hi = row_x[0], y_lo = row_y[0], y_hi = row_y[0];
  for (int v = 0; v < side; ++v) {
    x_lo = std::min({x_lo, row_x[v], row_x[v] + du});
    x_hi = std::max({x_hi, row_x[v], row_x[v] + du});
    y_lo = std::min({y_lo, row_y[v], row_y[v] + eu});
    y_hi = std::max({y_hi, row_y[v], row_y[v] + eu});
  }
  if (x_lo < 0 || y_lo < 0 || x_hi >= x_limit || y_hi >= y_limit) return false;
  warp.row_x = row_x;
  warp.row_y = row_y;
  return true;
}

/// Window sums of a template level (exact integers): gradient products and sums, intensities.
struct TemplateSums {
  int64_t gxx = 0, gxy = 0, gyy = 0, gx = 0, gy = 0, t = 0, tt = 0;
};

/// One template row: `src` the image pixel above-left of the row's first pixel (rows of
/// `stride`, side + 2 columns and 3 rows are read), out the values (<< kLkValueBits), the Scharr
/// gradients (Scharr 2000, unnormalised: 32 x the intensity gradient) and zeros up to `tstride`.
/// `vector`: SSE2 / NEON where available (the same values).
void templateRow(const uint8_t* src, std::ptrdiff_t stride, int side, int tstride, int16_t* T,
                 int16_t* Sx, int16_t* Sy, TemplateSums& sums, bool vector) {
  const uint8_t* r0 = src;
  const uint8_t* r1 = src + stride;
  const uint8_t* r2 = src + 2 * stride;
  int u = 0;
#if EPITRACK_LK_SIMD
  if (vector) {
    using namespace simd;
    // Pairs of columns per int32 lane: products <= 2 * 4080^2 < 2^25, 3 groups of 8 at most
    // before the row's sums go to int64 (each sum below 2^27).
    const I16x8 three = set16(3), ten = set16(10), ones = set16(1);
    I32x4 gxx = zero32(), gxy = zero32(), gyy = zero32(), gx = zero32(), gy = zero32();
    I32x4 t = zero32(), tt = zero32();
    for (; u + 8 <= side; u += 8) {
      // Columns u - 1 .. u + 8 of the three rows (src is one column left of the row).
      const I16x8 ul = loadWidenU8(r0 + u), uc = loadWidenU8(r0 + u + 1),
                  ur = loadWidenU8(r0 + u + 2);
      const I16x8 ml = loadWidenU8(r1 + u), mc = loadWidenU8(r1 + u + 1),
                  mr = loadWidenU8(r1 + u + 2);
      const I16x8 dl = loadWidenU8(r2 + u), dc = loadWidenU8(r2 + u + 1),
                  dr = loadWidenU8(r2 + u + 2);
      const I16x8 ggx =
          add16(mul16(sub16(add16(ur, dr), add16(ul, dl)), three), mul16(sub16(mr, ml), ten));
      const I16x8 ggy =
          add16(mul16(add16(sub16(dl, ul), sub16(dr, ur)), three), mul16(sub16(dc, uc), ten));
      storeI16(T + u, sll16<kLkValueBits>(mc));
      storeI16(Sx + u, ggx);
      storeI16(Sy + u, ggy);
      gxx = add32(gxx, madd(ggx, ggx));
      gxy = add32(gxy, madd(ggx, ggy));
      gyy = add32(gyy, madd(ggy, ggy));
      gx = add32(gx, madd(ggx, ones));
      gy = add32(gy, madd(ggy, ones));
      t = add32(t, madd(mc, ones));
      tt = add32(tt, madd(mc, mc));
      if (u % 24 == 16) {  // after 3 groups
        sums.gxx += sum32(gxx);
        sums.gxy += sum32(gxy);
        sums.gyy += sum32(gyy);
        gxx = gxy = gyy = zero32();
      }
    }
    sums.gxx += sum32(gxx);
    sums.gxy += sum32(gxy);
    sums.gyy += sum32(gyy);
    sums.gx += sum32(gx);
    sums.gy += sum32(gy);
    sums.t += sum32(t);
    sums.tt += sum32(tt);
  }
#else
  static_cast<void>(vector);
#endif
  for (; u < side; ++u) {
    const int xx = u + 1;
    const int gx = 3 * (r0[xx + 1] - r0[xx - 1]) + 10 * (r1[xx + 1] - r1[xx - 1]) +
                   3 * (r2[xx + 1] - r2[xx - 1]);
    const int gy =
        3 * (r2[xx - 1] - r0[xx - 1]) + 10 * (r2[xx] - r0[xx]) + 3 * (r2[xx + 1] - r0[xx + 1]);
    T[u] = static_cast<int16_t>(r1[xx] << kLkValueBits);
    Sx[u] = static_cast<int16_t>(gx);
    Sy[u] = static_cast<int16_t>(gy);
    sums.gxx += gx * gx;
    sums.gxy += gx * gy;
    sums.gyy += gy * gy;
    sums.gx += gx;
    sums.gy += gy;
    sums.t += r1[xx];
    sums.tt += r1[xx] * r1[xx];
  }
  for (; u < tstride; ++u) {  // the vector kernels' zero padding
    T[u] = 0;
    Sx[u] = 0;
    Sy[u] = 0;
  }
}

}  // namespace

void PyramidalLk::setAffineHessian(int slot) {
  AffineTemplate& at = affine_[static_cast<std::size_t>(slot)];
  at.valid = false;
  if (!options_.affine) return;
  const std::size_t base = patchIndex(slot, 0);
  const int16_t* Sx = grad_x_.data() + base;
  const int16_t* Sy = grad_y_.data() + base;
  // Gauss-Newton Hessian sum J J^T over the window, J = [gx, gy, u gx, v gx, u gy, v gy, 32]
  // (u, v from the centre; Baker & Matthews 2004 §3.2), from exact integer moments: per row the
  // sums of q = gx^2, gx gy, gy^2 with weights 1, u, u^2 (and of gx, gy with 1, u), then over the
  // rows with weights 1, v, v^2. Every entry is an integer below 2^53, so the doubles are exact.
  int64_t m[3][6] = {};   // q; weights 1, u, v, u^2, u v, v^2
  int64_t s1[2][3] = {};  // gx, gy; weights 1, u, v
  for (int v = 0; v < side_; ++v) {
    int64_t r[3][3] = {};
    int64_t rg[2][2] = {};
    const int16_t* sx = Sx + v * tstride_;
    const int16_t* sy = Sy + v * tstride_;
    for (int u = 0; u < side_; ++u) {
      const int64_t du = u - half_;
      const int32_t gx = sx[u];
      const int32_t gy = sy[u];
      const int64_t q[3] = {gx * gx, gx * gy, gy * gy};  // < 2^24 each
      for (int i = 0; i < 3; ++i) {
        r[i][0] += q[i];
        r[i][1] += du * q[i];
        r[i][2] += du * du * q[i];
      }
      rg[0][0] += gx;
      rg[0][1] += du * gx;
      rg[1][0] += gy;
      rg[1][1] += du * gy;
    }
    const int64_t dv = v - half_;
    for (int i = 0; i < 3; ++i) {
      m[i][0] += r[i][0];
      m[i][1] += r[i][1];
      m[i][2] += dv * r[i][0];
      m[i][3] += r[i][2];
      m[i][4] += dv * r[i][1];
      m[i][5] += dv * dv * r[i][0];
    }
    for (int k = 0; k < 2; ++k) {
      s1[k][0] += rg[k][0];
      s1[k][1] += rg[k][1];
      s1[k][2] += dv * rg[k][0];
    }
  }
  enum { kXX, kXY, kYY };
  enum { k1, kU, kV, kUU, kUV, kVV };
  const auto f = [](int64_t x) { return static_cast<double>(x); };
  const double c = 1 << kValueBits;  // the bias column of J
  Eigen::Matrix<double, 7, 7> H;
  // Lower triangle, row by row; column 6 (the bias) last.
  H(0, 0) = f(m[kXX][k1]);
  H(1, 0) = f(m[kXY][k1]);
  H(1, 1) = f(m[kYY][k1]);
  H(2, 0) = f(m[kXX][kU]);
  H(2, 1) = f(m[kXY][kU]);
  H(2, 2) = f(m[kXX][kUU]);
  H(3, 0) = f(m[kXX][kV]);
  H(3, 1) = f(m[kXY][kV]);
  H(3, 2) = f(m[kXX][kUV]);
  H(3, 3) = f(m[kXX][kVV]);
  H(4, 0) = f(m[kXY][kU]);
  H(4, 1) = f(m[kYY][kU]);
  H(4, 2) = f(m[kXY][kUU]);
  H(4, 3) = f(m[kXY][kUV]);
  H(4, 4) = f(m[kYY][kUU]);
  H(5, 0) = f(m[kXY][kV]);
  H(5, 1) = f(m[kYY][kV]);
  H(5, 2) = f(m[kXY][kUV]);
  H(5, 3) = f(m[kXY][kVV]);
  H(5, 4) = f(m[kYY][kUV]);
  H(5, 5) = f(m[kYY][kVV]);
  H(6, 0) = c * f(s1[0][k1]);
  H(6, 1) = c * f(s1[1][k1]);
  H(6, 2) = c * f(s1[0][kU]);
  H(6, 3) = c * f(s1[0][kV]);
  H(6, 4) = c * f(s1[1][kU]);
  H(6, 5) = c * f(s1[1][kV]);
  H(6, 6) = c * c * static_cast<double>(area_);
  H.triangularView<Eigen::StrictlyUpper>() = H.transpose();
  // Damping of the four shape parameters (Tikhonov, towards no change): at a corner whose edges
  // pass through the centre, stretching along an edge is unobservable and an undamped step in
  // that direction diverges. kShapeDamping of the curvature a fully textured window would have.
  constexpr double kShapeDamping = 3.0;
  const double lambda = kShapeDamping * 0.5 * (H(0, 0) + H(1, 1)) * (half_ * half_) / 3.0;
  for (int i = 2; i < 6; ++i) H(i, i) += lambda;
  const Eigen::LDLT<Eigen::Matrix<double, 7, 7>> ldlt(H);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return;
  const Eigen::Matrix<double, 7, 7> Hi = ldlt.solve(Eigen::Matrix<double, 7, 7>::Identity());
  if (!Hi.allFinite()) return;
  // Conditioning: a tiny pivot relative to the largest means an unobservable affine direction
  // (an edge rather than a corner); such templates are tracked by translation only.
  const auto d = ldlt.vectorD();
  if (d.minCoeff() <= 1e-9 * d.maxCoeff()) return;
  for (int i = 0; i < 49; ++i) at.H_inv[static_cast<std::size_t>(i)] = Hi(i % 7, i / 7);
  at.valid = true;
}

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
    int cx = static_cast<int>(std::lround(px));
    int cy = static_cast<int>(std::lround(py));
    if (l > 0) {
      // Near the border a coarse level takes its template where the window fits, up to half a
      // window inward: the patch still overlaps the feature, its offset is remembered, and a
      // translation of the patch is the feature's (the coarse levels only seed the finer ones).
      // Without this, features near the border would have no coarse levels: no large motion.
      cx = std::clamp(cx, std::min(half_ + 1, cx + half_),
                      std::max(img.width - half_ - 2, cx - half_));
      cy = std::clamp(cy, std::min(half_ + 1, cy + half_),
                      std::max(img.height - half_ - 2, cy - half_));
    }
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
    TemplateSums sums;
    for (int v = 0; v < side_; ++v) {
      const int yy = cy - half_ + v;
      const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(tstride_);
      templateRow(img.row(yy - 1) + (cx - half_ - 1), img.stride, side_, tstride_, T + i, Sx + i,
                  Sy + i, sums, options_.vector_kernels);
    }
    const double sxx = static_cast<double>(sums.gxx), sxy = static_cast<double>(sums.gxy);
    const double syy = static_cast<double>(sums.gyy), sx = static_cast<double>(sums.gx);
    const double sy = static_cast<double>(sums.gy), st = static_cast<double>(sums.t);
    const double stt = static_cast<double>(sums.tt);
    // Gauss-Newton Hessian of the residual e = I(W(x; p)) - T(x) - b over [dx, dy, b], with the
    // Jacobian row [Sx, Sy, 32] in the units of e (1/32 gray levels); Baker & Matthews 2004 eq. 36.
    const double n = static_cast<double>(area_);
    // Contrast of the template (its intensity standard deviation): residuals are reported
    // relative to it, so one threshold serves faint and strong corners (gain normalisation).
    lt.contrast = std::sqrt(std::max(stt / n - (st / n) * (st / n), 1.0));
    if (l == 0) {
      // The same over the residual's central window (the whole window: the sums above).
      const int r = residual_radius_;
      int64_t ict = sums.t, ictt = sums.tt;
      if (r < half_) {
        ict = 0;
        ictt = 0;
        const std::size_t centre = static_cast<std::size_t>(slot) * centre_size_;
        for (int v = half_ - r; v <= half_ + r; ++v) {
          const std::size_t row =
              centre + static_cast<std::size_t>(v - (half_ - r)) * centre_stride_;
          for (int u = half_ - r; u <= half_ + r; ++u) {
            const int value = T[v * tstride_ + u] >> kValueBits;
            ict += value;
            ictt += value * value;
          }
          // The row again, zero-padded to centre_stride_ (the vector kernels need the padding).
          const std::size_t from = static_cast<std::size_t>(v * tstride_ + (half_ - r));
          const int cols = 2 * r + 1;
          const std::pair<const int16_t*, int16_t*> copies[] = {
              {T, centre_value_.data()}, {Sx, centre_grad_x_.data()}, {Sy, centre_grad_y_.data()}};
          for (const auto& [src, dst] : copies) {
            std::copy_n(src + from, cols, dst + row);
            std::fill(dst + row + cols, dst + row + centre_stride_, 0);
          }
        }
      }
      const double ct = static_cast<double>(ict), ctt = static_cast<double>(ictt);
      const double m = static_cast<double>((2 * r + 1) * (2 * r + 1));
      lt.centre_contrast = std::sqrt(std::max(ctt / m - (ct / m) * (ct / m), 1.0));
    }
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
    if (l == 0) setAffineHessian(slot);
  }
  return base_status;
}

void PyramidalLk::copyTemplate(int from, int to) {
  EPITRACK_ASSERT(from >= 0 && from < capacity_ && to >= 0 && to < capacity_);
  if (from == to) return;
  const std::size_t n =
      static_cast<std::size_t>(level_count_) * static_cast<std::size_t>(patch_size_);
  std::copy_n(value_.data() + patchIndex(from, 0), n, value_.data() + patchIndex(to, 0));
  std::copy_n(grad_x_.data() + patchIndex(from, 0), n, grad_x_.data() + patchIndex(to, 0));
  std::copy_n(grad_y_.data() + patchIndex(from, 0), n, grad_y_.data() + patchIndex(to, 0));
  if (centre_size_ > 0) {
    const std::size_t c = static_cast<std::size_t>(centre_size_);
    std::copy_n(centre_value_.data() + from * c, c, centre_value_.data() + to * c);
    std::copy_n(centre_grad_x_.data() + from * c, c, centre_grad_x_.data() + to * c);
    std::copy_n(centre_grad_y_.data() + from * c, c, centre_grad_y_.data() + to * c);
  }
  for (int l = 0; l < level_count_; ++l) {
    levels_[static_cast<std::size_t>(to * level_count_ + l)] =
        levels_[static_cast<std::size_t>(from * level_count_ + l)];
  }
  affine_[static_cast<std::size_t>(to)] = affine_[static_cast<std::size_t>(from)];
}

LkStatus PyramidalLk::alignLevel(int slot, int level, ImageView<const uint8_t> image, double& cx,
                                 double& cy, double& bias_io, double& residual,
                                 bool want_residual) const {
  const LevelTemplate& lt = levels_[static_cast<std::size_t>(slot * level_count_ + level)];
  const std::size_t base = patchIndex(slot, level);
  const int16_t* T = value_.data() + base;
  const int16_t* Sx = grad_x_.data() + base;
  const int16_t* Sy = grad_y_.data() + base;
  const auto& Hi = lt.H_inv;
  // Coarse levels only need to land in the finer level's basin: a 4x looser bound.
  const double eps = level > 0 ? 4.0 * options_.epsilon : options_.epsilon;
  const double eps2 = eps * eps;
  constexpr int kOne = 1 << kWeightBits;
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
    const auto ax = static_cast<int32_t>(std::lround((cx - fx_floor) * kOne));
    const auto ay = static_cast<int32_t>(std::lround((cy - fy_floor) * kOne));
    const LkBilinear w = lkBilinear(ax, ay);
    const uint8_t* window = image.row(iy - half_) + (ix - half_);
    LkWindowSums sums;
    if (options_.vector_kernels) {
      lkTranslationSumsVector(window, image.stride, side_, w, T, Sx, Sy, tstride_, sums);
    } else {
      lkTranslationSumsScalar(window, image.stride, side_, w, T, Sx, Sy, tstride_, sums);
    }
    const int64_t gx_e = sums.gx_e;
    const int64_t gy_e = sums.gy_e;
    const int64_t sum_e = sums.sum_e;
    const int64_t sum_sq = sums.sum_sq;
    const double g0 = static_cast<double>(gx_e);
    const double g1 = static_cast<double>(gy_e);
    const double g2 = static_cast<double>(sum_e) * (1 << kValueBits);
    const double dx = Hi[0] * g0 + Hi[1] * g1 + Hi[2] * g2;
    const double dy = Hi[3] * g0 + Hi[4] * g1 + Hi[5] * g2;
    const double bias = Hi[6] * g0 + Hi[7] * g1 + Hi[8] * g2;  // gray levels
    if (want_residual) residual = rmsAfterBias(sum_e, sum_sq, area_);
    if (!std::isfinite(dx) || !std::isfinite(dy) || std::abs(dx) > half_ || std::abs(dy) > half_) {
      return LkStatus::kNoConvergence;
    }
    bias_io = bias;
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

LkStatus PyramidalLk::alignAffine(int slot, ImageView<const uint8_t> image, double& cx, double& cy,
                                  double (&A)[4], double& bias, double& residual) const {
  const AffineTemplate& at = affine_[static_cast<std::size_t>(slot)];
  const std::size_t base = patchIndex(slot, 0);
  const int16_t* T = value_.data() + base;
  const int16_t* Sx = grad_x_.data() + base;
  const int16_t* Sy = grad_y_.data() + base;
  const auto& Hi = at.H_inv;
  const double eps2 = options_.epsilon * options_.epsilon;
  const double h = half_;
  double last_step2 = 0.0;
  for (int it = 0; it < options_.max_iterations; ++it) {
    // The warped window must stay inside the image (with the bilinear neighbours).
    LkAffineWarp warp;
    if (!rowWarp(cx, cy, A, half_, side_, image.width, image.height, row_x_.data(), row_y_.data(),
                 warp)) {
      return LkStatus::kLeftImage;
    }
    ++iterations_;
    LkAffineSums sums;
    if (options_.vector_kernels) {
      lkAffineSumsVector(image, warp, side_, T, Sx, Sy, tstride_, sums);
    } else {
      lkAffineSumsScalar(image, warp, side_, T, Sx, Sy, tstride_, sums);
    }
    const int64_t s_gx = sums.gx_e, s_gy = sums.gy_e, s_ugx = sums.ugx_e, s_vgx = sums.vgx_e;
    const int64_t s_ugy = sums.ugy_e, s_vgy = sums.vgy_e, s_e = sums.sum_e, s_sq = sums.sum_sq;
    const double g[7] = {static_cast<double>(s_gx),
                         static_cast<double>(s_gy),
                         static_cast<double>(s_ugx),
                         static_cast<double>(s_vgx),
                         static_cast<double>(s_ugy),
                         static_cast<double>(s_vgy),
                         static_cast<double>(s_e) * (1 << kValueBits)};
    double delta[7];
    for (int r = 0; r < 7; ++r) {
      double acc = 0.0;
      for (int c = 0; c < 7; ++c) acc += Hi[static_cast<std::size_t>(r * 7 + c)] * g[c];
      delta[r] = acc;
    }
    residual = rmsAfterBias(s_e, s_sq, area_);
    bool finite = true;
    for (const double d : delta) finite = finite && std::isfinite(d);
    if (!finite || std::abs(delta[0]) > h || std::abs(delta[1]) > h)
      return LkStatus::kNoConvergence;
    bias = delta[6];
    // Inverse composition (Baker & Matthews 2004 eq. 10): W <- W o W(delta)^-1 with
    // W(k; delta) = (I + D) k + d, so A <- A (I + D)^-1 and t <- t - A (I + D)^-1 d.
    const double m00 = 1.0 + delta[2], m01 = delta[3], m10 = delta[4], m11 = 1.0 + delta[5];
    const double det = m00 * m11 - m01 * m10;
    if (!(std::abs(det) > 1e-6)) return LkStatus::kNoConvergence;
    const double i00 = m11 / det, i01 = -m01 / det, i10 = -m10 / det, i11 = m00 / det;
    const double n00 = A[0] * i00 + A[1] * i10;
    const double n01 = A[0] * i01 + A[1] * i11;
    const double n10 = A[2] * i00 + A[3] * i10;
    const double n11 = A[2] * i01 + A[3] * i11;
    const double step_cx = n00 * delta[0] + n01 * delta[1];
    const double step_cy = n10 * delta[0] + n11 * delta[1];
    cx -= step_cx;
    cy -= step_cy;
    A[0] = n00;
    A[1] = n01;
    A[2] = n10;
    A[3] = n11;
    // Shape change in pixels at the window's edge; it converges more slowly than the position
    // (damped, and poorly observed at corners) and matters less, so it gets a 10x looser bound.
    const double shape_step =
        h * (std::abs(delta[2]) + std::abs(delta[3]) + std::abs(delta[4]) + std::abs(delta[5]));
    last_step2 = step_cx * step_cx + step_cy * step_cy;
    if (last_step2 < eps2 && shape_step < 10.0 * options_.epsilon) break;
  }
  const double a_det = A[0] * A[3] - A[1] * A[2];
  if (!(a_det > 0.25 && a_det < 4.0)) return LkStatus::kNoConvergence;
  return last_step2 < 0.01 ? LkStatus::kTracked : LkStatus::kNoConvergence;
}

double PyramidalLk::centreResidual(int slot, ImageView<const uint8_t> image, double cx, double cy,
                                   const double (&A)[4]) const {
  const int r = residual_radius_;
  LkAffineWarp warp;
  if (!rowWarp(cx, cy, A, r, 2 * r + 1, image.width, image.height, row_x_.data(), row_y_.data(),
               warp)) {
    return -1.0;
  }
  // The central (2r+1)^2 pixels of the base template (their zero-padded copy), sampled as
  // alignAffine does; every kernel variant gives the same sums.
  const std::size_t offset = static_cast<std::size_t>(slot) * centre_size_;
  LkAffineSums sums;
  if (options_.vector_kernels) {
    lkAffineSumsVector(image, warp, 2 * r + 1, centre_value_.data() + offset,
                       centre_grad_x_.data() + offset, centre_grad_y_.data() + offset,
                       centre_stride_, sums);
  } else {
    lkAffineSumsScalar(image, warp, 2 * r + 1, centre_value_.data() + offset,
                       centre_grad_x_.data() + offset, centre_grad_y_.data() + offset,
                       centre_stride_, sums);
  }
  const double rms = rmsAfterBias(sums.sum_e, sums.sum_sq, (2 * r + 1) * (2 * r + 1));
  return rms / levels_[static_cast<std::size_t>(slot * level_count_)].centre_contrast;
}

LkStatus PyramidalLk::align(int slot, const Pyramid& pyramid, float& x, float& y, PatchShape& shape,
                            float& residual, int start_level) const {
  EPITRACK_ASSERT(slot >= 0 && slot < capacity_);
  const int levels = std::min(level_count_, pyramid.levelCount());
  double px = x;
  double py = y;
  double res = 0.0;       // RMS error after the bias of the last level's window (gray levels)
  double relative = 0.0;  // the base level's residual, relative (see residual_radius)
  double A[4] = {shape.a00, shape.a01, shape.a10, shape.a11};
  double bias = 0.0;  // intensity offset, carried from coarse to fine
  for (int l = std::min(levels - 1, std::max(start_level, 0)); l >= 0; --l) {
    const LevelTemplate& lt = levels_[static_cast<std::size_t>(slot * level_count_ + l)];
    if (!lt.valid) {
      if (l == 0) return LkStatus::kLowTexture;
      continue;
    }
    const double scale = static_cast<double>(1 << l);
    // Feature = template centre + A * offset (the offset is in template coordinates).
    const double ox = A[0] * lt.offset_x + A[1] * lt.offset_y;
    const double oy = A[2] * lt.offset_x + A[3] * lt.offset_y;
    double cx = px / scale - ox;
    double cy = py / scale - oy;
    LkStatus s = LkStatus::kTracked;
    if (l == 0 && affine_[static_cast<std::size_t>(slot)].valid) {
      s = alignAffine(slot, pyramid.level(0), cx, cy, A, bias, res);
      if (s != LkStatus::kTracked) {
        // The shape estimate diverged (an unobservable direction): fall back to translation
        // with the template's identity shape from the same start.
        A[0] = 1.0;
        A[1] = 0.0;
        A[2] = 0.0;
        A[3] = 1.0;
        cx = px - lt.offset_x;
        cy = py - lt.offset_y;
        s = alignLevel(slot, 0, pyramid.level(0), cx, cy, bias, res, true);
      }
    } else {
      s = alignLevel(slot, l, pyramid.level(l), cx, cy, bias, res, l == 0);
    }
    if (s != LkStatus::kTracked) {
      if (l == 0) return s;
      continue;  // a coarse level that fails leaves the guess to the finer levels
    }
    if (l == 0) {
      relative = residual_radius_ < half_ ? centreResidual(slot, pyramid.level(0), cx, cy, A)
                                          : res / lt.contrast;
      if (relative < 0.0) return LkStatus::kLeftImage;
    }
    const double nox = A[0] * lt.offset_x + A[1] * lt.offset_y;
    const double noy = A[2] * lt.offset_x + A[3] * lt.offset_y;
    px = (cx + nox) * scale;
    py = (cy + noy) * scale;
  }
  x = static_cast<float>(px);
  y = static_cast<float>(py);
  shape = PatchShape{static_cast<float>(A[0]), static_cast<float>(A[1]), static_cast<float>(A[2]),
                     static_cast<float>(A[3])};
  residual = static_cast<float>(relative);
  return relative > options_.max_residual ? LkStatus::kResidualTooHigh : LkStatus::kTracked;
}

}  // namespace epitrack

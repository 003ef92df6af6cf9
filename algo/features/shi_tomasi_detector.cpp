#include "algo/features/shi_tomasi_detector.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "algo/flow/simd_int16.hpp"
#include "algo/image/scharr.hpp"

namespace epitrack {

// ---- FeatureGrid -----------------------------------------------------------------------------

void FeatureGrid::configure(int width, int height, double min_distance) {
  cell_ = static_cast<float>(std::max(1.0, min_distance));
  cols_ = std::max(1, static_cast<int>(std::ceil(static_cast<float>(width) / cell_)));
  rows_ = std::max(1, static_cast<int>(std::ceil(static_cast<float>(height) / cell_)));
  min_distance2_ = static_cast<float>(min_distance * min_distance);
  const auto cells = static_cast<std::size_t>(cols_) * static_cast<std::size_t>(rows_);
  points_.reserve(cells * kPerCell);
  count_.reserve(cells);
  clear();
}

void FeatureGrid::clear() {
  std::memset(count_.data(), 0, static_cast<std::size_t>(cols_) * static_cast<std::size_t>(rows_));
}

bool FeatureGrid::isFree(float x, float y) const {
  const int cx = static_cast<int>(x / cell_);
  const int cy = static_cast<int>(y / cell_);
  for (int gy = std::max(0, cy - 1); gy <= std::min(rows_ - 1, cy + 1); ++gy) {
    for (int gx = std::max(0, cx - 1); gx <= std::min(cols_ - 1, cx + 1); ++gx) {
      const int c = cellIndex(gx, gy);
      const Point2f* p = points_.data() + static_cast<std::ptrdiff_t>(c) * kPerCell;
      for (int i = 0; i < count_.data()[c]; ++i) {
        const float ddx = p[i].x - x;
        const float ddy = p[i].y - y;
        if (ddx * ddx + ddy * ddy < min_distance2_) return false;
      }
    }
  }
  return true;
}

void FeatureGrid::insert(float x, float y) {
  const int cx = std::clamp(static_cast<int>(x / cell_), 0, cols_ - 1);
  const int cy = std::clamp(static_cast<int>(y / cell_), 0, rows_ - 1);
  const int c = cellIndex(cx, cy);
  uint8_t& n = count_.data()[c];
  if (n >= kPerCell) return;
  points_.data()[static_cast<std::ptrdiff_t>(c) * kPerCell + n] = Point2f{x, y};
  ++n;
}

// ---- ShiTomasiDetector -----------------------------------------------------------------------

ShiTomasiDetector::ShiTomasiDetector(const ShiTomasiOptions& options, int width, int height)
    : options_(options), width_(width), height_(height) {
  options_.block_radius = std::clamp(options_.block_radius, 1, 3);
  options_.border = std::max(options_.border, options_.block_radius + options_.subpixel_radius + 2);
  dx_.allocate(width, height);
  dy_.allocate(width, height);
  response_.allocate(width, height);
  const auto rows = static_cast<std::size_t>(2 * options_.block_radius + 1);
  row_sums_.reserve(3 * rows * static_cast<std::size_t>(std::max(width, 1)));
  products_.reserve(3 * static_cast<std::size_t>(std::max(width, 1)));
  // Strict 3x3 maxima are at most one pixel in four.
  candidate_capacity_ = static_cast<std::size_t>(std::max(width, 1)) *
                            static_cast<std::size_t>(std::max(height, 1)) / 4 +
                        1;
  candidates_.reserve(candidate_capacity_);
  grid_.configure(std::max(width, 1), std::max(height, 1), options_.min_distance);
}

void ShiTomasiDetector::computeResponse(ImageView<const uint8_t> image) {
  scharrGradients(image, dx_.view(), dy_.view());
#if EPITRACK_LK_SIMD
  if (options_.vector_kernels) {
    computeResponseVector();
    return;
  }
#endif
  computeResponseScalar();
}

void ShiTomasiDetector::computeResponseScalar() {
  const int w = width_;
  const int r = options_.block_radius;
  const int rows = 2 * r + 1;
  const int b = options_.border - 1;  // the response is needed one pixel inside the border for NMS
  // Horizontal block sums of the products gx^2, gx*gy, gy^2 of one row into ring slot `slot`.
  // |g| <= 4080: a product <= 16.6e6, a (2r+1)^2 <= 49 sum <= 8.2e8 < 2^31.
  const auto horizontalSums = [&](int y, int slot) {
    const int16_t* gx = dx_.row(y);
    const int16_t* gy = dy_.row(y);
    int32_t* sxx = row_sums_.data() + static_cast<std::ptrdiff_t>(3 * slot) * w;
    int32_t* sxy = sxx + w;
    int32_t* syy = sxy + w;
    for (int x = b; x < w - b; ++x) {
      int32_t axx = 0, axy = 0, ayy = 0;
      for (int k = -r; k <= r; ++k) {
        const int32_t ux = gx[x + k];
        const int32_t uy = gy[x + k];
        axx += ux * ux;
        axy += ux * uy;
        ayy += uy * uy;
      }
      sxx[x] = axx;
      sxy[x] = axy;
      syy[x] = ayy;
    }
  };
  float max_response = 0.0f;
  for (int y = b - r; y < b + r; ++y) horizontalSums(y, y % rows);
  for (int y = b; y < height_ - b; ++y) {
    horizontalSums(y + r, (y + r) % rows);
    float* out = response_.row(y);
    for (int x = b; x < w - b; ++x) {
      int32_t a = 0, c = 0, d = 0;
      for (int k = 0; k < rows; ++k) {
        const int32_t* s = row_sums_.data() + static_cast<std::ptrdiff_t>(3 * k) * w;
        a += s[x];
        c += s[x + w];
        d += s[x + 2 * w];
      }
      // Minimum eigenvalue of [a c; c d] (Shi & Tomasi 1994 eq. 3): ((a+d) - sqrt((a-d)^2+4c^2))/2.
      const float fa = static_cast<float>(a);
      const float fc = static_cast<float>(c);
      const float fd = static_cast<float>(d);
      const float diff = fa - fd;
      const float lambda = 0.5f * ((fa + fd) - std::sqrt(diff * diff + 4.0f * fc * fc));
      out[x] = lambda;
      max_response = std::max(max_response, lambda);
    }
  }
  max_response_ = max_response;
}

#if EPITRACK_LK_SIMD

void ShiTomasiDetector::computeResponseVector() {
  using namespace simd;
  const int w = width_;
  const int r = options_.block_radius;
  const int rows = 2 * r + 1;
  const int b = options_.border - 1;  // as computeResponseScalar
  int32_t* pxx = products_.data();
  int32_t* pxy = pxx + w;
  int32_t* pyy = pxy + w;
  // The products of row y over columns [b - r, w - b + r), then their horizontal block sums over
  // [b, w - b) into ring slot `slot` (the same integers as the scalar pass).
  const auto horizontalSums = [&](int y, int slot) {
    const int16_t* gx = dx_.row(y);
    const int16_t* gy = dy_.row(y);
    const int x_end = w - b + r;
    int x = b - r;
    for (; x + 8 <= x_end; x += 8) {
      const I16x8 ux = loadI16(gx + x);
      const I16x8 uy = loadI16(gy + x);
      I32x4 lo, hi;
      mulWiden16(ux, ux, lo, hi);
      store32(pxx + x, lo);
      store32(pxx + x + 4, hi);
      mulWiden16(ux, uy, lo, hi);
      store32(pxy + x, lo);
      store32(pxy + x + 4, hi);
      mulWiden16(uy, uy, lo, hi);
      store32(pyy + x, lo);
      store32(pyy + x + 4, hi);
    }
    for (; x < x_end; ++x) {
      pxx[x] = gx[x] * gx[x];
      pxy[x] = gx[x] * gy[x];
      pyy[x] = gy[x] * gy[x];
    }
    int32_t* sxx = row_sums_.data() + static_cast<std::ptrdiff_t>(3 * slot) * w;
    int32_t* sxy = sxx + w;
    int32_t* syy = sxy + w;
    x = b;
    for (; x + 4 <= w - b; x += 4) {
      I32x4 axx = zero32(), axy = zero32(), ayy = zero32();
      for (int k = -r; k <= r; ++k) {
        axx = add32(axx, loadI32(pxx + x + k));
        axy = add32(axy, loadI32(pxy + x + k));
        ayy = add32(ayy, loadI32(pyy + x + k));
      }
      store32(sxx + x, axx);
      store32(sxy + x, axy);
      store32(syy + x, ayy);
    }
    for (; x < w - b; ++x) {
      int32_t axx = 0, axy = 0, ayy = 0;
      for (int k = -r; k <= r; ++k) {
        axx += pxx[x + k];
        axy += pxy[x + k];
        ayy += pyy[x + k];
      }
      sxx[x] = axx;
      sxy[x] = axy;
      syy[x] = ayy;
    }
  };
  // Minimum eigenvalue of [a c; c d] (Shi & Tomasi 1994 eq. 3), in the scalar pass's order.
  const F32x4 half = setF32(0.5f);
  const F32x4 four = setF32(4.0f);
  F32x4 max4 = setF32(0.0f);
  float max_response = 0.0f;
  for (int y = b - r; y < b + r; ++y) horizontalSums(y, y % rows);
  for (int y = b; y < height_ - b; ++y) {
    horizontalSums(y + r, (y + r) % rows);
    float* out = response_.row(y);
    int x = b;
    for (; x + 4 <= w - b; x += 4) {
      I32x4 a = zero32(), c = zero32(), d = zero32();
      for (int k = 0; k < rows; ++k) {
        const int32_t* s = row_sums_.data() + static_cast<std::ptrdiff_t>(3 * k) * w + x;
        a = add32(a, loadI32(s));
        c = add32(c, loadI32(s + w));
        d = add32(d, loadI32(s + 2 * w));
      }
      const F32x4 fa = toF32(a), fc = toF32(c), fd = toF32(d);
      const F32x4 diff = subF32(fa, fd);
      const F32x4 root = sqrtF32(addF32(mulF32(diff, diff), mulF32(mulF32(four, fc), fc)));
      const F32x4 lambda = mulF32(half, subF32(addF32(fa, fd), root));
      storeF32(out + x, lambda);
      max4 = maxF32(max4, lambda);
    }
    for (; x < w - b; ++x) {
      int32_t a = 0, c = 0, d = 0;
      for (int k = 0; k < rows; ++k) {
        const int32_t* s = row_sums_.data() + static_cast<std::ptrdiff_t>(3 * k) * w;
        a += s[x];
        c += s[x + w];
        d += s[x + 2 * w];
      }
      const float fa = static_cast<float>(a);
      const float fc = static_cast<float>(c);
      const float fd = static_cast<float>(d);
      const float diff = fa - fd;
      const float lambda = 0.5f * ((fa + fd) - std::sqrt(diff * diff + 4.0f * fc * fc));
      out[x] = lambda;
      max_response = std::max(max_response, lambda);
    }
  }
  max_response_ = std::max(max_response, maxLaneF32(max4));
}

#else

void ShiTomasiDetector::computeResponseVector() { computeResponseScalar(); }

#endif

std::size_t ShiTomasiDetector::rowMaximaScalar(int y, int x0, int x1, float floor_response,
                                               const uint8_t* m, std::size_t n) {
  const float* r0 = response_.row(y - 1);
  const float* r1 = response_.row(y);
  const float* r2 = response_.row(y + 1);
  Corner* cand = candidates_.data();
  for (int x = x0; x < x1; ++x) {
    const float v = r1[x];
    if (v <= floor_response) continue;
    if (v < r0[x - 1] || v < r0[x] || v < r0[x + 1] || v < r1[x - 1] || v <= r1[x + 1] ||
        v <= r2[x - 1] || v <= r2[x] || v <= r2[x + 1]) {
      continue;
    }
    if (m != nullptr && m[x] == 0) continue;
    if (n < candidate_capacity_)
      cand[n++] = Corner{static_cast<float>(x), static_cast<float>(y), v};
  }
  return n;
}

std::size_t ShiTomasiDetector::rowMaximaVector(int y, int b, float floor_response, const uint8_t* m,
                                               std::size_t n) {
#if EPITRACK_LK_SIMD
  using namespace simd;
  const float* r0 = response_.row(y - 1);
  const float* r1 = response_.row(y);
  const float* r2 = response_.row(y + 1);
  Corner* cand = candidates_.data();
  const F32x4 floor4 = setF32(floor_response);
  int x = b;
  // Strict 3x3 maxima, ties broken towards the first in raster order (as rowMaximaScalar).
  for (; x + 4 <= width_ - b; x += 4) {
    const F32x4 v = loadF32(r1 + x);
    int bits = maskGtF32(v, floor4) & maskGeF32(v, loadF32(r0 + x - 1)) &
               maskGeF32(v, loadF32(r0 + x)) & maskGeF32(v, loadF32(r0 + x + 1)) &
               maskGeF32(v, loadF32(r1 + x - 1)) & maskGtF32(v, loadF32(r1 + x + 1)) &
               maskGtF32(v, loadF32(r2 + x - 1)) & maskGtF32(v, loadF32(r2 + x)) &
               maskGtF32(v, loadF32(r2 + x + 1));
    for (int i = 0; bits != 0; ++i, bits >>= 1) {
      if ((bits & 1) == 0) continue;
      const int xi = x + i;
      if (m != nullptr && m[xi] == 0) continue;
      if (n < candidate_capacity_)
        cand[n++] = Corner{static_cast<float>(xi), static_cast<float>(y), r1[xi]};
    }
  }
  return rowMaximaScalar(y, x, width_ - b, floor_response, m, n);
#else
  return rowMaximaScalar(y, b, width_ - b, floor_response, m, n);
#endif
}

void ShiTomasiDetector::refine(float& x, float& y) const {
  const int rad = options_.subpixel_radius;
  const int lo = rad + 1;
  const int dead = options_.subpixel_dead_zone;
  float cx = x;
  float cy = y;
  for (int it = 0; it < options_.subpixel_iterations; ++it) {
    const int ix = static_cast<int>(std::lround(cx));
    const int iy = static_cast<int>(std::lround(cy));
    if (ix < lo || iy < lo || ix >= width_ - lo || iy >= height_ - lo) break;
    // Each pixel p with gradient g constrains the corner q to its edge line: g.(q - p) = 0.
    // Least squares: (sum g g^T) q = sum g g^T p (Foerstner & Guelch 1987), weights g g^T.
    double gxx = 0.0, gxy = 0.0, gyy = 0.0, bx = 0.0, by = 0.0;
    for (int v = -rad; v <= rad; ++v) {
      const int16_t* gxr = dx_.row(iy + v);
      const int16_t* gyr = dy_.row(iy + v);
      for (int u = -rad; u <= rad; ++u) {
        // Pixels next to the vertex mix both edges' gradients (OpenCV's cornerSubPix "zero
        // zone"): they carry no line constraint and are left out.
        if (std::abs(u) <= dead && std::abs(v) <= dead) continue;
        const double gx = gxr[ix + u];
        const double gy = gyr[ix + u];
        const double px = ix + u;
        const double py = iy + v;
        gxx += gx * gx;
        gxy += gx * gy;
        gyy += gy * gy;
        bx += gx * gx * px + gx * gy * py;
        by += gx * gy * px + gy * gy * py;
      }
    }
    const double det = gxx * gyy - gxy * gxy;
    if (!(det > 1e-6 * (gxx + gyy) * (gxx + gyy))) break;
    const double qx = (gyy * bx - gxy * by) / det;
    const double qy = (gxx * by - gxy * bx) / det;
    if (!std::isfinite(qx) || !std::isfinite(qy) || std::abs(qx - static_cast<double>(x)) > 3.0 ||
        std::abs(qy - static_cast<double>(y)) > 3.0) {
      break;
    }
    const bool moved_cell = std::lround(qx) != ix || std::lround(qy) != iy;
    cx = static_cast<float>(qx);
    cy = static_cast<float>(qy);
    if (!moved_cell) break;
  }
  x = cx;
  y = cy;
}

ShiTomasiDetector::Status ShiTomasiDetector::detect(ImageView<const uint8_t> image,
                                                    std::span<const Point2f> existing,
                                                    ImageView<const uint8_t> mask, int wanted,
                                                    std::span<Corner> out, int& found) {
  found = 0;
  if (width_ <= 0 || height_ <= 0) return Status::kNotConfigured;
  if (image.width != width_ || image.height != height_) return Status::kSizeMismatch;
  if (!mask.empty() && !sameSize(mask, image)) return Status::kSizeMismatch;
  const int b = options_.border;
  if (2 * b + 2 >= width_ || 2 * b + 2 >= height_) return Status::kOk;
  computeResponse(image);
  const int limit = std::min({wanted, static_cast<int>(out.size()), options_.max_features});
  if (limit <= 0 || max_response_ <= 0.0f) return Status::kOk;

  // Candidates: 3x3 local maxima above the floor (ties broken towards the first in raster order).
  const float floor_response = static_cast<float>(options_.min_quality) * max_response_;
  std::size_t n = 0;
  Corner* cand = candidates_.data();
  for (int y = b; y < height_ - b; ++y) {
    const uint8_t* m = mask.empty() ? nullptr : mask.row(y);
    n = options_.vector_kernels ? rowMaximaVector(y, b, floor_response, m, n)
                                : rowMaximaScalar(y, b, width_ - b, floor_response, m, n);
  }
  // Strongest first (then raster order: a strict order, so the same sequence as a full sort),
  // from a heap: usually only a few hundred of the candidates are looked at.
  const auto after = [](const Corner& a, const Corner& c) {
    if (a.response != c.response) return a.response < c.response;
    if (a.y != c.y) return a.y > c.y;
    return a.x > c.x;
  };
  std::make_heap(cand, cand + n, after);

  grid_.clear();
  for (const Point2f& p : existing) grid_.insert(p.x, p.y);
  last_quality_ = 0.0;
  for (std::size_t left = n; left > 0 && found < limit; --left) {
    std::pop_heap(cand, cand + left, after);
    const Corner c = cand[left - 1];
    if (!grid_.isFree(c.x, c.y)) continue;
    grid_.insert(c.x, c.y);
    Corner refined = c;
    if (options_.subpixel) refine(refined.x, refined.y);
    out[static_cast<std::size_t>(found++)] = refined;
    last_quality_ = static_cast<double>(c.response / max_response_);
  }
  return Status::kOk;
}

}  // namespace epitrack

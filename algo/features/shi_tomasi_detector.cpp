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

void ShiTomasiDetector::computeResponse(const PixelRect& rect) {
#if EPITRACK_LK_SIMD
  if (options_.vector_kernels) {
    computeResponseVector(rect);
    return;
  }
#endif
  computeResponseScalar(rect);
}

void ShiTomasiDetector::computeResponseScalar(const PixelRect& rect) {
  const int w = width_;
  const int r = options_.block_radius;
  const int rows = 2 * r + 1;
  // Horizontal block sums of the products gx^2, gx*gy, gy^2 of one row into ring slot `slot`.
  // |g| <= 4080: a product <= 16.6e6, a (2r+1)^2 <= 49 sum <= 8.2e8 < 2^31.
  const auto horizontalSums = [&](int y, int slot) {
    const int16_t* gx = dx_.row(y);
    const int16_t* gy = dy_.row(y);
    int32_t* sxx = row_sums_.data() + static_cast<std::ptrdiff_t>(3 * slot) * w;
    int32_t* sxy = sxx + w;
    int32_t* syy = sxy + w;
    for (int x = rect.x0; x < rect.x1; ++x) {
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
  for (int y = rect.y0 - r; y < rect.y0 + r; ++y) horizontalSums(y, y % rows);
  for (int y = rect.y0; y < rect.y1; ++y) {
    horizontalSums(y + r, (y + r) % rows);
    float* out = response_.row(y);
    for (int x = rect.x0; x < rect.x1; ++x) {
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
  max_response_ = std::max(max_response_, max_response);
}

#if EPITRACK_LK_SIMD

void ShiTomasiDetector::computeResponseVector(const PixelRect& rect) {
  using namespace simd;
  const int w = width_;
  const int r = options_.block_radius;
  const int rows = 2 * r + 1;
  int32_t* pxx = products_.data();
  int32_t* pxy = pxx + w;
  int32_t* pyy = pxy + w;
  // The products of row y over columns [x0 - r, x1 + r), then their horizontal block sums over
  // [x0, x1) into ring slot `slot` (the same integers as the scalar pass).
  const auto horizontalSums = [&](int y, int slot) {
    const int16_t* gx = dx_.row(y);
    const int16_t* gy = dy_.row(y);
    const int x_end = rect.x1 + r;
    int x = rect.x0 - r;
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
    x = rect.x0;
    for (; x + 4 <= rect.x1; x += 4) {
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
    for (; x < rect.x1; ++x) {
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
  for (int y = rect.y0 - r; y < rect.y0 + r; ++y) horizontalSums(y, y % rows);
  for (int y = rect.y0; y < rect.y1; ++y) {
    horizontalSums(y + r, (y + r) % rows);
    float* out = response_.row(y);
    int x = rect.x0;
    for (; x + 4 <= rect.x1; x += 4) {
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
    for (; x < rect.x1; ++x) {
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
  max_response_ = std::max(max_response_, std::max(max_response, maxLaneF32(max4)));
}

#else

void ShiTomasiDetector::computeResponseVector(const PixelRect& rect) {
  computeResponseScalar(rect);
}

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

std::size_t ShiTomasiDetector::rowMaximaVector(int y, int x0, int x1, float floor_response,
                                               const uint8_t* m, std::size_t n) {
#if EPITRACK_LK_SIMD
  using namespace simd;
  const float* r0 = response_.row(y - 1);
  const float* r1 = response_.row(y);
  const float* r2 = response_.row(y + 1);
  Corner* cand = candidates_.data();
  const F32x4 floor4 = setF32(floor_response);
  int x = x0;
  // Strict 3x3 maxima, ties broken towards the first in raster order (as rowMaximaScalar).
  for (; x + 4 <= x1; x += 4) {
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
  return rowMaximaScalar(y, x, x1, floor_response, m, n);
#else
  return rowMaximaScalar(y, x0, x1, floor_response, m, n);
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

PixelRect ShiTomasiDetector::clipToCornerArea(const PixelRect& r) const {
  const int b = options_.border;
  PixelRect c{std::max(r.x0, b), std::max(r.y0, b), std::min(r.x1, width_ - b),
              std::min(r.y1, height_ - b)};
  if (c.x1 <= c.x0 || c.y1 <= c.y0) c = PixelRect{};
  return c;
}

std::size_t ShiTomasiDetector::collectMaxima(const PixelRect& r, float floor_response,
                                             ImageView<const uint8_t> mask, std::size_t n) {
  for (int y = r.y0; y < r.y1; ++y) {
    const uint8_t* m = mask.empty() ? nullptr : mask.row(y);
    n = options_.vector_kernels ? rowMaximaVector(y, r.x0, r.x1, floor_response, m, n)
                                : rowMaximaScalar(y, r.x0, r.x1, floor_response, m, n);
  }
  return n;
}

void ShiTomasiDetector::resetGrid(std::span<const Point2f> existing) {
  grid_.clear();
  for (const Point2f& p : existing) grid_.insert(p.x, p.y);
  last_quality_ = 0.0;
}

void ShiTomasiDetector::selectCorners(std::size_t n, int limit, std::span<Corner> out, int& found) {
  // Strongest first (then raster order: a strict order, so the same sequence as a full sort),
  // from a heap: usually only a few hundred of the candidates are looked at.
  const auto after = [](const Corner& a, const Corner& c) {
    if (a.response != c.response) return a.response < c.response;
    if (a.y != c.y) return a.y > c.y;
    return a.x > c.x;
  };
  Corner* cand = candidates_.data();
  std::make_heap(cand, cand + n, after);
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
}

ShiTomasiDetector::Status ShiTomasiDetector::checkInput(ImageView<const uint8_t> image,
                                                        ImageView<const uint8_t> mask,
                                                        bool& too_small) const {
  if (width_ <= 0 || height_ <= 0) return Status::kNotConfigured;
  if (image.width != width_ || image.height != height_) return Status::kSizeMismatch;
  if (!mask.empty() && !sameSize(mask, image)) return Status::kSizeMismatch;
  const int b = options_.border;
  too_small = 2 * b + 2 >= width_ || 2 * b + 2 >= height_;  // no corner area: nothing to find
  return Status::kOk;
}

ShiTomasiDetector::Status ShiTomasiDetector::detect(ImageView<const uint8_t> image,
                                                    std::span<const Point2f> existing,
                                                    ImageView<const uint8_t> mask, int wanted,
                                                    std::span<Corner> out, int& found) {
  found = 0;
  bool too_small = false;
  if (const Status st = checkInput(image, mask, too_small); st != Status::kOk || too_small)
    return st;
  const int b = options_.border;
  scharrGradients(image, dx_.view(), dy_.view());
  max_response_ = 0.0f;
  // The response is needed one pixel beyond the corner area for the 3x3 maxima.
  const PixelRect corners{b, b, width_ - b, height_ - b};
  computeResponse(PixelRect{b - 1, b - 1, width_ - b + 1, height_ - b + 1});
  const int limit = std::min({wanted, static_cast<int>(out.size()), options_.max_features});
  if (limit <= 0 || max_response_ <= 0.0f) return Status::kOk;
  const float floor_response = static_cast<float>(options_.min_quality) * max_response_;
  resetGrid(existing);
  selectCorners(collectMaxima(corners, floor_response, mask, 0), limit, out, found);
  return Status::kOk;
}

ShiTomasiDetector::Status ShiTomasiDetector::detectInRegions(
    ImageView<const uint8_t> image, std::span<const Point2f> existing,
    ImageView<const uint8_t> mask, std::span<const DetectionRegion> regions, int wanted,
    std::span<Corner> out, int& found) {
  found = 0;
  bool too_small = false;
  if (const Status st = checkInput(image, mask, too_small); st != Status::kOk || too_small)
    return st;
  // The gradients a corner of a region depends on: its block sums and 3x3 maximum (block_radius
  // + 1 around it) and its refinement (subpixel_radius around a centre that moves at most 3 px,
  // see refine). The border keeps all of it inside the image.
  const int margin = std::max(options_.block_radius + 1, options_.subpixel_radius + 3);
  max_response_ = 0.0f;
  for (const DetectionRegion& region : regions) {
    const PixelRect r = clipToCornerArea(region.area);
    if (r.x1 == r.x0) continue;
    scharrGradientsRegion(image, dx_.view(), dy_.view(), r.x0 - margin, r.y0 - margin,
                          r.x1 + margin, r.y1 + margin);
    computeResponse(PixelRect{r.x0 - 1, r.y0 - 1, r.x1 + 1, r.y1 + 1});
  }
  const int limit = std::min({wanted, static_cast<int>(out.size()), options_.max_features});
  if (limit <= 0 || max_response_ <= 0.0f) return Status::kOk;
  const float floor_response = static_cast<float>(options_.min_quality) * max_response_;
  resetGrid(existing);
  // Regions without a cap of their own compete for the call's budget, strongest first.
  std::size_t n = 0;
  for (const DetectionRegion& region : regions) {
    const PixelRect r = clipToCornerArea(region.area);
    if (r.x1 > r.x0 && region.wanted < 0) n = collectMaxima(r, floor_response, mask, n);
  }
  selectCorners(n, limit, out, found);
  for (const DetectionRegion& region : regions) {
    const PixelRect r = clipToCornerArea(region.area);
    if (r.x1 == r.x0 || region.wanted <= 0) continue;
    selectCorners(collectMaxima(r, floor_response, mask, 0), std::min(limit, found + region.wanted),
                  out, found);
  }
  return Status::kOk;
}

}  // namespace epitrack

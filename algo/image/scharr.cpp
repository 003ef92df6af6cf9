#include "algo/image/scharr.hpp"

#include <algorithm>

#include "algo/flow/simd_int16.hpp"
#include "algo/image/border.hpp"

namespace epitrack {

void scharrGradientsScalar(ImageView<const uint8_t> src, ImageView<int16_t> dx,
                           ImageView<int16_t> dy) {
  EPITRACK_ASSERT(sameSize(src, dx) && sameSize(src, dy));
  const int w = src.width;
  const int h = src.height;
  for (int y = 0; y < h; ++y) {
    const uint8_t* up = src.row(reflect101(y - 1, h));
    const uint8_t* mid = src.row(y);
    const uint8_t* down = src.row(reflect101(y + 1, h));
    int16_t* ox = dx.row(y);
    int16_t* oy = dy.row(y);
    // Separable: smoothing [3 10 3] across the derivative direction, difference [-1 0 1] along it.
    const auto at = [&](int x) {
      const int xl = reflect101(x - 1, w);
      const int xr = reflect101(x + 1, w);
      const int gx = 3 * (up[xr] - up[xl]) + 10 * (mid[xr] - mid[xl]) + 3 * (down[xr] - down[xl]);
      const int gy = 3 * (down[xl] - up[xl]) + 10 * (down[x] - up[x]) + 3 * (down[xr] - up[xr]);
      ox[x] = static_cast<int16_t>(gx);
      oy[x] = static_cast<int16_t>(gy);
    };
    if (w < 3) {
      for (int x = 0; x < w; ++x) at(x);
      continue;
    }
    at(0);
    for (int x = 1; x < w - 1; ++x) {
      const int gx = 3 * (up[x + 1] - up[x - 1]) + 10 * (mid[x + 1] - mid[x - 1]) +
                     3 * (down[x + 1] - down[x - 1]);
      const int gy =
          3 * (down[x - 1] - up[x - 1]) + 10 * (down[x] - up[x]) + 3 * (down[x + 1] - up[x + 1]);
      ox[x] = static_cast<int16_t>(gx);
      oy[x] = static_cast<int16_t>(gy);
    }
    at(w - 1);
  }
}

void scharrGradients(ImageView<const uint8_t> src, ImageView<int16_t> dx, ImageView<int16_t> dy) {
  scharrGradientsRegion(src, dx, dy, 0, 0, src.width, src.height);
}

void scharrGradientsRegion(ImageView<const uint8_t> src, ImageView<int16_t> dx,
                           ImageView<int16_t> dy, int x0, int y0, int x1, int y1) {
  EPITRACK_ASSERT(sameSize(src, dx) && sameSize(src, dy));
  const int w = src.width;
  const int h = src.height;
  x0 = std::max(x0, 0);
  y0 = std::max(y0, 0);
  x1 = std::min(x1, w);
  y1 = std::min(y1, h);
#if EPITRACK_LK_SIMD
  if (w < 10) {
    scharrGradientsScalar(src, dx, dy);
    return;
  }
  using namespace simd;
  const I16x8 three = set16(3);
  const I16x8 ten = set16(10);
  for (int y = y0; y < y1; ++y) {
    const uint8_t* up = src.row(reflect101(y - 1, h));
    const uint8_t* mid = src.row(y);
    const uint8_t* down = src.row(reflect101(y + 1, h));
    int16_t* ox = dx.row(y);
    int16_t* oy = dy.row(y);
    const auto at = [&](int x) {
      const int xl = reflect101(x - 1, w);
      const int xr = reflect101(x + 1, w);
      ox[x] = static_cast<int16_t>(3 * (up[xr] - up[xl]) + 10 * (mid[xr] - mid[xl]) +
                                   3 * (down[xr] - down[xl]));
      oy[x] = static_cast<int16_t>(3 * (down[xl] - up[xl]) + 10 * (down[x] - up[x]) +
                                   3 * (down[xr] - up[xr]));
    };
    int x = x0;
    if (x == 0 && x < x1) at(x++);
    // 8 columns per step, reading columns x - 1 .. x + 8 (|sums| <= 16 * 255: int16).
    for (; x + 8 <= x1 && x + 9 <= w; x += 8) {
      const I16x8 ul = loadWidenU8(up + x - 1), uc = loadWidenU8(up + x),
                  ur = loadWidenU8(up + x + 1);
      const I16x8 ml = loadWidenU8(mid + x - 1), mr = loadWidenU8(mid + x + 1);
      const I16x8 dl = loadWidenU8(down + x - 1), dc = loadWidenU8(down + x),
                  dr = loadWidenU8(down + x + 1);
      const I16x8 gx =
          add16(mul16(sub16(add16(ur, dr), add16(ul, dl)), three), mul16(sub16(mr, ml), ten));
      const I16x8 gy =
          add16(mul16(add16(sub16(dl, ul), sub16(dr, ur)), three), mul16(sub16(dc, uc), ten));
      storeI16(ox + x, gx);
      storeI16(oy + x, gy);
    }
    for (; x < x1; ++x) at(x);
  }
#else
  (void)x0;
  (void)y0;
  (void)x1;
  (void)y1;
  scharrGradientsScalar(src, dx, dy);
#endif
}

}  // namespace epitrack

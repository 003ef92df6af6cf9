#include "tools/synth/scene.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "tools/synth/portable_math.hpp"
#include "tools/synth/random.hpp"

namespace epitrack::synth {

namespace {
// double -> int as x86-64 converts it (cvttsd2si): values outside the int range, infinities and
// NaN give INT_MIN. A plain static_cast is undefined there, and aarch64 saturates instead, which
// rendered different pixels (and, for an infinite footprint, looped over 2^32 cells) on the board.
// Spelling the x86-64 result out keeps the clips rendered so far and makes them portable.
int toIntX86(double v) {
  if (v >= -2147483648.0 && v < 2147483648.0) return static_cast<int>(v);
  return std::numeric_limits<int>::min();
}
}  // namespace

float TexturedQuad::boxLookup(double u, double v, double wu, double wv) const {
  const double cu = u / cell;
  const double cv = v / cell;
  const double hu = 0.5 * wu / cell;
  const double hv = 0.5 * wv / cell;
  // Coarsest level at which the box spans at most two cells per axis (so at most 3x3 terms).
  std::size_t level = 0;
  double scale = 1.0;
  while (level + 1 < levels.size() && std::max(hu, hv) > scale) {
    ++level;
    scale *= 2.0;
  }
  const int cols = level_cols[level];
  const int rows = level_rows[level];
  const std::vector<float>& cells = levels[level];
  const double x0 = (cu - hu) / scale;
  const double x1 = (cu + hu) / scale;
  const double y0 = (cv - hv) / scale;
  const double y1 = (cv + hv) / scale;
  const auto clampi = [](int i, int n) { return i < 0 ? 0 : (i >= n ? n - 1 : i); };
  if (x1 - x0 < 1e-9 || y1 - y0 < 1e-9) {  // degenerate footprint: point sample
    const int i = clampi(toIntX86(std::floor(cu / scale)), cols);
    const int j = clampi(toIntX86(std::floor(cv / scale)), rows);
    return cells[static_cast<std::size_t>(j) * static_cast<std::size_t>(cols) +
                 static_cast<std::size_t>(i)];
  }
  const int i0 = toIntX86(std::floor(x0));
  const int i1 = toIntX86(std::floor(x1));
  const int j0 = toIntX86(std::floor(y0));
  const int j1 = toIntX86(std::floor(y1));
  double sum = 0.0;
  for (int j = j0; j <= j1; ++j) {
    const double oy = std::min(y1, j + 1.0) - std::max(y0, static_cast<double>(j));
    if (oy <= 0.0) continue;
    const float* row =
        cells.data() + static_cast<std::size_t>(clampi(j, rows)) * static_cast<std::size_t>(cols);
    double acc = 0.0;
    for (int i = i0; i <= i1; ++i) {
      const double ox = std::min(x1, i + 1.0) - std::max(x0, static_cast<double>(i));
      if (ox > 0.0) acc += ox * static_cast<double>(row[clampi(i, cols)]);
    }
    sum += oy * acc;
  }
  return static_cast<float>(sum / ((x1 - x0) * (y1 - y0)));
}

namespace {

// Area of the convex polygon `poly` (n vertices) clipped to the rectangle [x0,x1] x [y0,y1]
// (Sutherland-Hodgman against the four sides, then the shoelace formula).
double clippedArea(const Eigen::Vector2d* poly, int n, double x0, double x1, double y0, double y1) {
  Eigen::Vector2d buf_a[12];
  Eigen::Vector2d buf_b[12];
  for (int i = 0; i < n; ++i) buf_a[i] = poly[i];
  Eigen::Vector2d* in = buf_a;
  Eigen::Vector2d* out = buf_b;
  const auto clip = [&](int axis, double bound, bool keep_above) {
    int m = 0;
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d& p = in[i];
      const Eigen::Vector2d& q = in[(i + 1) % n];
      const bool p_in = keep_above ? p[axis] >= bound : p[axis] <= bound;
      const bool q_in = keep_above ? q[axis] >= bound : q[axis] <= bound;
      if (p_in) out[m++] = p;
      if (p_in != q_in) {
        const double s = (bound - p[axis]) / (q[axis] - p[axis]);
        out[m++] = p + s * (q - p);
      }
    }
    n = m;
    std::swap(in, out);
  };
  clip(0, x0, true);
  if (n > 0) clip(0, x1, false);
  if (n > 0) clip(1, y0, true);
  if (n > 0) clip(1, y1, false);
  double area2 = 0.0;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d& p = in[i];
    const Eigen::Vector2d& q = in[(i + 1) % n];
    area2 += p.x() * q.y() - q.x() * p.y();
  }
  return 0.5 * std::abs(area2);
}

}  // namespace

float TexturedQuad::parallelogramLookup(double u, double v, const Eigen::Vector2d& a,
                                        const Eigen::Vector2d& b) const {
  // In cell units.
  const Eigen::Vector2d c(u / cell, v / cell);
  const Eigen::Vector2d ha = 0.5 * a / cell;
  const Eigen::Vector2d hb = 0.5 * b / cell;
  const Eigen::Vector2d ext(std::abs(ha.x()) + std::abs(hb.x()),
                            std::abs(ha.y()) + std::abs(hb.y()));
  const auto clampi = [](int i, int n) { return i < 0 ? 0 : (i >= n ? n - 1 : i); };
  const int i0 = toIntX86(std::floor(c.x() - ext.x()));
  const int i1 = toIntX86(std::floor(c.x() + ext.x()));
  const int j0 = toIntX86(std::floor(c.y() - ext.y()));
  const int j1 = toIntX86(std::floor(c.y() + ext.y()));
  const std::vector<float>& base = levels[0];
  const auto value = [&](int i, int j) {
    return base[static_cast<std::size_t>(clampi(j, cells_v)) * static_cast<std::size_t>(cells_u) +
                static_cast<std::size_t>(clampi(i, cells_u))];
  };
  if (i0 == i1 && j0 == j1) return value(i0, j0);  // inside one cell: constant
  const double area = 4.0 * std::abs(ha.x() * hb.y() - ha.y() * hb.x());
  if (area < 1e-12) return value(toIntX86(std::floor(c.x())), toIntX86(std::floor(c.y())));
  if ((i1 - i0 + 1) * (j1 - j0 + 1) > 36) {
    // Large footprint: box-filtered pieces along the long side on the cell pyramid.
    Eigen::Vector2d la = a;
    Eigen::Vector2d lb = b;
    if (la.squaredNorm() < lb.squaredNorm()) std::swap(la, lb);
    const double full_area = std::abs(la.x() * lb.y() - la.y() * lb.x());
    const int pieces = std::clamp(toIntX86(std::ceil(la.squaredNorm() / full_area)), 1, 16);
    const Eigen::Vector2d step = la / pieces;
    double wu = std::abs(step.x()) + std::abs(lb.x());
    double wv = std::abs(step.y()) + std::abs(lb.y());
    const double s = std::sqrt(full_area / pieces / (wu * wv));
    wu *= s;
    wv *= s;
    double sum = 0.0;
    for (int k = 0; k < pieces; ++k) {
      const double f = (k + 0.5) / pieces - 0.5;
      sum += static_cast<double>(boxLookup(u + f * la.x(), v + f * la.y(), wu, wv));
    }
    return static_cast<float>(sum / pieces);
  }
  const Eigen::Vector2d poly[4] = {c - ha - hb, c + ha - hb, c + ha + hb, c - ha + hb};
  double sum = 0.0;
  for (int j = j0; j <= j1; ++j) {
    for (int i = i0; i <= i1; ++i) {
      const double part = clippedArea(poly, 4, i, i + 1.0, j, j + 1.0);
      if (part > 0.0) sum += part * static_cast<double>(value(i, j));
    }
  }
  return static_cast<float>(sum / area);
}

void addTexturedQuad(Scene& scene, const Eigen::Vector3d& origin, const Eigen::Vector3d& axis_u,
                     const Eigen::Vector3d& axis_v, double cell, int cells_u, int cells_v,
                     uint64_t seed) {
  TexturedQuad q;
  q.origin = origin;
  q.axis_u = axis_u.normalized();
  q.axis_v = axis_v.normalized();
  q.normal = q.axis_u.cross(q.axis_v);
  q.cell = cell;
  q.cells_u = cells_u;
  q.cells_v = cells_v;
  // Lambert-like constant shading from one fixed light, so box faces differ in brightness.
  const Eigen::Vector3d light = Eigen::Vector3d(0.4, -0.5, 0.75).normalized();
  q.brightness = 0.62 + 0.38 * std::max(0.0, q.normal.dot(light));
  SplitMix64 rng(seed);
  std::vector<float> base(static_cast<std::size_t>(cells_u) * static_cast<std::size_t>(cells_v));
  for (float& c : base) c = static_cast<float>(q.brightness * (20.0 + 215.0 * rng.uniform()));
  q.levels.push_back(std::move(base));
  q.level_cols.push_back(cells_u);
  q.level_rows.push_back(cells_v);
  while (q.level_cols.back() > 1 || q.level_rows.back() > 1) {
    const int pc = q.level_cols.back();
    const int pr = q.level_rows.back();
    const int nc = (pc + 1) / 2;
    const int nr = (pr + 1) / 2;
    const std::vector<float>& prev = q.levels.back();
    std::vector<float> next(static_cast<std::size_t>(nc) * static_cast<std::size_t>(nr));
    for (int j = 0; j < nr; ++j) {
      for (int i = 0; i < nc; ++i) {
        double s = 0.0;
        int n = 0;
        for (int dj = 0; dj < 2; ++dj) {
          for (int di = 0; di < 2; ++di) {
            const int pi = 2 * i + di;
            const int pj = 2 * j + dj;
            if (pi < pc && pj < pr) {
              s += static_cast<double>(
                  prev[static_cast<std::size_t>(pj) * static_cast<std::size_t>(pc) +
                       static_cast<std::size_t>(pi)]);
              ++n;
            }
          }
        }
        next[static_cast<std::size_t>(j) * static_cast<std::size_t>(nc) +
             static_cast<std::size_t>(i)] = static_cast<float>(s / n);
      }
    }
    q.levels.push_back(std::move(next));
    q.level_cols.push_back(nc);
    q.level_rows.push_back(nr);
  }
  scene.quads.push_back(std::move(q));
}

namespace {

void addBox(Scene& scene, const Eigen::Vector2d& centre, double yaw, double cell, int kx, int ky,
            int kz, uint64_t seed) {
  const Eigen::Vector3d ex(portableCos(yaw), portableSin(yaw), 0.0);
  const Eigen::Vector3d ey(-portableSin(yaw), portableCos(yaw), 0.0);
  const Eigen::Vector3d ez(0.0, 0.0, 1.0);
  const Eigen::Vector3d c(centre.x(), centre.y(), 0.0);
  const double a = 0.5 * kx * cell;
  const double b = 0.5 * ky * cell;
  const double h = kz * cell;
  addTexturedQuad(scene, c + a * ex - b * ey, ey, ez, cell, ky, kz, mixSeed(seed, 1));   // +x face
  addTexturedQuad(scene, c - a * ex + b * ey, -ey, ez, cell, ky, kz, mixSeed(seed, 2));  // -x face
  addTexturedQuad(scene, c + b * ey + a * ex, -ex, ez, cell, kx, kz, mixSeed(seed, 3));  // +y face
  addTexturedQuad(scene, c - b * ey - a * ex, ex, ez, cell, kx, kz, mixSeed(seed, 4));   // -y face
  addTexturedQuad(scene, c - a * ex - b * ey + h * ez, ex, ey, cell, kx, ky,
                  mixSeed(seed, 5));  // top
}

}  // namespace

Scene makeRoomScene(uint64_t seed) {
  Scene s;
  const Eigen::Vector3d X(1, 0, 0);
  const Eigen::Vector3d Y(0, 1, 0);
  const Eigen::Vector3d Z(0, 0, 1);
  addTexturedQuad(s, {-12, -12, 0}, X, Y, 0.3, 80, 80, mixSeed(seed, 100));  // floor, normal +z
  addTexturedQuad(s, {-12, 12, 0}, X, Z, 0.4, 60, 20, mixSeed(seed, 101));   // y = +12, faces -y
  addTexturedQuad(s, {12, -12, 0}, -X, Z, 0.4, 60, 20, mixSeed(seed, 102));  // y = -12, faces +y
  addTexturedQuad(s, {12, 12, 0}, -Y, Z, 0.4, 60, 20, mixSeed(seed, 103));   // x = +12, faces -x
  addTexturedQuad(s, {-12, -12, 0}, Y, Z, 0.4, 60, 20, mixSeed(seed, 104));  // x = -12, faces +x
  // Boxes: rejection-sampled so their footprints do not overlap.
  SplitMix64 rng(mixSeed(seed, 200));
  std::vector<Eigen::Vector3d> placed;  // x, y, radius
  const double cell = 0.15;
  for (int attempt = 0; attempt < 200 && placed.size() < 6; ++attempt) {
    const int kx = rng.uniformInt(3, 10);
    const int ky = rng.uniformInt(3, 10);
    const int kz = rng.uniformInt(3, 12);
    const double r = rng.uniform(0.0, 3.5);
    const double phi = rng.uniform(0.0, 2.0 * kPi);
    const double yaw = rng.uniform(0.0, kPi);
    const Eigen::Vector2d c(r * portableCos(phi), r * portableSin(phi));
    const double radius = 0.5 * cell * std::sqrt(static_cast<double>(kx * kx + ky * ky)) + 0.2;
    bool free = true;
    for (const auto& p : placed) {
      if ((c - p.head<2>()).norm() < radius + p.z()) free = false;
    }
    if (!free) continue;
    placed.emplace_back(c.x(), c.y(), radius);
    addBox(s, c, yaw, cell, kx, ky, kz, mixSeed(seed, 300 + placed.size()));
  }
  collectLandmarks(s);
  return s;
}

Scene makeOcclusionScene(uint64_t seed) {
  Scene s;
  const Eigen::Vector3d X(1, 0, 0);
  const Eigen::Vector3d Y(0, 1, 0);
  const Eigen::Vector3d Z(0, 0, 1);
  addTexturedQuad(s, {-12, -12, 0}, X, Y, 0.3, 80, 80, mixSeed(seed, 500));  // floor, normal +z
  addTexturedQuad(s, {-12, 12, 0}, X, Z, 0.4, 60, 20, mixSeed(seed, 501));   // y = +12, faces -y
  addTexturedQuad(s, {12, -12, 0}, -X, Z, 0.4, 60, 20, mixSeed(seed, 502));  // y = -12, faces +y
  addTexturedQuad(s, {12, 12, 0}, -Y, Z, 0.4, 60, 20, mixSeed(seed, 503));   // x = +12, faces -x
  addTexturedQuad(s, {-12, -12, 0}, Y, Z, 0.4, 60, 20, mixSeed(seed, 504));  // x = -12, faces +x
  // Pillars: rejection-sampled footprints with a 0.25 m gap between them.
  SplitMix64 rng(mixSeed(seed, 600));
  std::vector<Eigen::Vector3d> placed;  // x, y, radius
  const double cell = 0.15;
  for (int attempt = 0; attempt < 2000 && placed.size() < 14; ++attempt) {
    const int kx = rng.uniformInt(2, 5);
    const int ky = rng.uniformInt(2, 5);
    const int kz = rng.uniformInt(8, 16);
    // Area-uniform radius, so the pillars fill the disc rather than crowd its centre.
    const double r = 0.3 + 4.3 * std::sqrt(rng.uniform());
    const double phi = rng.uniform(0.0, 2.0 * kPi);
    const double yaw = rng.uniform(0.0, kPi);
    const Eigen::Vector2d c(r * portableCos(phi), r * portableSin(phi));
    const double radius = 0.5 * cell * std::sqrt(static_cast<double>(kx * kx + ky * ky)) + 0.125;
    bool free = true;
    for (const auto& p : placed) {
      if ((c - p.head<2>()).norm() < radius + p.z()) free = false;
    }
    if (!free) continue;
    placed.emplace_back(c.x(), c.y(), radius);
    addBox(s, c, yaw, cell, kx, ky, kz, mixSeed(seed, 700 + placed.size()));
  }
  collectLandmarks(s);
  return s;
}

Scene makePlanarScene(uint64_t seed) {
  Scene s;
  addTexturedQuad(s, {-8, 4, -3}, {1, 0, 0}, {0, 0, 1}, 0.25, 64, 40, mixSeed(seed, 400));
  collectLandmarks(s);
  return s;
}

void collectLandmarks(Scene& scene, double min_contrast) {
  scene.landmarks.clear();
  int id = 0;
  for (std::size_t qi = 0; qi < scene.quads.size(); ++qi) {
    const TexturedQuad& q = scene.quads[qi];
    for (int j = 1; j < q.cells_v; ++j) {
      for (int i = 1; i < q.cells_u; ++i) {
        const auto a = static_cast<double>(q.cellValue(i - 1, j - 1));
        const auto b = static_cast<double>(q.cellValue(i, j - 1));
        const auto c = static_cast<double>(q.cellValue(i - 1, j));
        const auto d = static_cast<double>(q.cellValue(i, j));
        const double across_u = std::max(std::abs(b - a), std::abs(d - c));
        const double across_v = std::max(std::abs(c - a), std::abs(d - b));
        if (across_u < min_contrast || across_v < min_contrast) continue;
        Landmark3d l;
        l.id = id++;
        l.quad = static_cast<int>(qi);
        l.position = q.origin + (i * q.cell) * q.axis_u + (j * q.cell) * q.axis_v;
        scene.landmarks.push_back(l);
      }
    }
  }
}

}  // namespace epitrack::synth

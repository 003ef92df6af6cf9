#include "tools/render/overlay_renderer.hpp"

#include <algorithm>
#include <cmath>

namespace epitrack::render {
namespace {

// 16 sample positions per pixel in an "N-rooks" pattern: every sample has its own column and row
// (x = (i + 1/2) / 16, y = ((5 i + 3) mod 16 + 1/2) / 16, a rank-1 lattice), so a near-vertical or
// near-horizontal edge is located to 1/16 px instead of the 1/4 px of a regular 4x4 grid.
struct SampleOffset {
  double x, y;
};
constexpr SampleOffset makeOffset(int i) {
  return {(i + 0.5) / 16.0 - 0.5, ((5 * i + 3) % 16 + 0.5) / 16.0 - 0.5};
}
constexpr SampleOffset kSampleOffset[16] = {
    makeOffset(0),  makeOffset(1),  makeOffset(2),  makeOffset(3), makeOffset(4),  makeOffset(5),
    makeOffset(6),  makeOffset(7),  makeOffset(8),  makeOffset(9), makeOffset(10), makeOffset(11),
    makeOffset(12), makeOffset(13), makeOffset(14), makeOffset(15)};

const Eigen::Vector3d kLight = Eigen::Vector3d(0.35, -0.45, 0.82).normalized();
constexpr double kAmbient = 0.38;

Rgb8 shade(const Rgb8& c, double lambert) {
  const double f = kAmbient + (1.0 - kAmbient) * std::max(0.0, lambert);
  const auto s = [f](uint8_t v) {
    return static_cast<uint8_t>(std::clamp(std::lround(v * f), 0L, 255L));
  };
  return {s(c.r), s(c.g), s(c.b)};
}

}  // namespace

OverlayRenderer::OverlayRenderer(const CameraIntrinsics& intrinsics, double near_plane)
    : k_(intrinsics),
      near_(near_plane),
      row_end_(intrinsics.height - 1),
      width_(intrinsics.width),
      height_(intrinsics.height) {
  const auto px = static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_);
  depth_.assign(px * kSamples, 0.0F);
  color_.assign(px * kSamples, Rgb8{});
  dirty_.assign(px, 0);
  alpha_.allocate(width_, height_);
  premul_r_.allocate(width_, height_);
  premul_g_.allocate(width_, height_);
  premul_b_.allocate(width_, height_);
  alpha_.fill(0.0F);
}

void OverlayRenderer::clear() {
  for (std::size_t p = 0; p < dirty_.size(); ++p) {
    if (dirty_[p] == 0) continue;
    std::fill(depth_.begin() + static_cast<std::ptrdiff_t>(p * kSamples),
              depth_.begin() + static_cast<std::ptrdiff_t>((p + 1) * kSamples), 0.0F);
    dirty_[p] = 0;
  }
  alpha_.fill(0.0F);
}

bool OverlayRenderer::project(const Eigen::Vector3d& p_c, ScreenVertex& out) const {
  if (p_c.z() < near_ * 0.999) return false;
  out.x = k_.fx * p_c.x() / p_c.z() + k_.cx;
  out.y = k_.fy * p_c.y() / p_c.z() + k_.cy;
  out.inv_z = 1.0 / p_c.z();
  return std::isfinite(out.x) && std::isfinite(out.y);
}

void OverlayRenderer::setRollingShutter(const RollingShutter& shutter,
                                        const RollingShutterMotion& motion) {
  shutter_ = shutter;
  motion_ = motion;
}

bool OverlayRenderer::rolling() const {
  return shutter_.line_delay != 0.0 &&
         (motion_.angular != Eigen::Vector3d::Zero() || motion_.linear != Eigen::Vector3d::Zero());
}

Eigen::Isometry3d OverlayRenderer::rowPose(const Eigen::Isometry3d& T_wc, int y) const {
  // The row's exposure time is that of the sensor row, in the distorted image: the pinhole row y
  // is taken at the image's vertical centre line (x = cx), where its distorted row is
  // cy + fy yn (1 + k1 yn^2 + k2 yn^4); elsewhere along the row the distorted row differs by the
  // distortion's bend of a horizontal line (see docs/augmentation.md, rolling shutter).
  const double yn = (y - k_.cy) / k_.fy;
  const double yn2 = yn * yn;
  const double sensor_row = k_.cy + k_.fy * yn * (1.0 + k_.k1 * yn2 + k_.k2 * yn2 * yn2);
  PoseCw pose;
  pose.R_cw = T_wc.linear().transpose();
  pose.t_cw = -pose.R_cw * T_wc.translation();
  const PoseCw at = poseAtTime(pose, motion_, shutter_.rowTime(sensor_row));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = at.R_cw.transpose();
  T.translation() = at.centre();
  return T;
}

void OverlayRenderer::drawMesh(const Mesh& mesh, const Eigen::Isometry3d& T_wc) {
  if (!rolling()) {
    drawMeshAtPose(mesh, T_wc);
    return;
  }
  for (int y = 0; y < height_; ++y) {
    row_begin_ = row_end_ = y;
    drawMeshAtPose(mesh, rowPose(T_wc, y));
  }
  row_begin_ = 0;
  row_end_ = height_ - 1;
}

void OverlayRenderer::drawLines(const LineSet& lines, const Eigen::Isometry3d& T_wc) {
  if (!rolling()) {
    drawLinesAtPose(lines, T_wc);
    return;
  }
  for (int y = 0; y < height_; ++y) {
    row_begin_ = row_end_ = y;
    drawLinesAtPose(lines, rowPose(T_wc, y));
  }
  row_begin_ = 0;
  row_end_ = height_ - 1;
}

void OverlayRenderer::drawMeshAtPose(const Mesh& mesh, const Eigen::Isometry3d& T_wc) {
  const Eigen::Isometry3d T_cw = T_wc.inverse();
  const Eigen::Vector3d centre = T_wc.translation();
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Eigen::Vector3i& tri = mesh.triangles[t];
    const Eigen::Vector3d& a = mesh.vertices[static_cast<std::size_t>(tri[0])];
    const Eigen::Vector3d& b = mesh.vertices[static_cast<std::size_t>(tri[1])];
    const Eigen::Vector3d& c = mesh.vertices[static_cast<std::size_t>(tri[2])];
    const Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.dot(centre - a) <= 0.0) continue;  // back face (or seen edge-on)
    const Rgb8 color =
        mesh.shaded ? shade(mesh.colors[t], n.normalized().dot(kLight)) : mesh.colors[t];
    // Clip against the near plane z = near (Sutherland-Hodgman on one plane: up to 4 vertices).
    const Eigen::Vector3d in[3] = {T_cw * a, T_cw * b, T_cw * c};
    Eigen::Vector3d poly[4];
    int n_poly = 0;
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d& p = in[i];
      const Eigen::Vector3d& q = in[(i + 1) % 3];
      const bool p_in = p.z() >= near_;
      const bool q_in = q.z() >= near_;
      if (p_in) poly[n_poly++] = p;
      if (p_in != q_in) poly[n_poly++] = p + (near_ - p.z()) / (q.z() - p.z()) * (q - p);
    }
    if (n_poly < 3) continue;
    ScreenVertex sv[4];
    bool ok = true;
    for (int i = 0; i < n_poly; ++i) ok = ok && project(poly[i], sv[i]);
    if (!ok) continue;
    for (int i = 1; i + 1 < n_poly; ++i) rasterizeTriangle(sv[0], sv[i], sv[i + 1], color);
  }
}

void OverlayRenderer::drawLinesAtPose(const LineSet& lines, const Eigen::Isometry3d& T_wc) {
  const Eigen::Isometry3d T_cw = T_wc.inverse();
  for (std::size_t i = 0; i < lines.from.size(); ++i) {
    Eigen::Vector3d p = T_cw * lines.from[i];
    Eigen::Vector3d q = T_cw * lines.to[i];
    if (p.z() < near_ && q.z() < near_) continue;
    if (p.z() < near_) p = p + (near_ - p.z()) / (q.z() - p.z()) * (q - p);
    if (q.z() < near_) q = q + (near_ - q.z()) / (p.z() - q.z()) * (p - q);
    ScreenVertex a;
    ScreenVertex b;
    if (!project(p, a) || !project(q, b)) continue;
    Eigen::Vector2d d(b.x - a.x, b.y - a.y);
    const double len = d.norm();
    if (len < 1e-9) continue;
    const Eigen::Vector2d n = Eigen::Vector2d(-d.y(), d.x()) * (0.5 * lines.width_px / len);
    // Split long lines into pieces of at most 16 px: a thin diagonal triangle's bounding box
    // would otherwise cover most of the frame and the rasterizer would test every sample in it.
    // Screen position and 1/z are both linear along the projected segment, so pieces are exact.
    const int pieces = std::max(1, static_cast<int>(std::ceil(len / 16.0)));
    // Only the pieces that can reach the image and the rows being drawn: a line clipped at the
    // near plane projects millions of pixels long, and the rolling shutter draws it once per
    // row. A piece left out lies wholly more than its half width + 3 px outside them, where
    // rasterizeTriangle would draw nothing, so the result is the same.
    double s_lo = 0.0;
    double s_hi = 1.0;
    const double margin = 0.5 * lines.width_px + 3.0;
    const auto keep = [&](double from, double delta, double lo, double hi) {
      if (std::abs(delta) < 1e-12) {
        if (from < lo || from > hi) s_hi = -1.0;
        return;
      }
      const double s0 = (lo - from) / delta;
      const double s1 = (hi - from) / delta;
      s_lo = std::max(s_lo, std::min(s0, s1));
      s_hi = std::min(s_hi, std::max(s0, s1));
    };
    keep(a.x, b.x - a.x, -margin, width_ - 1 + margin);
    keep(a.y, b.y - a.y, row_begin_ - margin, row_end_ + margin);
    if (s_hi < s_lo) continue;
    const int k_begin = std::max(0, static_cast<int>(std::floor(s_lo * pieces)) - 1);
    const int k_end = std::min(pieces, static_cast<int>(std::ceil(s_hi * pieces)) + 1);
    for (int k = k_begin; k < k_end; ++k) {
      const double s0 = static_cast<double>(k) / pieces;
      const double s1 = static_cast<double>(k + 1) / pieces;
      const ScreenVertex p0{a.x + s0 * (b.x - a.x), a.y + s0 * (b.y - a.y),
                            a.inv_z + s0 * (b.inv_z - a.inv_z)};
      const ScreenVertex p1{a.x + s1 * (b.x - a.x), a.y + s1 * (b.y - a.y),
                            a.inv_z + s1 * (b.inv_z - a.inv_z)};
      const ScreenVertex a0{p0.x + n.x(), p0.y + n.y(), p0.inv_z};
      const ScreenVertex a1{p0.x - n.x(), p0.y - n.y(), p0.inv_z};
      const ScreenVertex b0{p1.x + n.x(), p1.y + n.y(), p1.inv_z};
      const ScreenVertex b1{p1.x - n.x(), p1.y - n.y(), p1.inv_z};
      rasterizeTriangle(a0, a1, b1, lines.color);
      rasterizeTriangle(a0, b1, b0, lines.color);
    }
  }
}

// Coverage of the 16 sample points of each pixel by edge functions, the top-left rule on shared
// edges, depth tested on interpolated 1/z.
void OverlayRenderer::rasterizeTriangle(const ScreenVertex& a0, const ScreenVertex& b0,
                                        const ScreenVertex& c0, const Rgb8& color) {
  ScreenVertex a = a0;
  ScreenVertex b = b0;
  ScreenVertex c = c0;
  double area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
  if (std::abs(area) < 1e-12) return;
  if (area < 0.0) {  // make the winding consistent (screen y is down)
    std::swap(b, c);
    area = -area;
  }
  const double min_x = std::min({a.x, b.x, c.x});
  const double max_x = std::max({a.x, b.x, c.x});
  const double min_y = std::min({a.y, b.y, c.y});
  const double max_y = std::max({a.y, b.y, c.y});
  const int x0 = std::max(0, static_cast<int>(std::floor(min_x + 0.5)) - 1);
  const int x1 = std::min(width_ - 1, static_cast<int>(std::ceil(max_x - 0.5)) + 1);
  const int y0 = std::max(row_begin_, static_cast<int>(std::floor(min_y + 0.5)) - 1);
  const int y1 = std::min(row_end_, static_cast<int>(std::ceil(max_y - 0.5)) + 1);
  if (x0 > x1 || y0 > y1) return;
  // Edge function E_ab(p) = (b - a) x (p - a) >= 0 inside. Top-left rule: a sample exactly on an
  // edge belongs to the triangle only for top or left edges, so shared edges are drawn once.
  struct Edge {
    double ex, ey, cx0, cy0;
    bool inclusive;
  };
  const auto makeEdge = [](const ScreenVertex& p, const ScreenVertex& q) {
    const double ex = q.x - p.x;
    const double ey = q.y - p.y;
    const bool top = ey == 0.0 && ex > 0.0;
    const bool left = ey < 0.0;
    return Edge{ex, ey, p.x, p.y, top || left};
  };
  const Edge edges[3] = {makeEdge(a, b), makeEdge(b, c), makeEdge(c, a)};
  const double inv_area = 1.0 / area;
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const std::size_t pixel = static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) +
                                static_cast<std::size_t>(x);
      bool touched = false;
      for (int s = 0; s < kSamples; ++s) {
        const double sx = x + kSampleOffset[s].x;
        const double sy = y + kSampleOffset[s].y;
        double w[3];
        bool inside = true;
        for (int e = 0; e < 3 && inside; ++e) {
          const Edge& E = edges[e];
          w[e] = E.ex * (sy - E.cy0) - E.ey * (sx - E.cx0);
          inside = w[e] > 0.0 || (w[e] == 0.0 && E.inclusive);
        }
        if (!inside) continue;
        // Barycentric weight of a vertex = edge function of the opposite edge / area.
        const double la = w[1] * inv_area;
        const double lb = w[2] * inv_area;
        const double lc = w[0] * inv_area;
        const auto inv_z = static_cast<float>(la * a.inv_z + lb * b.inv_z + lc * c.inv_z);
        const std::size_t idx = pixel * kSamples + static_cast<std::size_t>(s);
        if (inv_z > depth_[idx]) {
          depth_[idx] = inv_z;
          color_[idx] = color;
          touched = true;
        }
      }
      if (touched) dirty_[pixel] = 1;
    }
  }
}

void OverlayRenderer::resolve() {
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) {
      const std::size_t pixel = static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) +
                                static_cast<std::size_t>(x);
      float n = 0.0F;
      float r = 0.0F;
      float g = 0.0F;
      float b = 0.0F;
      if (dirty_[pixel] != 0) {
        for (int s = 0; s < kSamples; ++s) {
          const std::size_t idx = pixel * kSamples + static_cast<std::size_t>(s);
          if (depth_[idx] <= 0.0F) continue;
          n += 1.0F;
          r += color_[idx].r;
          g += color_[idx].g;
          b += color_[idx].b;
        }
      }
      alpha_(x, y) = n / kSamples;
      premul_r_(x, y) = r / kSamples;
      premul_g_(x, y) = g / kSamples;
      premul_b_(x, y) = b / kSamples;
    }
  }
}

void OverlayRenderer::composite(ImageView<Rgb8> frame) {
  resolve();
  const bool warp = k_.hasDistortion();
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) {
      float a;
      float r;
      float g;
      float b;
      if (!warp) {
        a = alpha_(x, y);
        r = premul_r_(x, y);
        g = premul_g_(x, y);
        b = premul_b_(x, y);
      } else {
        // The output pixel sees the ideal-camera position of its undistorted ray.
        const double dx = (x - k_.cx) / k_.fx;
        const double dy = (y - k_.cy) / k_.fy;
        double ux = dx;
        double uy = dy;
        for (int i = 0; i < 20; ++i) {
          const double r2 = ux * ux + uy * uy;
          const double f = 1.0 + k_.k1 * r2 + k_.k2 * r2 * r2;
          ux = dx / f;
          uy = dy / f;
        }
        const double px = k_.fx * ux + k_.cx;
        const double py = k_.fy * uy + k_.cy;
        const int ix = static_cast<int>(std::floor(px));
        const int iy = static_cast<int>(std::floor(py));
        if (ix < 0 || iy < 0 || ix + 1 >= width_ || iy + 1 >= height_) continue;
        const auto fx = static_cast<float>(px - ix);
        const auto fy = static_cast<float>(py - iy);
        const auto bil = [&](const Image<float>& im) {
          return (1 - fy) * ((1 - fx) * im(ix, iy) + fx * im(ix + 1, iy)) +
                 fy * ((1 - fx) * im(ix, iy + 1) + fx * im(ix + 1, iy + 1));
        };
        a = bil(alpha_);
        r = bil(premul_r_);
        g = bil(premul_g_);
        b = bil(premul_b_);
      }
      if (a <= 0.0F) continue;
      Rgb8& p = frame(x, y);
      const auto mix = [a](uint8_t under, float over) {
        return static_cast<uint8_t>(
            std::clamp(std::lround(over + (1.0F - a) * static_cast<float>(under)), 0L, 255L));
      };
      p = {mix(p.r, r), mix(p.g, g), mix(p.b, b)};
    }
  }
}

Mesh makeBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, Rgb8 color) {
  Mesh m;
  for (int i = 0; i < 8; ++i) {
    m.vertices.emplace_back((i & 1) != 0 ? hi.x() : lo.x(), (i & 2) != 0 ? hi.y() : lo.y(),
                            (i & 4) != 0 ? hi.z() : lo.z());
  }
  // Faces as quads (outward counter-clockwise), split into two triangles each.
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    m.triangles.emplace_back(q[0], q[1], q[2]);
    m.triangles.emplace_back(q[0], q[2], q[3]);
    m.colors.push_back(color);
    m.colors.push_back(color);
  }
  return m;
}

namespace {
void append(Mesh& dst, const Mesh& src) {
  const int base = static_cast<int>(dst.vertices.size());
  dst.vertices.insert(dst.vertices.end(), src.vertices.begin(), src.vertices.end());
  for (const auto& t : src.triangles)
    dst.triangles.emplace_back(t + Eigen::Vector3i::Constant(base));
  dst.colors.insert(dst.colors.end(), src.colors.begin(), src.colors.end());
}

// A square pyramid on the square of half side `half` centred at `centre` (horizontal), apex
// `height` above it: four sides to the apex (outward counter-clockwise) and the underside.
void appendPyramid(Mesh& m, const Eigen::Vector3d& centre, double half, double height, Rgb8 sides,
                   Rgb8 underside) {
  const int v0 = static_cast<int>(m.vertices.size());
  m.vertices.push_back(centre + Eigen::Vector3d(-half, -half, 0.0));
  m.vertices.push_back(centre + Eigen::Vector3d(half, -half, 0.0));
  m.vertices.push_back(centre + Eigen::Vector3d(half, half, 0.0));
  m.vertices.push_back(centre + Eigen::Vector3d(-half, half, 0.0));
  m.vertices.push_back(centre + Eigen::Vector3d(0.0, 0.0, height));
  for (int i = 0; i < 4; ++i) {
    m.triangles.emplace_back(v0 + i, v0 + (i + 1) % 4, v0 + 4);
    m.colors.push_back(sides);
  }
  m.triangles.emplace_back(v0, v0 + 3, v0 + 2);
  m.triangles.emplace_back(v0, v0 + 2, v0 + 1);
  m.colors.push_back(underside);
  m.colors.push_back(underside);
}
}  // namespace

Mesh makeCube(const Eigen::Vector3d& anchor, double scale) {
  const double h = 0.125 * scale;
  return makeBox(anchor + Eigen::Vector3d(-h, -h, 0.0), anchor + Eigen::Vector3d(h, h, 2.0 * h),
                 Rgb8{230, 160, 40});
}

Mesh makeTowers(const Eigen::Vector3d& anchor, double scale) {
  Mesh m;
  const double half = 0.06 * scale;
  const double height = 0.45 * scale;
  const double roof = 0.14 * scale;
  for (const double side : {-1.0, 1.0}) {
    const Eigen::Vector3d base = anchor + Eigen::Vector3d(side * 0.15 * scale, 0.0, 0.0);
    append(m, makeBox(base + Eigen::Vector3d(-half, -half, 0.0),
                      base + Eigen::Vector3d(half, half, height), Rgb8{215, 195, 160}));
    appendPyramid(m, base + Eigen::Vector3d(0.0, 0.0, height), half * 1.25, roof, Rgb8{180, 50, 40},
                  Rgb8{120, 35, 30});
  }
  return m;
}

Mesh makeUpArrow(const Eigen::Vector3d& base, double length) {
  Mesh m;
  const double shaft = 0.025 * length;
  const double shaft_top = 0.72 * length;
  const Rgb8 yellow{250, 205, 40};
  append(m, makeBox(base + Eigen::Vector3d(-shaft, -shaft, 0.0),
                    base + Eigen::Vector3d(shaft, shaft, shaft_top), yellow));
  appendPyramid(m, base + Eigen::Vector3d(0.0, 0.0, shaft_top), 0.09 * length, length - shaft_top,
                yellow, Rgb8{200, 160, 30});
  return m;
}

Mesh makeAxes(const Eigen::Vector3d& origin, double scale) {
  Mesh m;
  const double len = 0.4 * scale;
  const double t = 0.012 * scale;
  append(m, makeBox(origin + Eigen::Vector3d(0, -t, -t), origin + Eigen::Vector3d(len, t, t),
                    Rgb8{230, 40, 40}));
  append(m, makeBox(origin + Eigen::Vector3d(-t, 0, -t), origin + Eigen::Vector3d(t, len, t),
                    Rgb8{40, 200, 60}));
  append(m, makeBox(origin + Eigen::Vector3d(-t, -t, 0), origin + Eigen::Vector3d(t, t, len),
                    Rgb8{50, 90, 240}));
  m.shaded = true;
  return m;
}

LineSet makeGroundGrid(const Eigen::Vector3d& centre, double half_extent, double step) {
  LineSet g;
  g.color = Rgb8{90, 220, 255};
  g.width_px = 1.2;
  const int n = static_cast<int>(std::floor(half_extent / step + 1e-9));
  for (int i = -n; i <= n; ++i) {
    const double o = i * step;
    g.from.push_back(centre + Eigen::Vector3d(o, -half_extent, 0.0));
    g.to.push_back(centre + Eigen::Vector3d(o, half_extent, 0.0));
    g.from.push_back(centre + Eigen::Vector3d(-half_extent, o, 0.0));
    g.to.push_back(centre + Eigen::Vector3d(half_extent, o, 0.0));
  }
  return g;
}

}  // namespace epitrack::render

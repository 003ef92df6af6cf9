#include "tools/render/overlay_renderer.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace render = epitrack::render;
using epitrack::CameraIntrinsics;

namespace {

// A camera 3 units from the origin looking at (0, 0, 0.1), z up, slightly from above.
Eigen::Isometry3d lookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d f = (target - eye).normalized();
  const Eigen::Vector3d r = f.cross(Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Matrix3d R;
  R.col(0) = r;
  R.col(1) = f.cross(r);
  R.col(2) = f;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = eye;
  return T;
}

Eigen::Vector2d projectPoint(const CameraIntrinsics& k, const Eigen::Isometry3d& T_wc,
                             const Eigen::Vector3d& p) {
  const Eigen::Vector3d c = T_wc.inverse() * p;
  return {k.fx * c.x() / c.z() + k.cx, k.fy * c.y() / c.z() + k.cy};
}

struct Moments {
  double area = 0, cx = 0, cy = 0, sxx = 0, syy = 0, sxy = 0;
};

// Area, centroid and second central moments of a polygon (Green's theorem).
Moments polygonMoments(const std::vector<Eigen::Vector2d>& p) {
  double a = 0, mx = 0, my = 0, mxx = 0, myy = 0, mxy = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Eigen::Vector2d& u = p[i];
    const Eigen::Vector2d& v = p[(i + 1) % p.size()];
    const double c = u.x() * v.y() - v.x() * u.y();
    a += c;
    mx += (u.x() + v.x()) * c;
    my += (u.y() + v.y()) * c;
    mxx += (u.x() * u.x() + u.x() * v.x() + v.x() * v.x()) * c;
    myy += (u.y() * u.y() + u.y() * v.y() + v.y() * v.y()) * c;
    mxy += (u.x() * v.y() + 2 * u.x() * u.y() + 2 * v.x() * v.y() + v.x() * u.y()) * c;
  }
  Moments m;
  m.area = a / 2;
  m.cx = mx / (6 * m.area);
  m.cy = my / (6 * m.area);
  m.sxx = mxx / (12 * m.area) - m.cx * m.cx;
  m.syy = myy / (12 * m.area) - m.cy * m.cy;
  m.sxy = mxy / (24 * m.area) - m.cx * m.cy;
  m.area = std::abs(m.area);
  return m;
}

// The same moments of a coverage image (each pixel a unit square at its centre).
Moments coverageMoments(epitrack::ImageView<const float> a) {
  Moments m;
  for (int y = 0; y < a.height; ++y) {
    for (int x = 0; x < a.width; ++x) {
      const auto w = static_cast<double>(a(x, y));
      m.area += w;
      m.cx += w * x;
      m.cy += w * y;
      m.sxx += w * (x * x + 1.0 / 12.0);
      m.syy += w * (y * y + 1.0 / 12.0);
      m.sxy += w * x * y;
    }
  }
  m.cx /= m.area;
  m.cy /= m.area;
  m.sxx = m.sxx / m.area - m.cx * m.cx;
  m.syy = m.syy / m.area - m.cy * m.cy;
  m.sxy = m.sxy / m.area - m.cx * m.cy;
  return m;
}

}  // namespace

TEST_CASE("Each visible cube face covers exactly its analytic projection", "[render]") {
  const CameraIntrinsics k = CameraIntrinsics::centered(320, 240, 300.0);
  const Eigen::Isometry3d T_wc = lookAt({2.2, -1.9, 1.4}, {0.0, 0.0, 0.1});
  const render::Mesh cube = render::makeCube(Eigen::Vector3d(0.05, -0.02, 0.0), 2.0);
  int visible = 0;
  for (std::size_t f = 0; f < 6; ++f) {
    render::Mesh face;
    face.vertices = cube.vertices;
    face.triangles = {cube.triangles[2 * f], cube.triangles[2 * f + 1]};
    face.colors = {cube.colors[2 * f], cube.colors[2 * f + 1]};
    const Eigen::Vector3d n =
        (cube.vertices[static_cast<std::size_t>(face.triangles[0][1])] -
         cube.vertices[static_cast<std::size_t>(face.triangles[0][0])])
            .cross(cube.vertices[static_cast<std::size_t>(face.triangles[0][2])] -
                   cube.vertices[static_cast<std::size_t>(face.triangles[0][0])]);
    const bool front = n.dot(T_wc.translation() -
                             cube.vertices[static_cast<std::size_t>(face.triangles[0][0])]) > 0;
    render::OverlayRenderer r(k);
    r.drawMesh(face, T_wc);
    r.resolve();
    double total = 0;
    for (int y = 0; y < 240; ++y)
      for (int x = 0; x < 320; ++x) total += static_cast<double>(r.coverage()(x, y));
    if (!front) {
      REQUIRE(total == 0.0);  // a hidden face is not drawn
      continue;
    }
    ++visible;
    std::vector<Eigen::Vector2d> poly;
    for (int i :
         {face.triangles[0][0], face.triangles[0][1], face.triangles[0][2], face.triangles[1][2]})
      poly.push_back(projectPoint(k, T_wc, cube.vertices[static_cast<std::size_t>(i)]));
    const Moments want = polygonMoments(poly);
    const Moments got = coverageMoments(r.coverage());
    INFO("face " << f << ": area " << got.area << " vs " << want.area << ", centroid (" << got.cx
                 << ", " << got.cy << ") vs (" << want.cx << ", " << want.cy << ")");
    REQUIRE(got.area == Approx(want.area).epsilon(0.003));
    REQUIRE(std::abs(got.cx - want.cx) < 0.02);
    REQUIRE(std::abs(got.cy - want.cy) < 0.02);
    REQUIRE(got.sxx == Approx(want.sxx).epsilon(0.01));
    REQUIRE(got.syy == Approx(want.syy).epsilon(0.01));
    REQUIRE(std::abs(got.sxy - want.sxy) < 0.01 * std::sqrt(want.sxx * want.syy));
  }
  REQUIRE(visible == 3);
}

namespace {

double bilinear(epitrack::ImageView<const float> a, const Eigen::Vector2d& p) {
  const int x = static_cast<int>(std::floor(p.x()));
  const int y = static_cast<int>(std::floor(p.y()));
  const double fx = p.x() - x;
  const double fy = p.y() - y;
  const auto at = [&](int u, int v) { return static_cast<double>(a(u, v)); };
  return (1 - fy) * ((1 - fx) * at(x, y) + fx * at(x + 1, y)) +
         fy * ((1 - fx) * at(x, y + 1) + fx * at(x + 1, y + 1));
}

// The silhouette edge from P to Q as measured in the coverage image: along normals at 20-80 % of
// the edge, the 0.5 crossing of the interpolated coverage; a line fitted through the crossings.
// Returns the line as (point, unit direction).
std::pair<Eigen::Vector2d, Eigen::Vector2d> measuredEdge(epitrack::ImageView<const float> a,
                                                         const Eigen::Vector2d& P,
                                                         const Eigen::Vector2d& Q,
                                                         const Eigen::Vector2d& inside) {
  const Eigen::Vector2d d = (Q - P).normalized();
  Eigen::Vector2d n(-d.y(), d.x());
  if (n.dot(inside - P) > 0) n = -n;  // n points out of the silhouette
  std::vector<Eigen::Vector2d> pts;
  for (double t = 0.2; t <= 0.8001; t += 0.05) {
    const Eigen::Vector2d m = P + t * (Q - P);
    double prev = bilinear(a, m - 3.0 * n);
    for (double s = -3.0 + 0.02; s <= 3.0; s += 0.02) {
      const double cur = bilinear(a, m + s * n);
      if (prev >= 0.5 && cur < 0.5) {
        const double f = (prev - 0.5) / (prev - cur);
        pts.push_back(m + (s - 0.02 + 0.02 * f) * n);
        break;
      }
      prev = cur;
    }
  }
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const auto& p : pts) c += p;
  c /= static_cast<double>(pts.size());
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const auto& p : pts) cov += (p - c) * (p - c).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cov);
  return {c, es.eigenvectors().col(1)};
}

Eigen::Vector2d intersect(const std::pair<Eigen::Vector2d, Eigen::Vector2d>& l1,
                          const std::pair<Eigen::Vector2d, Eigen::Vector2d>& l2) {
  Eigen::Matrix2d A;
  A.col(0) = l1.second;
  A.col(1) = -l2.second;
  const Eigen::Vector2d st = A.colPivHouseholderQr().solve(l2.first - l1.first);
  return l1.first + st.x() * l1.second;
}

}  // namespace

TEST_CASE("Cube vertices land at their analytic projections within 0.5 px", "[render]") {
  // The silhouette of the cube is the convex hull of its projected vertices. Each hull vertex is
  // measured in the rendered coverage as the intersection of its two silhouette edges.
  const CameraIntrinsics k = CameraIntrinsics::centered(320, 240, 300.0);
  const Eigen::Isometry3d T_wc = lookAt({2.4, -1.6, 1.3}, {0.0, 0.0, 0.2});
  render::Mesh cube = render::makeCube(Eigen::Vector3d::Zero(), 2.4);
  cube.shaded = false;
  render::OverlayRenderer r(k);
  r.drawMesh(cube, T_wc);
  r.resolve();
  std::vector<Eigen::Vector2d> pts;
  for (const auto& v : cube.vertices) pts.push_back(projectPoint(k, T_wc, v));
  std::sort(pts.begin(), pts.end(),
            [](auto a, auto b) { return a.x() != b.x() ? a.x() < b.x() : a.y() < b.y(); });
  std::vector<Eigen::Vector2d> hull;  // Andrew's monotone chain
  const auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a,
                        const Eigen::Vector2d& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  for (int pass = 0; pass < 2; ++pass) {
    const std::size_t start = hull.size();
    for (const auto& p : pts) {
      while (hull.size() >= start + 2 && cross(hull[hull.size() - 2], hull.back(), p) <= 0)
        hull.pop_back();
      hull.push_back(p);
    }
    hull.pop_back();
    std::reverse(pts.begin(), pts.end());
  }
  REQUIRE(hull.size() == 6);
  Eigen::Vector2d inside = Eigen::Vector2d::Zero();
  for (const auto& h : hull) inside += h;
  inside /= static_cast<double>(hull.size());
  double worst = 0;
  for (std::size_t i = 0; i < hull.size(); ++i) {
    const auto& prev = hull[(i + hull.size() - 1) % hull.size()];
    const auto& next = hull[(i + 1) % hull.size()];
    const Eigen::Vector2d measured = intersect(measuredEdge(r.coverage(), prev, hull[i], inside),
                                               measuredEdge(r.coverage(), hull[i], next, inside));
    worst = std::max(worst, (measured - hull[i]).norm());
  }
  INFO("largest vertex error " << worst << " px");
  REQUIRE(worst < 0.5);
  REQUIRE(worst < 0.2);  // measured 0.14 (16 N-rooks samples; the edge fit adds its own error)
  // And the drawn area is the silhouette's area.
  const Moments want = polygonMoments(hull);
  const Moments got = coverageMoments(r.coverage());
  REQUIRE(got.area == Approx(want.area).epsilon(0.003));
  REQUIRE(std::abs(got.cx - want.cx) < 0.02);
  REQUIRE(std::abs(got.cy - want.cy) < 0.02);
}

TEST_CASE("Hidden faces are not drawn and depth order is respected", "[render]") {
  const CameraIntrinsics k = CameraIntrinsics::centered(200, 150, 180.0);
  const Eigen::Isometry3d T_wc = lookAt({0.0, -3.0, 0.3}, {0.0, 0.0, 0.3});
  render::Mesh near_box =
      render::makeBox({-0.2, -0.6, 0.1}, {0.2, -0.4, 0.5}, render::Rgb8{255, 0, 0});
  render::Mesh far_box =
      render::makeBox({-0.6, 0.4, 0.0}, {0.6, 0.6, 0.6}, render::Rgb8{0, 255, 0});
  near_box.shaded = false;
  far_box.shaded = false;
  epitrack::Image<render::Rgb8> frame(200, 150);
  for (int order = 0; order < 2; ++order) {
    frame.fill(render::Rgb8{0, 0, 0});
    render::OverlayRenderer r(k);
    if (order == 0) {
      r.drawMesh(near_box, T_wc);
      r.drawMesh(far_box, T_wc);
    } else {
      r.drawMesh(far_box, T_wc);
      r.drawMesh(near_box, T_wc);
    }
    r.composite(frame.view());
    // The image centre sees the near box whatever the drawing order.
    const Eigen::Vector2d c = projectPoint(k, T_wc, {0.0, -0.6, 0.3});
    const render::Rgb8 centre =
        frame(static_cast<int>(std::lround(c.x())), static_cast<int>(std::lround(c.y())));
    REQUIRE(centre == render::Rgb8{255, 0, 0});
    const Eigen::Vector2d side = projectPoint(k, T_wc, {0.5, 0.4, 0.3});
    REQUIRE(frame(static_cast<int>(std::lround(side.x())),
                  static_cast<int>(std::lround(side.y()))) == render::Rgb8{0, 255, 0});
  }
}

TEST_CASE("Objects behind the camera draw nothing: objects through the near plane are clipped",
          "[render]") {
  const CameraIntrinsics k = CameraIntrinsics::centered(160, 120, 150.0);
  const Eigen::Isometry3d T_wc = lookAt({0.0, 0.0, 1.0}, {0.0, 5.0, 1.0});  // looking along +y
  render::OverlayRenderer r(k);
  r.drawMesh(render::makeTowers({0.0, -2.0, 0.0}, 2.0), T_wc);  // behind
  r.drawMesh(render::makeCube({0.0, -1.0, 0.5}, 1.0), T_wc);
  r.resolve();
  double total = 0;
  for (int y = 0; y < 120; ++y)
    for (int x = 0; x < 160; ++x) total += static_cast<double>(r.coverage()(x, y));
  REQUIRE(total == 0.0);
  // A ground grid that extends behind the camera: only the floor below the horizon is drawn.
  render::OverlayRenderer g(k);
  g.drawLines(render::makeGroundGrid({0.0, 0.0, 0.0}, 5.0, 0.5), T_wc);
  g.resolve();
  double above = 0;
  double below = 0;
  for (int y = 0; y < 120; ++y) {
    for (int x = 0; x < 160; ++x) {
      REQUIRE(std::isfinite(g.coverage()(x, y)));
      (y < 59 ? above : below) += static_cast<double>(g.coverage()(x, y));
    }
  }
  REQUIRE(above == 0.0);
  REQUIRE(below > 100.0);
}

TEST_CASE("Compositing blends by coverage and leaves untouched pixels alone", "[render]") {
  const CameraIntrinsics k = CameraIntrinsics::centered(64, 48, 60.0);
  const Eigen::Isometry3d T_wc = lookAt({0.0, -2.0, 0.0}, {0.0, 0.0, 0.0});
  render::Mesh box =
      render::makeBox({-0.3, -0.3, -0.3}, {0.3, 0.3, 0.3}, render::Rgb8{200, 100, 50});
  box.shaded = false;
  epitrack::Image<render::Rgb8> frame(64, 48);
  frame.fill(render::Rgb8{10, 20, 30});
  render::OverlayRenderer r(k);
  r.drawMesh(box, T_wc);
  r.composite(frame.view());
  REQUIRE(frame(0, 0) == render::Rgb8{10, 20, 30});
  REQUIRE(frame(32, 24) == render::Rgb8{200, 100, 50});
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) {
      const auto a = static_cast<double>(r.coverage()(x, y));
      const double expect = 10 + a * (200 - 10);
      REQUIRE(std::abs(frame(x, y).r - expect) <= 1.0);
    }
  }
}

#include "tools/render/report_views.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tools/render/report_html.hpp"

namespace epitrack::render {

using namespace report_html;  // NOLINT(google-build-using-namespace): the section helpers

namespace {

// A point cloud as grey dots at (X(u[i]), Y(v[i])) in SVG pixels, those outside width x height
// left out.
template <typename MapX, typename MapY>
std::string dots(const std::string& series, const std::vector<double>& u,
                 const std::vector<double>& v, MapX X, MapY Y, double width, double height,
                 double radius) {
  std::string svg = "<g data-series=\"" + series + "\" data-count=\"" + std::to_string(u.size()) +
                    "\" fill=\"#555\" fill-opacity=\"0.55\">";
  for (std::size_t i = 0; i < u.size(); ++i) {
    const double x = X(u[i]), y = Y(v[i]);
    if (x < 0 || x > width || y < 0 || y > height) continue;
    svg += "<circle cx=\"" + px(x) + "\" cy=\"" + px(y) + "\" r=\"" + px(radius) + "\"/>";
  }
  return svg + "</g>\n";
}

}  // namespace

std::string topViewSection(const io::Reconstruction& rec, const ReportOptions& options) {
  // Scene frame: with a ground plane z is up, so the top view is the x-y plane; the first-camera
  // frame keeps the camera axes (y down), so its top view is x-z.
  const bool z_up = rec.ground != "none";
  auto u = [](const Eigen::Vector3d& p) { return p.x(); };
  auto v = [&](const Eigen::Vector3d& p) { return z_up ? p.y() : p.z(); };
  std::vector<double> pu, pv, cu, cv;
  for (const auto& p : rec.points)
    if (p.X.allFinite()) {
      pu.push_back(u(p.X));
      pv.push_back(v(p.X));
    }
  for (const auto& c : rec.cameras)
    if (c.solved && c.p_wc.allFinite()) {
      cu.push_back(u(c.p_wc));
      cv.push_back(v(c.p_wc));
    }
  // Range: every camera and the central 96% of the points, square pixels.
  double u0 = quantile(pu, 0.02), u1 = quantile(pu, 0.98);
  double v0 = quantile(pv, 0.02), v1 = quantile(pv, 0.98);
  if (!std::isfinite(u0)) u0 = u1 = v0 = v1 = 0.0;
  for (std::size_t i = 0; i < cu.size(); ++i) {
    u0 = std::min(u0, cu[i]);
    u1 = std::max(u1, cu[i]);
    v0 = std::min(v0, cv[i]);
    v1 = std::max(v1, cv[i]);
  }
  constexpr double kSize = 520, kMargin = 24;
  const double span = std::max({u1 - u0, v1 - v0, 1e-6}) * 1.08;
  const double uc = 0.5 * (u0 + u1), vc = 0.5 * (v0 + v1);
  const double scale = (kSize - 2 * kMargin) / span;
  auto X = [&](double a) { return kSize / 2 + (a - uc) * scale; };
  auto Y = [&](double b) { return kSize / 2 - (b - vc) * scale; };  // up the page = +y (or +z)
  std::string svg = "<svg id=\"plot-top-view\" class=\"plot square\" viewBox=\"0 0 " + px(kSize) +
                    " " + px(kSize) + "\" xmlns=\"http://www.w3.org/2000/svg\" role=\"img\">\n";
  svg += "<rect class=\"frame\" x=\"0.5\" y=\"0.5\" width=\"" + px(kSize - 1) + "\" height=\"" +
         px(kSize - 1) + "\"/>\n";
  // A scale bar of a 1-2-5 length about a fifth of the view.
  const double bar = niceStep(0.0, span, 5);
  svg += "<line class=\"scalebar\" x1=\"" + px(kMargin) + "\" y1=\"" + px(kSize - 12) + "\" x2=\"" +
         px(kMargin + bar * scale) + "\" y2=\"" + px(kSize - 12) + "\"/><text class=\"tick\" x=\"" +
         px(kMargin + bar * scale + 6) + "\" y=\"" + px(kSize - 8) + "\">" + tickLabel(bar, bar) +
         " scene units</text>\n";
  // Scene axes at the origin.
  svg += "<line class=\"axis-u\" x1=\"" + px(X(0)) + "\" y1=\"" + px(Y(0)) + "\" x2=\"" +
         px(X(0) + 40) + "\" y2=\"" + px(Y(0)) + "\"/><line class=\"axis-v\" x1=\"" + px(X(0)) +
         "\" y1=\"" + px(Y(0)) + "\" x2=\"" + px(X(0)) + "\" y2=\"" + px(Y(0) - 40) + "\"/>\n";
  svg += "<text class=\"tick\" x=\"" + px(X(0) + 42) + "\" y=\"" + px(Y(0) + 4) +
         "\">x</text><text class=\"tick\" x=\"" + px(X(0) - 3) + "\" y=\"" + px(Y(0) - 44) + "\">" +
         (z_up ? "y" : "z") + "</text>\n";
  if (z_up)  // +z comes out of the page: the usual "arrow tip towards the viewer" symbol
    svg += "<g class=\"up-out\"><circle cx=\"" + px(X(0) - 14) + "\" cy=\"" + px(Y(0) + 14) +
           "\" r=\"6\" fill=\"none\" stroke=\"#b7950b\" stroke-width=\"2\"/><circle cx=\"" +
           px(X(0) - 14) + "\" cy=\"" + px(Y(0) + 14) +
           "\" r=\"2\" fill=\"#b7950b\"/><title>up (+z) points out of the page</title></g>\n";
  svg += dots("points", pu, pv, X, Y, kSize, kSize, 1.6);
  svg += "<g data-series=\"camera_path\" data-count=\"" + std::to_string(cu.size()) +
         "\" data-u=\"" + dataValues(cu) + "\" data-v=\"" + dataValues(cv) + "\">";
  std::string path;
  for (std::size_t i = 0; i < cu.size(); ++i) {
    if (i > 0) path += ' ';
    path += px(X(cu[i]));
    path += ',';
    path += px(Y(cv[i]));
  }
  if (!path.empty()) {
    svg += "<polyline class=\"path\" points=\"" + path + "\"/>";
    svg += "<circle class=\"start\" cx=\"" + px(X(cu.front())) + "\" cy=\"" + px(Y(cv.front())) +
           "\" r=\"5\"><title>first solved camera</title></circle>";
    svg += "<circle class=\"end\" cx=\"" + px(X(cu.back())) + "\" cy=\"" + px(Y(cv.back())) +
           "\" r=\"5\"><title>last solved camera</title></circle>";
  }
  svg += "</g>\n";
  if (options.has_object && options.object_at.allFinite()) {
    const double ox = X(u(options.object_at)), oy = Y(v(options.object_at));
    svg += "<g data-series=\"object\" data-values=\"" + dataNumber(u(options.object_at)) + " " +
           dataNumber(v(options.object_at)) + "\"><rect class=\"object\" x=\"" + px(ox - 5) +
           "\" y=\"" + px(oy - 5) + "\" width=\"10\" height=\"10\"><title>virtual object (" +
           escapeHtml(options.render_object) + ")</title></rect></g>\n";
  }
  return figure("top-view", "Top view: camera path and point cloud", svg,
                std::string("Seen from above in the scene frame (") +
                    (z_up ? "x-y plane, z (up) out of the page: the yellow circled dot"
                          : "x-z plane of the first camera") +
                    "): " + std::to_string(cu.size()) +
                    " camera centres (green start, red end) over " + std::to_string(pu.size()) +
                    " points (central 96% framed)" +
                    (options.has_object ? "; the orange square is the virtual object" : "") + ".");
}

namespace {

// The horizontal axis of the side view: the direction (in the ground's x-y plane) along which the
// cameras and points spread most, so the view is broadside to the scene (principal component).
Eigen::Vector2d sideViewAxis(const io::Reconstruction& rec) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  std::vector<Eigen::Vector2d> xy;
  for (const auto& c : rec.cameras)
    if (c.solved && c.p_wc.allFinite()) xy.emplace_back(c.p_wc.x(), c.p_wc.y());
  for (const auto& p : rec.points)
    if (p.X.allFinite()) xy.emplace_back(p.X.x(), p.X.y());
  if (xy.size() < 2) return Eigen::Vector2d::UnitX();
  for (const auto& q : xy) mean += q;
  mean /= static_cast<double>(xy.size());
  double sxx = 0.0, sxy = 0.0, syy = 0.0;
  for (const auto& q : xy) {
    const Eigen::Vector2d d = q - mean;
    sxx += d.x() * d.x();
    sxy += d.x() * d.y();
    syy += d.y() * d.y();
  }
  // Major axis of the 2x2 scatter matrix: angle 0.5 atan2(2 sxy, sxx - syy).
  const double angle = 0.5 * std::atan2(2.0 * sxy, sxx - syy);
  Eigen::Vector2d axis(std::cos(angle), std::sin(angle));
  if (!axis.allFinite()) return Eigen::Vector2d::UnitX();
  return axis.x() < 0.0 ? Eigen::Vector2d(-axis) : axis;  // keep +x to the right when possible
}

// What a user should double-check about the scene frame (empty when nothing).
std::vector<std::string> sceneFrameWarnings(const io::Reconstruction& rec, bool has_object) {
  std::vector<std::string> w;
  if (rec.ground == "none")
    w.push_back(
        "No ground: the scene frame is the first camera's (-y up). Objects stand in it, "
        "which is level only if the first frame was; give --origin to choose.");
  if (std::isfinite(rec.up_confidence) && rec.up_confidence < io::kWeakUpConfidence)
    w.push_back("The cameras disagree about up (confidence " + fmt(2, rec.up_confidence) +
                ", spread " + fmt(1, rec.up_spread_deg) +
                " deg): the ground may be tilted. Check the picture below.");
  const io::AugmentedObject& obj = rec.object;
  if (has_object && obj.solved_frames > 0 && 2 * obj.visible_frames < obj.solved_frames)
    w.push_back("The object covers at least 0.5 % of the image in only " +
                std::to_string(obj.visible_frames) + " of " + std::to_string(obj.solved_frames) +
                " frames: try --object-at / --object-scale.");
  if (has_object && std::isfinite(obj.upright_cosine_median) && obj.upright_cosine_median < 0.8)
    w.push_back("The object does not look upright in the images (median cosine " +
                fmt(2, obj.upright_cosine_median) + " between the scene's up and the image's up).");
  return w;
}

// The side view: the ground (z = 0) as a line, +z up the page, the cameras and points projected
// onto the vertical plane through `sideViewAxis`, equal scales on both axes (so a tilted ground
// or a camera path below the ground is visible as such), the object as its silhouette.
std::string sideView(const io::Reconstruction& rec, const ReportOptions& options) {
  const Eigen::Vector2d axis = sideViewAxis(rec);
  auto u = [&](const Eigen::Vector3d& p) { return axis.x() * p.x() + axis.y() * p.y(); };
  std::vector<double> pu, pz, cu, cz;
  for (const auto& p : rec.points)
    if (p.X.allFinite()) {
      pu.push_back(u(p.X));
      pz.push_back(p.X.z());
    }
  for (const auto& c : rec.cameras)
    if (c.solved && c.p_wc.allFinite()) {
      cu.push_back(u(c.p_wc));
      cz.push_back(c.p_wc.z());
    }
  const io::AugmentedObject& obj = rec.object;
  const bool show_object = options.has_object && obj.at.allFinite() && std::isfinite(obj.height);
  // Range: the cameras, the central 96 % of the points, the ground and the object.
  double u0 = quantile(pu, 0.02), u1 = quantile(pu, 0.98);
  double z0 = std::min(quantile(pz, 0.02), 0.0), z1 = std::max(quantile(pz, 0.98), 0.0);
  if (!std::isfinite(u0)) u0 = u1 = 0.0;
  if (!std::isfinite(z0)) z0 = z1 = 0.0;
  for (std::size_t i = 0; i < cu.size(); ++i) {
    u0 = std::min(u0, cu[i]);
    u1 = std::max(u1, cu[i]);
    z0 = std::min(z0, cz[i]);
    z1 = std::max(z1, cz[i]);
  }
  if (show_object) {
    u0 = std::min(u0, u(obj.at));
    u1 = std::max(u1, u(obj.at));
    z1 = std::max(z1, obj.height);
  }
  constexpr double kWidth = 560, kHeight = 300, kMargin = 28;
  const double scale = std::min((kWidth - 2 * kMargin) / std::max(u1 - u0, 1e-6),
                                (kHeight - 2 * kMargin) / std::max(z1 - z0, 1e-6)) /
                       1.08;
  const double uc = 0.5 * (u0 + u1), zc = 0.5 * (z0 + z1);
  auto X = [&](double a) { return kWidth / 2 + (a - uc) * scale; };
  auto Y = [&](double b) { return kHeight / 2 - (b - zc) * scale; };  // up the page = +z
  std::string svg = "<svg id=\"plot-side-view\" class=\"plot\" viewBox=\"0 0 " + px(kWidth) + " " +
                    px(kHeight) + "\" xmlns=\"http://www.w3.org/2000/svg\" role=\"img\">\n";
  svg += "<rect class=\"frame\" x=\"0.5\" y=\"0.5\" width=\"" + px(kWidth - 1) + "\" height=\"" +
         px(kHeight - 1) + "\"/>\n";
  // The ground: everything below z = 0 shaded, the line itself drawn.
  const double gy = std::clamp(Y(0.0), 1.0, kHeight - 1.0);
  svg += "<g data-series=\"ground\" data-values=\"0\"><rect class=\"below-ground\" x=\"1\" y=\"" +
         px(gy) + "\" width=\"" + px(kWidth - 2) + "\" height=\"" + px(kHeight - 1 - gy) +
         "\"/><line class=\"ground\" x1=\"1\" y1=\"" + px(gy) + "\" x2=\"" + px(kWidth - 1) +
         "\" y2=\"" + px(gy) + "\"/></g>\n";
  // The up arrow, 60 px, at the left end of the ground.
  svg += "<g data-series=\"up\" data-values=\"0 0 1\" class=\"up\"><line x1=\"" + px(kMargin) +
         "\" y1=\"" + px(gy) + "\" x2=\"" + px(kMargin) + "\" y2=\"" + px(gy - 60) +
         "\"/><path d=\"M" + px(kMargin - 6) + "," + px(gy - 52) + " L" + px(kMargin) + "," +
         px(gy - 64) + " L" + px(kMargin + 6) + "," + px(gy - 52) +
         " Z\"/><text class=\"tick\" x=\"" + px(kMargin + 9) + "\" y=\"" + px(gy - 56) +
         "\">up (+z)</text></g>\n";
  svg += dots("point_height", pu, pz, X, Y, kWidth, kHeight, 1.5);
  svg += "<g data-series=\"camera_height\" data-values=\"" + dataValues(cz) + "\">";
  std::string path;
  for (std::size_t i = 0; i < cu.size(); ++i) {
    if (i > 0) path += ' ';
    path += px(X(cu[i])) + "," + px(Y(cz[i]));
  }
  if (!path.empty()) svg += "<polyline class=\"path\" points=\"" + path + "\"/>";
  svg += "</g>\n";
  if (show_object) {
    const double half = 0.2 * obj.scale * scale;  // the towers' footprint, about 0.4 x scale
    svg += "<g data-series=\"object\" data-values=\"" + dataNumber(u(obj.at)) + " " +
           dataNumber(obj.at.z()) + " " + dataNumber(obj.height) +
           "\"><rect class=\"object\" x=\"" + px(X(u(obj.at)) - half) + "\" y=\"" +
           px(Y(obj.at.z() + obj.height)) + "\" width=\"" + px(2 * half) + "\" height=\"" +
           px(obj.height * scale) + "\"><title>virtual object (" +
           escapeHtml(options.render_object) + ")</title></rect></g>\n";
  }
  std::string caption =
      "Seen from the side (the vertical plane along the scene's main horizontal "
      "direction, " +
      fmt(2, axis.x()) + " x + " + fmt(2, axis.y()) +
      " y; equal scales): the ground z = 0 (brown), up the page is the scene's "
      "up, the camera path in blue";
  if (show_object) caption += ", the object in orange standing on the ground";
  caption += ". Ground from " +
             std::string(rec.ground == "plane" ? "a plane of the points levelled to the cameras' up"
                                               : "the cameras' up, under the points") +
             (std::isfinite(rec.up_confidence)
                  ? "; up confidence " + fmt(2, rec.up_confidence) + " (1: every camera agrees)"
                  : std::string()) +
             ".";
  return "<figure>\n" + svg + "</svg>\n<figcaption>" + escapeHtml(caption) +
         "</figcaption>\n</figure>\n";
}

}  // namespace

std::string sceneFrameSection(const io::Reconstruction& rec, const ReportOptions& options) {
  std::string h = "<section id=\"scene-frame\">\n<h2>Scene frame: ground, up and the object</h2>\n";
  for (const auto& warning : sceneFrameWarnings(rec, options.has_object))
    h += "<p class=\"warn\">Warning: " + escapeHtml(warning) + "</p>\n";
  if (rec.ground == "none") {
    h += "<p>No ground was chosen, so there is no side view.</p>\n";
  } else {
    h += sideView(rec, options);
  }
  if (!options.scene_frame_image.empty())
    h += "<figure><img class=\"scene-frame\" src=\"" + escapeHtml(options.scene_frame_image) +
         "\" alt=\"augmented frame with the ground grid, the up arrow and the object\">"
         "<figcaption>Frame " +
         std::to_string(options.scene_frame_index) +
         " with the ground grid (cyan), the scene's up (yellow arrow) and the object.</figcaption>"
         "</figure>\n";
  return h + "</section>\n";
}

}  // namespace epitrack::render

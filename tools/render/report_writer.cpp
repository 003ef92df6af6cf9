#include "tools/render/report_writer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "hal/io/file_util.hpp"

namespace epitrack::render {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// -- text helpers -------------------------------------------------------------------------------

std::string escapeHtml(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (const char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string fmt(int digits, double v) {
  if (!std::isfinite(v)) return "n/a";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
  return buf;
}

// Numbers in data-values: enough digits for a test to compare at 1e-5 relative.
std::string dataNumber(double v) {
  if (!std::isfinite(v)) return "nan";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.7g", v);
  return buf;
}

std::string dataValues(const std::vector<double>& values) {
  std::string out;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (i > 0) out += ' ';
    out += dataNumber(values[i]);
  }
  return out;
}

// Coordinates inside the SVG: one decimal is plenty at these sizes.
std::string px(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.1f", v);
  return buf;
}

// -- plotting -----------------------------------------------------------------------------------

// A 1-2-5 step giving about `target` intervals over [lo, hi].
double niceStep(double lo, double hi, int target) {
  const double range = hi - lo;
  if (!(range > 0.0)) return 1.0;
  const double raw = range / target;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double r = raw / mag;
  return (r < 1.5 ? 1.0 : r < 3.5 ? 2.0 : r < 7.5 ? 5.0 : 10.0) * mag;
}

std::string tickLabel(double v, double step) {
  if (std::fabs(v) < step * 1e-6) v = 0.0;
  char buf[32];
  if (step >= 1.0 || std::fabs(v) >= 1e4)
    std::snprintf(buf, sizeof(buf), "%.0f", v);
  else
    std::snprintf(buf, sizeof(buf), "%.*f", static_cast<int>(std::ceil(-std::log10(step))), v);
  return buf;
}

// A rectangular plot area mapping data (x, y) to SVG pixels, with axes, ticks and labels.
class Plot {
 public:
  static constexpr double kWidth = 560, kHeight = 250;
  static constexpr double kLeft = 62, kRight = 14, kTop = 14, kBottom = 40;

  Plot(double x0, double x1, double y0, double y1) : x0_(x0), x1_(x1), y0_(y0), y1_(y1) {
    if (!(x1_ > x0_)) x1_ = x0_ + 1.0;
    if (!(y1_ > y0_)) y1_ = y0_ + 1.0;
  }
  [[nodiscard]] double sx(double x) const {
    return kLeft + (x - x0_) / (x1_ - x0_) * (kWidth - kLeft - kRight);
  }
  [[nodiscard]] double sy(double y) const {
    return kHeight - kBottom - (y - y0_) / (y1_ - y0_) * (kHeight - kTop - kBottom);
  }

  /// Opens the <svg> and draws grid, ticks and axis titles.
  [[nodiscard]] std::string begin(const std::string& id, const std::string& x_title,
                                  const std::string& y_title) const {
    std::string s = "<svg id=\"" + id + "\" class=\"plot\" viewBox=\"0 0 " + px(kWidth) + " " +
                    px(kHeight) + "\" xmlns=\"http://www.w3.org/2000/svg\" role=\"img\">\n";
    const double xs = niceStep(x0_, x1_, 8), ys = niceStep(y0_, y1_, 5);
    for (double v = std::ceil(x0_ / xs) * xs; v <= x1_ + xs * 1e-9; v += xs) {
      s += "<line class=\"grid\" x1=\"" + px(sx(v)) + "\" y1=\"" + px(kTop) + "\" x2=\"" +
           px(sx(v)) + "\" y2=\"" + px(kHeight - kBottom) + "\"/>";
      s += "<text class=\"tick\" x=\"" + px(sx(v)) + "\" y=\"" + px(kHeight - kBottom + 14) +
           "\" text-anchor=\"middle\">" + tickLabel(v, xs) + "</text>\n";
    }
    for (double v = std::ceil(y0_ / ys) * ys; v <= y1_ + ys * 1e-9; v += ys) {
      s += "<line class=\"grid\" x1=\"" + px(kLeft) + "\" y1=\"" + px(sy(v)) + "\" x2=\"" +
           px(kWidth - kRight) + "\" y2=\"" + px(sy(v)) + "\"/>";
      s += "<text class=\"tick\" x=\"" + px(kLeft - 6) + "\" y=\"" + px(sy(v) + 4) +
           "\" text-anchor=\"end\">" + tickLabel(v, ys) + "</text>\n";
    }
    s += "<rect class=\"frame\" x=\"" + px(kLeft) + "\" y=\"" + px(kTop) + "\" width=\"" +
         px(kWidth - kLeft - kRight) + "\" height=\"" + px(kHeight - kTop - kBottom) + "\"/>\n";
    s += "<text class=\"axis\" x=\"" + px((kLeft + kWidth - kRight) / 2) + "\" y=\"" +
         px(kHeight - 6) + "\" text-anchor=\"middle\">" + escapeHtml(x_title) + "</text>\n";
    s += "<text class=\"axis\" transform=\"translate(14 " + px((kTop + kHeight - kBottom) / 2) +
         ") rotate(-90)\" text-anchor=\"middle\">" + escapeHtml(y_title) + "</text>\n";
    return s;
  }

  /// A polyline through (i, values[i]), broken at non-finite values.
  [[nodiscard]] std::string series(const std::string& name, const std::string& color,
                                   const std::vector<double>& values) const {
    std::string s = "<g data-series=\"" + name + "\" data-values=\"" + dataValues(values) +
                    "\" fill=\"none\" stroke=\"" + color + "\" stroke-width=\"1.6\">";
    std::string points;
    auto flush = [&]() {
      if (!points.empty()) s += "<polyline points=\"" + points + "\"/>";
      points.clear();
    };
    for (std::size_t i = 0; i < values.size(); ++i) {
      if (!std::isfinite(values[i])) {
        flush();
        continue;
      }
      if (!points.empty()) points += ' ';
      const double v = std::clamp(values[i], y0_, y1_);
      points += px(sx(static_cast<double>(i))) + "," + px(sy(v));
    }
    flush();
    if (values.size() == 1 && std::isfinite(values[0]))
      s += "<circle cx=\"" + px(sx(0)) + "\" cy=\"" + px(sy(values[0])) + "\" r=\"2.5\" fill=\"" +
           color + "\"/>";
    s += "</g>\n";
    return s;
  }

  /// Shaded bands over the unsolved frame ranges (half a frame either side, so a single frame
  /// shows), each with its range and cause in data attributes and a tooltip.
  [[nodiscard]] std::string gaps(const std::vector<io::FrameRangeEntry>& ranges) const {
    std::string s = "<g class=\"gaps\">";
    for (const auto& r : ranges) {
      if (r.solved) continue;
      const double a = std::max(sx(static_cast<double>(r.first) - 0.5), kLeft);
      const double b = std::min(sx(static_cast<double>(r.last) + 0.5), kWidth - kRight);
      s += "<rect class=\"gap\" data-first=\"" + std::to_string(r.first) + "\" data-last=\"" +
           std::to_string(r.last) + "\" data-cause=\"" + escapeHtml(r.cause) + "\" x=\"" + px(a) +
           "\" y=\"" + px(kTop) + "\" width=\"" + px(std::max(b - a, 0.8)) + "\" height=\"" +
           px(kHeight - kTop - kBottom) + "\"><title>frames " + std::to_string(r.first) + "-" +
           std::to_string(r.last) + " unsolved: " + escapeHtml(r.reason) + "</title></rect>";
    }
    return s + "</g>\n";
  }

  static std::string legend(const std::vector<std::pair<std::string, std::string>>& entries) {
    std::string s = "<g class=\"legend\">";
    double x = kLeft + 10;
    for (const auto& [label, color] : entries) {
      s += "<rect x=\"" + px(x) + "\" y=\"" + px(kTop + 6) +
           "\" width=\"12\" height=\"4\" fill=\"" + color + "\"/><text class=\"tick\" x=\"" +
           px(x + 16) + "\" y=\"" + px(kTop + 12) + "\">" + escapeHtml(label) + "</text>";
      x += 24 + 7.0 * static_cast<double>(label.size());
    }
    return s + "</g>\n";
  }

 private:
  double x0_, x1_, y0_, y1_;
};

double maxFinite(const std::vector<double>& v, double fallback) {
  double m = -std::numeric_limits<double>::infinity();
  for (const double x : v)
    if (std::isfinite(x)) m = std::max(m, x);
  return std::isfinite(m) ? m : fallback;
}

// The value below which `fraction` of the finite values lie (for robust plot ranges).
double quantile(std::vector<double> v, double fraction) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return kNaN;
  const auto k = static_cast<std::size_t>(std::clamp(fraction * static_cast<double>(v.size() - 1),
                                                     0.0, static_cast<double>(v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

// -- sections -----------------------------------------------------------------------------------

struct Summary {
  int solved = 0, keyframes = 0, points = 0;
  double mean_px = kNaN, median_px = kNaN;
};

// The summary.json figures (tools/export basic_outputs.cpp reprojectionStatistics: the
// reconstruction's own statistics, else the observation residuals, else the points' errors).
Summary summarize(const io::Reconstruction& rec) {
  Summary s;
  for (const auto& c : rec.cameras) {
    s.solved += c.solved ? 1 : 0;
    s.keyframes += (c.solved && c.keyframe) ? 1 : 0;
  }
  for (const auto& p : rec.points) s.points += p.X.allFinite() ? 1 : 0;
  s.mean_px = rec.mean_reproj_px;
  s.median_px = rec.median_reproj_px;
  if (std::isfinite(s.mean_px) && std::isfinite(s.median_px)) return s;
  std::vector<double> r;
  for (const auto& o : rec.observations)
    if (std::isfinite(o.residual_px)) r.push_back(o.residual_px);
  if (r.empty())
    for (const auto& p : rec.points)
      if (std::isfinite(p.reproj_px)) r.push_back(p.reproj_px);
  if (!r.empty()) {
    double sum = 0.0;
    for (const double x : r) sum += x;
    if (!std::isfinite(s.mean_px)) s.mean_px = sum / static_cast<double>(r.size());
    if (!std::isfinite(s.median_px)) {
      std::sort(r.begin(), r.end());
      const std::size_t n = r.size();
      s.median_px = n % 2 == 1 ? r[n / 2] : 0.5 * (r[n / 2 - 1] + r[n / 2]);
    }
  }
  return s;
}

std::string row(const std::string& key, const std::string& label, const std::string& value) {
  return "<tr><th>" + escapeHtml(label) + "</th><td data-key=\"" + key + "\">" + escapeHtml(value) +
         "</td></tr>\n";
}

std::string summarySection(const io::Reconstruction& rec, const Summary& s) {
  const auto& k = rec.intrinsics;
  std::string h = "<section id=\"summary\">\n<h2>Summary</h2>\n<table class=\"summary\">\n";
  h += row("status", "status", rec.status);
  if (!rec.message.empty()) h += row("message", "message", rec.message);
  h += row("frames", "frames", std::to_string(rec.frames));
  h += row("solved_frames", "solved frames", std::to_string(s.solved));
  std::string unsolved;
  for (const auto& r : rec.frame_ranges) {
    if (r.solved) continue;
    if (!unsolved.empty()) unsolved += "; ";
    unsolved += std::to_string(r.first) +
                (r.last > r.first ? "-" + std::to_string(r.last) : std::string()) + " (" +
                r.reason + ")";
  }
  if (!unsolved.empty()) h += row("unsolved_ranges", "unsolved frames", unsolved);
  h += row("keyframes", "keyframes", std::to_string(s.keyframes));
  h += row("focal_px", "focal (px)", fmt(3, k.fx));
  h += row("focal_source", "focal source", rec.focal_source);
  h += row("focal_observable", "focal observable", rec.focal_observable ? "true" : "false");
  h += row("motion", "motion", rec.motion);
  h += row("mean_reproj_px", "mean reprojection error (px)", fmt(4, s.mean_px));
  h += row("median_reproj_px", "median reprojection error (px)", fmt(4, s.median_px));
  h += row("points", "points", std::to_string(s.points));
  h += row("observations", "observations", std::to_string(rec.observations.size()));
  char buf[160];
  std::snprintf(buf, sizeof(buf), "%d x %d, cx %.2f, cy %.2f, k1 %.5g, k2 %.5g", k.width, k.height,
                k.cx, k.cy, k.k1, k.k2);
  h += row("intrinsics", "image and intrinsics", buf);
  std::string frame =
      rec.origin + (rec.plane_found ? ", ground plane found (+z up)" : ", no plane");
  if (!rec.origin_note.empty()) frame += " (" + rec.origin_note + ")";
  h += row("scene_frame", "scene frame", frame);
  h += "</table>\n<table class=\"summary\" id=\"seconds\">\n<tr><th colspan=\"2\">seconds per "
       "stage</th></tr>\n";
  for (const auto& [stage, secs] : rec.seconds.stages)
    h += row("seconds." + stage, stage, fmt(3, secs));
  h += row("seconds.total", "total", fmt(3, rec.seconds.total));
  return h + "</table>\n</section>\n";
}

std::string figure(const std::string& id, const std::string& title, const std::string& svg,
                   const std::string& caption) {
  return "<section id=\"" + id + "\">\n<h2>" + escapeHtml(title) + "</h2>\n<figure>\n" + svg +
         "</svg>\n<figcaption>" + caption + "</figcaption>\n</figure>\n</section>\n";
}

std::string perFrameSection(const io::Reconstruction& rec, bool reproj) {
  const std::size_t n = std::max<std::size_t>(static_cast<std::size_t>(rec.frames), 1);
  std::vector<double> a(n, kNaN), b(n, kNaN);
  for (const auto& c : rec.cameras) {
    if (c.frame < 0 || static_cast<std::size_t>(c.frame) >= n) continue;
    const auto i = static_cast<std::size_t>(c.frame);
    if (reproj) {
      a[i] = c.solved ? c.mean_reproj_px : kNaN;
    } else {
      a[i] = static_cast<double>(c.features);
      b[i] = c.solved ? static_cast<double>(c.inliers) : kNaN;
    }
  }
  const double top = reproj ? std::max(quantile(a, 0.98) * 1.25, 1e-3)
                            : std::max({maxFinite(a, 1.0), maxFinite(b, 1.0)}) * 1.1;
  const Plot plot(0.0, static_cast<double>(n - 1), 0.0, std::isfinite(top) ? top : 1.0);
  if (reproj) {
    std::string svg = plot.begin("plot-reprojection", "frame", "mean reprojection error (px)");
    svg += plot.gaps(rec.frame_ranges);
    svg += plot.series("reproj_px", "#c0392b", a);
    int unsolved = 0;
    for (std::size_t i = 0; i < n; ++i) unsolved += std::isfinite(a[i]) ? 0 : 1;
    return figure("reprojection", "Reprojection error per frame", svg,
                  "Mean distance between each solved frame's tracked features and the "
                  "projections of their 3D points (outliers excluded). Gaps: " +
                      std::to_string(unsolved) + " frame(s) without a solved camera.");
  }
  std::string svg = plot.begin("plot-features", "frame", "features");
  svg += plot.gaps(rec.frame_ranges);
  svg += plot.series("features", "#2471a3", a);
  svg += plot.series("inliers", "#27ae60", b);
  svg += Plot::legend({{"tracked features", "#2471a3"}, {"used for the pose", "#27ae60"}});
  return figure("features", "Live features per frame", svg,
                "Features the 2D tracker followed in each frame, and the observations of "
                "reconstructed points that fit the solved camera.");
}

std::string trackLengthSection(const io::Reconstruction& rec) {
  const std::vector<int> lengths = trackLengths(rec);
  int longest = 1;
  for (const int l : lengths) longest = std::max(longest, l);
  const int width = std::max(1, (longest + 39) / 40);  // at most 40 bars
  const int bins = longest / width + 1;
  std::vector<double> counts(static_cast<std::size_t>(bins), 0.0);
  for (const int l : lengths) counts[static_cast<std::size_t>(l / width)] += 1.0;
  const Plot plot(0.0, static_cast<double>(bins * width), 0.0, maxFinite(counts, 1.0) * 1.1);
  std::string svg = plot.begin("plot-track-lengths", "track length (solved frames)", "points");
  std::string lengths_text;
  for (std::size_t i = 0; i < lengths.size(); ++i) {
    if (i > 0) lengths_text += ' ';
    lengths_text += std::to_string(lengths[i]);
  }
  svg += "<g data-series=\"track_lengths\" data-values=\"" + lengths_text + "\" data-bin-width=\"" +
         std::to_string(width) + "\" fill=\"#8e44ad\">";
  for (int i = 0; i < bins; ++i) {
    const double c = counts[static_cast<std::size_t>(i)];
    if (c <= 0.0) continue;
    const double x0 = plot.sx(i * width), x1 = plot.sx((i + 1) * width);
    svg += "<rect x=\"" + px(x0 + 0.5) + "\" y=\"" + px(plot.sy(c)) + "\" width=\"" +
           px(std::max(x1 - x0 - 1.0, 0.8)) + "\" height=\"" + px(plot.sy(0) - plot.sy(c)) +
           "\"><title>" + std::to_string(i * width) +
           (width > 1 ? "-" + std::to_string(i * width + width - 1) : std::string()) +
           " frames: " + std::to_string(static_cast<int>(c)) + " points</title></rect>";
  }
  svg += "</g>\n";
  double mean = 0.0;
  for (const int l : lengths) mean += l;
  mean = lengths.empty() ? 0.0 : mean / static_cast<double>(lengths.size());
  return figure("track-lengths", "Track lengths", svg,
                "Number of solved frames in which each of the " + std::to_string(lengths.size()) +
                    " reconstructed points was observed (mean " + fmt(1, mean) + "; bins of " +
                    std::to_string(width) + ").");
}

std::string focalSection(const io::Reconstruction& rec) {
  const auto& est = rec.focal_estimates;
  const double chosen = rec.intrinsics.fx;
  std::vector<double> f;
  double x_max = std::max(1.0, static_cast<double>(rec.frames - 1));
  for (const auto& e : est) f.push_back(e.focal_px);
  double lo = chosen, hi = chosen;
  if (!f.empty()) {
    lo = std::min(lo, quantile(f, 0.02));
    hi = std::max(hi, quantile(f, 0.98));
  }
  const double pad = std::max(0.08 * (hi - lo), 0.05 * std::fabs(chosen) + 1.0);
  const Plot plot(0.0, x_max, std::max(0.0, lo - pad), hi + pad);
  std::string svg = plot.begin("plot-focal", "frame pair (midpoint)", "focal (px)");
  std::vector<double> a, b;
  std::string dots;
  for (const auto& e : est) {
    a.push_back(static_cast<double>(e.frame_a));
    b.push_back(static_cast<double>(e.frame_b));
    const double mid = 0.5 * static_cast<double>(e.frame_a + e.frame_b);
    if (!std::isfinite(e.focal_px)) continue;
    const double y = std::clamp(e.focal_px, std::max(0.0, lo - pad), hi + pad);
    dots += "<circle cx=\"" + px(plot.sx(mid)) + "\" cy=\"" + px(plot.sy(y)) +
            "\" r=\"3\" class=\"" + (e.coherent ? "coherent" : "outlier") + "\"><title>frames " +
            std::to_string(e.frame_a) + "-" + std::to_string(e.frame_b) + ": " +
            fmt(1, e.focal_px) + " px</title></circle>";
  }
  svg += "<g data-series=\"focal_px\" data-values=\"" + dataValues(f) + "\" data-frame-a=\"" +
         dataValues(a) + "\" data-frame-b=\"" + dataValues(b) + "\">" + dots + "</g>\n";
  svg += "<g data-series=\"chosen_focal_px\" data-values=\"" + dataNumber(chosen) +
         "\"><line class=\"chosen\" x1=\"" + px(Plot::kLeft) + "\" y1=\"" + px(plot.sy(chosen)) +
         "\" x2=\"" + px(Plot::kWidth - Plot::kRight) + "\" y2=\"" + px(plot.sy(chosen)) +
         "\"/></g>\n";
  svg += Plot::legend({{"agrees with the choice", "#27ae60"},
                       {"disagrees", "#e67e22"},
                       {"chosen " + fmt(1, chosen) + " px", "#c0392b"}});
  int coherent = 0;
  for (const auto& e : est) coherent += e.coherent ? 1 : 0;
  std::string caption =
      est.empty() ? "No pairwise focal estimate (focal " + escapeHtml(rec.focal_source) + ")."
                  : std::to_string(est.size()) + " frame pairs gave a focal estimate, " +
                        std::to_string(coherent) + " agree with the chosen focal " +
                        fmt(2, chosen) + " px (" + escapeHtml(rec.focal_source) + ").";
  return figure("focal", "Focal estimates per frame pair", svg, caption);
}

std::string topViewSection(const io::Reconstruction& rec, const ReportOptions& options) {
  // Scene frame: with a ground plane z is up, so the top view is the x-y plane; the first-camera
  // frame keeps the camera axes (y down), so its top view is x-z.
  const bool z_up = rec.plane_found;
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
  svg += "<g data-series=\"points\" data-count=\"" + std::to_string(pu.size()) +
         "\" fill=\"#555\" fill-opacity=\"0.55\">";
  for (std::size_t i = 0; i < pu.size(); ++i) {
    const double x = X(pu[i]), y = Y(pv[i]);
    if (x < 0 || x > kSize || y < 0 || y > kSize) continue;
    svg += "<circle cx=\"" + px(x) + "\" cy=\"" + px(y) + "\" r=\"1.6\"/>";
  }
  svg += "</g>\n<g data-series=\"camera_path\" data-count=\"" + std::to_string(cu.size()) +
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
                    (z_up ? "x-y plane, z up" : "x-z plane of the first camera") + "): " +
                    std::to_string(cu.size()) + " camera centres (green start, red end) over " +
                    std::to_string(pu.size()) + " points (central 96% framed)" +
                    (options.has_object ? "; the orange square is the virtual object" : "") + ".");
}

std::string stripSection(const ReportOptions& options) {
  std::string h = "<section id=\"augmented\">\n<h2>Augmented frames</h2>\n";
  if (options.augmented_frames.empty()) {
    h += "<p>No augmented frames (run with <code>--render towers|cube|axes</code>).</p>\n";
  } else {
    h += "<div class=\"strip\">\n";
    for (const std::size_t i :
         stripSelection(options.augmented_frames.size(), options.strip_frames)) {
      const auto& [frame, src] = options.augmented_frames[i];
      h += "<figure class=\"frame\"><a href=\"" + escapeHtml(src) + "\"><img src=\"" +
           escapeHtml(src) + "\" alt=\"augmented frame " + std::to_string(frame) +
           "\" loading=\"eager\"></a><figcaption>frame " + std::to_string(frame) +
           "</figcaption></figure>\n";
    }
    h += "</div>\n";
  }
  if (!options.video.empty())
    h += "<p>Video: <a href=\"" + escapeHtml(options.video) + "\">" + escapeHtml(options.video) +
         "</a> (MJPEG AVI: <code>ffplay</code>, <code>mpv</code> or VLC).</p>\n";
  return h + "</section>\n";
}

constexpr const char* kStyle = R"(
body { font-family: system-ui, sans-serif; margin: 24px auto; max-width: 1180px; color: #222; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; } h2 { font-size: 1.2em; margin: 1.2em 0 0.4em; }
.sub { color: #666; margin-top: 0; }
.grid2 { display: grid; grid-template-columns: repeat(auto-fit, minmax(520px, 1fr)); gap: 8px 24px; }
table.summary { border-collapse: collapse; display: inline-table; margin: 0 24px 12px 0; vertical-align: top; }
table.summary th, table.summary td { border-bottom: 1px solid #ddd; padding: 3px 10px; text-align: left; }
table.summary th { font-weight: 600; color: #444; }
figure { margin: 0; } figcaption { color: #555; font-size: 0.9em; margin-top: 4px; }
svg.plot { width: 100%; max-width: 560px; height: auto; background: #fff; }
svg.square { max-width: 520px; }
svg .grid { stroke: #eee; } svg .frame { fill: none; stroke: #999; }
svg .gap { fill: #f5b7b1; fill-opacity: 0.45; stroke: none; }
svg .tick { font-size: 11px; fill: #555; } svg .axis { font-size: 12px; fill: #333; }
svg .chosen { stroke: #c0392b; stroke-width: 1.5; stroke-dasharray: 6 4; }
svg .coherent { fill: #27ae60; } svg .outlier { fill: #e67e22; }
svg .path { fill: none; stroke: #2471a3; stroke-width: 2; }
svg .start { fill: #27ae60; } svg .end { fill: #c0392b; }
svg .object { fill: #e67e22; stroke: #7e3f0a; stroke-width: 1.5; }
svg .axis-u { stroke: #c0392b; stroke-width: 2; } svg .axis-v { stroke: #27ae60; stroke-width: 2; }
svg .scalebar { stroke: #222; stroke-width: 3; }
.strip { display: grid; grid-template-columns: repeat(3, 1fr); gap: 8px; }
.strip img { width: 100%; height: auto; display: block; border: 1px solid #ccc; }
)";

}  // namespace

std::vector<int> trackLengths(const io::Reconstruction& rec) {
  std::map<int64_t, int> count;
  for (const auto& o : rec.observations) ++count[o.point_id];
  std::vector<int> lengths;
  lengths.reserve(rec.points.size());
  for (const auto& p : rec.points) {
    const auto it = count.find(p.id);
    if (it != count.end()) lengths.push_back(it->second);
  }
  return lengths;
}

std::vector<std::size_t> stripSelection(std::size_t available, int count) {
  std::vector<std::size_t> picks;
  if (available == 0 || count <= 0) return picks;
  const auto n = std::min(available, static_cast<std::size_t>(count));
  for (std::size_t i = 0; i < n; ++i)
    picks.push_back(n == 1 ? 0
                           : static_cast<std::size_t>(std::llround(
                                 static_cast<double>(i) * static_cast<double>(available - 1) /
                                 static_cast<double>(n - 1))));
  return picks;
}

std::string formatReportHtml(const io::Reconstruction& rec, const ReportOptions& options) {
  const Summary s = summarize(rec);
  std::string h = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" +
                  escapeHtml(options.title) + "</title>\n<style>" + kStyle +
                  "</style>\n</head>\n<body>\n";
  h += "<h1>" + escapeHtml(options.title) + "</h1>\n<p class=\"sub\">";
  if (!options.input.empty()) h += "Input <code>" + escapeHtml(options.input) + "</code>. ";
  h += std::to_string(s.solved) + " of " + std::to_string(rec.frames) + " frames solved, focal " +
       fmt(1, rec.intrinsics.fx) + " px (" + escapeHtml(rec.focal_source) + "), " +
       std::to_string(s.points) + " points, mean reprojection error " + fmt(3, s.mean_px) +
       " px.</p>\n";
  h += summarySection(rec, s);
  h += "<div class=\"grid2\">\n";
  h += perFrameSection(rec, true);
  h += perFrameSection(rec, false);
  h += trackLengthSection(rec);
  h += focalSection(rec);
  h += "</div>\n";
  h += topViewSection(rec, options);
  h += stripSection(options);
  h += "</body>\n</html>\n";
  return h;
}

bool writeReportHtml(const io::Reconstruction& rec, const ReportOptions& options,
                     const std::string& path, std::string& error) {
  return hal::writeTextAtomic(path, formatReportHtml(rec, options), error);
}

}  // namespace epitrack::render

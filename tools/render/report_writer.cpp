#include "tools/render/report_writer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "hal/io/file_util.hpp"
#include "tools/render/report_html.hpp"
#include "tools/render/report_views.hpp"

namespace epitrack::render {

namespace {

using namespace report_html;  // NOLINT(google-build-using-namespace): the section helpers

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
  if (rec.centre_sd_steps >= 0.0) {
    // The camera path check (summary.json centre_uncertainty): above the limit the status is
    // trajectory-uncertain.
    h += row("centre_uncertainty", "camera centre sd",
             fmt(3, rec.centre_sd_steps) + " frame-to-frame steps (limit " +
                 fmt(2, rec.centre_sd_limit_steps) + "), " + fmt(3, rec.centre_sd_percent) +
                 " % of the path");
  }
  if (rec.view_pairs_checked >= 0) {
    // Key frames (summary.json view_pair_check): pairs contradicted by their own matches make
    // the status inconsistent (or are warned of in a partial solve).
    std::string pairs = std::to_string(rec.contradicted_view_pairs.size()) + " of " +
                        std::to_string(rec.view_pairs_checked) + " contradicted";
    if (!rec.contradicted_view_pairs.empty())
      pairs += ": " + io::contradictedPairsText(rec.contradicted_view_pairs, 5);
    h += row("view_pair_check", "view pairs", pairs);
  }
  char buf[160];
  std::snprintf(buf, sizeof(buf), "%d x %d, cx %.2f, cy %.2f, k1 %.5g, k2 %.5g", k.width, k.height,
                k.cx, k.cy, k.k1, k.k2);
  h += row("intrinsics", "image and intrinsics", buf);
  std::string frame = rec.origin;
  if (rec.ground == "plane") {
    frame += ", ground plane found (+z up";
    if (std::isfinite(rec.plane_up_angle_deg))
      frame += ", " + fmt(1, rec.plane_up_angle_deg) + " deg from the cameras' up";
    frame += ")";
  } else if (rec.ground == "cameras") {
    frame += ", no level plane: +z is the cameras' up, the ground under the points";
  } else {
    frame += ", no plane";
  }
  if (std::isfinite(rec.up_confidence)) {
    frame += "; up confidence " + fmt(2, rec.up_confidence) + ", spread " +
             fmt(1, rec.up_spread_deg) + " deg";
    if (rec.up_confidence < io::kWeakUpConfidence) frame += " (weak: check the augmented frames)";
  }
  if (!rec.origin_note.empty()) frame += " (" + rec.origin_note + ")";
  h += row("scene_frame", "scene frame", frame);
  h += "</table>\n<table class=\"summary\" id=\"seconds\">\n<tr><th colspan=\"2\">seconds per "
       "stage</th></tr>\n";
  for (const auto& [stage, secs] : rec.seconds.stages)
    h += row("seconds." + stage, stage, fmt(3, secs));
  h += row("seconds.total", "total", fmt(3, rec.seconds.total));
  return h + "</table>\n</section>\n";
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
svg .ground { stroke: #795548; stroke-width: 2.5; } svg .below-ground { fill: #efebe9; }
svg .up line { stroke: #b7950b; stroke-width: 3; } svg .up path { fill: #b7950b; }
.warn { background: #fdebd0; border-left: 4px solid #e67e22; padding: 6px 10px; }
img.scene-frame { max-width: 560px; width: 100%; height: auto; border: 1px solid #ccc; }
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
  h += sceneFrameSection(rec, options);
  h += stripSection(options);
  h += "</body>\n</html>\n";
  return h;
}

bool writeReportHtml(const io::Reconstruction& rec, const ReportOptions& options,
                     const std::string& path, std::string& error) {
  return hal::writeTextAtomic(path, formatReportHtml(rec, options), error);
}

}  // namespace epitrack::render

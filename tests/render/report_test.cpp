// report.html (tools/render/report_writer): every section present, balanced markup, the figures
// equal to the reconstruction's, and a headless Chromium rendering when chromium is installed.
#include "tools/render/report_writer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <catch2/catch.hpp>

#include "hal/io/file_util.hpp"
#include "hal/io/image_codec.hpp"
#include "hal/io/text_formats.hpp"
#include "tests/support/test_support.hpp"

using epitrack::io::Reconstruction;
using epitrack::render::formatReportHtml;
using epitrack::render::ReportOptions;

namespace {

// A plausible solve: 40 frames on an arc above a ground plane, 60 points, a few unsolved frames,
// residuals and focal estimates with a known spread.
Reconstruction makeReconstruction() {
  Reconstruction rec;
  rec.intrinsics = epitrack::CameraIntrinsics::centered(320, 240, 300.0);
  rec.frames = 40;
  rec.focal_source = "self-calibrated";
  rec.motion = "general";
  rec.plane_found = true;
  rec.ground = "plane";
  rec.message = "a <note> & more";
  std::mt19937 rng(7);
  auto uniform = [&](double lo, double hi) {
    return lo + (hi - lo) * static_cast<double>(rng()) / 4294967295.0;
  };
  for (int f = 0; f < rec.frames; ++f) {
    epitrack::io::SolvedCamera c;
    c.frame = f;
    c.solved = f != 5 && f != 6;
    const double a = 0.05 * f;
    c.p_wc = Eigen::Vector3d(2.0 * std::cos(a), 2.0 * std::sin(a), 1.2);
    c.mean_reproj_px = 0.2 + 0.01 * f;
    c.features = 150 - f;
    c.inliers = 100 + (f % 7);
    c.keyframe = f % 8 == 0;
    rec.cameras.push_back(c);
  }
  for (int i = 0; i < 60; ++i) {
    epitrack::io::ScenePoint p;
    p.id = 1000 + i;
    p.X = Eigen::Vector3d(uniform(-1, 1), uniform(-1, 1), i % 4 == 0 ? uniform(0, 0.5) : 0.0);
    rec.points.push_back(p);
    const int first = i % 20, length = 2 + (i * 7) % 25;
    for (int f = first; f < std::min(rec.frames, first + length); ++f) {
      if (!rec.cameras[static_cast<std::size_t>(f)].solved) continue;
      rec.observations.push_back({f, p.id, uniform(0, 319), uniform(0, 239), uniform(0, 0.6)});
    }
  }
  for (int k = 0; k < 12; ++k)
    rec.focal_estimates.push_back({k, k + 10, 300.0 + 4.0 * (k - 6), k != 3});
  rec.seconds.stages = {{"tracking", 0.5}, {"calibration", 0.25}, {"bundle_adjustment", 1.0}};
  rec.seconds.total = 1.75;
  return rec;
}

int countOf(const std::string& text, const std::string& needle) {
  int n = 0;
  for (auto pos = text.find(needle); pos != std::string::npos; pos = text.find(needle, pos + 1))
    ++n;
  return n;
}

// Opening tags "<name" followed by a space or '>' (so "<s" does not count "<svg").
int openTags(const std::string& html, const std::string& name) {
  return countOf(html, "<" + name + " ") + countOf(html, "<" + name + ">");
}

std::string cellValue(const std::string& html, const std::string& key) {
  const std::string open = "data-key=\"" + key + "\">";
  const auto pos = html.find(open);
  if (pos == std::string::npos) return "<missing>";
  const auto start = pos + open.size();
  return html.substr(start, html.find("</td>", start) - start);
}

// The numbers of `data-values` on the element whose data-series is `name`.
std::vector<double> seriesValues(const std::string& html, const std::string& name,
                                 const std::string& attribute = "data-values") {
  std::vector<double> values;
  const auto pos = html.find("data-series=\"" + name + "\"");
  if (pos == std::string::npos) return values;
  const auto end = html.find('>', pos);
  const auto attr = html.find(attribute + "=\"", pos);
  if (attr == std::string::npos || attr > end) return values;
  const auto start = attr + attribute.size() + 2;
  std::istringstream in(html.substr(start, html.find('"', start) - start));
  std::string token;
  while (in >> token) values.push_back(token == "nan" ? std::nan("") : std::stod(token));
  return values;
}

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
  return buf;
}

}  // namespace

TEST_CASE("report has every section with balanced markup", "[render][report]") {
  const Reconstruction rec = makeReconstruction();
  ReportOptions options;
  for (int f = 0; f < 40; ++f) {
    char name[40];
    std::snprintf(name, sizeof(name), "augmented/%06d.jpg", f);
    options.augmented_frames.emplace_back(f, name);
  }
  options.video = "augmented.avi";
  options.has_object = true;
  options.object_at = Eigen::Vector3d(0.25, -0.5, 0.0);
  const std::string html = formatReportHtml(rec, options);

  for (const char* id : {"summary", "reprojection", "features", "track-lengths", "focal",
                         "top-view", "scene-frame", "augmented"})
    CHECK(html.find(std::string("<section id=\"") + id + "\"") != std::string::npos);
  for (const char* id : {"plot-reprojection", "plot-features", "plot-track-lengths", "plot-focal",
                         "plot-top-view", "plot-side-view"})
    CHECK(html.find(std::string("<svg id=\"") + id + "\"") != std::string::npos);

  CHECK(html.rfind("<!DOCTYPE html>", 0) == 0);
  for (const char* tag :
       {"html", "head", "body", "section", "svg", "table", "tr", "figure", "figcaption", "div", "g",
        "text", "title", "style", "a", "p", "h1", "h2", "code"}) {
    INFO(tag);
    CHECK(openTags(html, tag) == countOf(html, std::string("</") + tag + ">"));
  }
  CHECK(openTags(html, "html") == 1);
  CHECK(openTags(html, "section") == 8);
  // No script, no remote resource: self-contained.
  CHECK(html.find("<script") == std::string::npos);
  CHECK(html.find("http://") == html.find("http://www.w3.org/2000/svg"));
  CHECK(html.find("https://") == std::string::npos);
  // User text is escaped.
  CHECK(html.find("a &lt;note&gt; &amp; more") != std::string::npos);

  // The strip: 6 evenly spaced frames, first and last included.
  CHECK(openTags(html, "img") == 6);
  CHECK(html.find("src=\"augmented/000000.jpg\"") != std::string::npos);
  CHECK(html.find("src=\"augmented/000039.jpg\"") != std::string::npos);
  CHECK(html.find("href=\"augmented.avi\"") != std::string::npos);
  // The object's ground position in the top view.
  CHECK(html.find("data-series=\"object\" data-values=\"0.25 -0.5\"") != std::string::npos);
}

TEST_CASE("report figures equal the reconstruction's", "[render][report]") {
  Reconstruction rec = makeReconstruction();
  const std::string html = formatReportHtml(rec, ReportOptions{});

  // Summary table: the summary.json fields.
  CHECK(cellValue(html, "frames") == "40");
  CHECK(cellValue(html, "solved_frames") == "38");
  CHECK(cellValue(html, "keyframes") == "5");
  CHECK(cellValue(html, "focal_px") == "300.000");
  CHECK(cellValue(html, "focal_source") == "self-calibrated");
  CHECK(cellValue(html, "focal_observable") == "true");
  CHECK(cellValue(html, "motion") == "general");
  CHECK(cellValue(html, "points") == "60");
  CHECK(cellValue(html, "observations") == std::to_string(rec.observations.size()));
  CHECK(cellValue(html, "seconds.bundle_adjustment") == "1.000");
  CHECK(cellValue(html, "seconds.total") == "1.750");
  CHECK(cellValue(html, "centre_uncertainty") == "<missing>");  // not measured: no row
  {
    Reconstruction uncertain = rec;
    uncertain.status = "trajectory-uncertain";
    uncertain.centre_sd_steps = 0.208;
    uncertain.centre_sd_limit_steps = 0.12;
    uncertain.centre_sd_percent = 0.174;
    const std::string u = formatReportHtml(uncertain, ReportOptions{});
    CHECK(cellValue(u, "status") == "trajectory-uncertain");
    CHECK(cellValue(u, "centre_uncertainty") ==
          "0.208 frame-to-frame steps (limit 0.12), 0.174 % of the path");
  }
  std::vector<double> residuals;
  double sum = 0.0;
  for (const auto& o : rec.observations) {
    residuals.push_back(o.residual_px);
    sum += o.residual_px;
  }
  std::sort(residuals.begin(), residuals.end());
  const std::size_t n = residuals.size();
  const double median = n % 2 ? residuals[n / 2] : 0.5 * (residuals[n / 2 - 1] + residuals[n / 2]);
  CHECK(cellValue(html, "mean_reproj_px") == fixed(sum / static_cast<double>(n), 4));
  CHECK(cellValue(html, "median_reproj_px") == fixed(median, 4));

  // Per-frame series: one value per frame, gaps at the unsolved ones.
  const auto reproj = seriesValues(html, "reproj_px");
  const auto features = seriesValues(html, "features");
  const auto inliers = seriesValues(html, "inliers");
  REQUIRE(reproj.size() == 40);
  REQUIRE(features.size() == 40);
  REQUIRE(inliers.size() == 40);
  for (std::size_t f = 0; f < 40; ++f) {
    const auto& c = rec.cameras[f];
    INFO("frame " << f);
    if (c.solved) {
      CHECK(reproj[f] == Approx(c.mean_reproj_px).epsilon(1e-6));
      CHECK(inliers[f] == c.inliers);
    } else {
      CHECK(std::isnan(reproj[f]));
      CHECK(std::isnan(inliers[f]));
    }
    CHECK(features[f] == c.features);
  }

  // Track lengths: observations per point id.
  std::map<int64_t, int> per_point;
  for (const auto& o : rec.observations) ++per_point[o.point_id];
  // Points without a solved-frame observation (one here: frames 5-6 only) are left out.
  std::vector<double> expected_lengths;
  for (const auto& p : rec.points)
    if (per_point.count(p.id) > 0) expected_lengths.push_back(per_point[p.id]);
  REQUIRE(expected_lengths.size() == rec.points.size() - 1);
  CHECK(seriesValues(html, "track_lengths") == expected_lengths);

  // Focal estimates and the chosen value.
  const auto focals = seriesValues(html, "focal_px");
  const auto frame_b = seriesValues(html, "focal_px", "data-frame-b");
  REQUIRE(focals.size() == rec.focal_estimates.size());
  REQUIRE(frame_b.size() == rec.focal_estimates.size());
  for (std::size_t i = 0; i < focals.size(); ++i) {
    CHECK(focals[i] == Approx(rec.focal_estimates[i].focal_px));
    CHECK(frame_b[i] == static_cast<double>(rec.focal_estimates[i].frame_b));
  }
  CHECK(seriesValues(html, "chosen_focal_px") == std::vector<double>{300.0});
  CHECK(countOf(html, "class=\"coherent\"") == 11);
  CHECK(countOf(html, "class=\"outlier\"") == 1);

  // Top view: solved camera centres (x, y), every point counted.
  const auto u = seriesValues(html, "camera_path", "data-u");
  const auto v = seriesValues(html, "camera_path", "data-v");
  REQUIRE(u.size() == 38);
  REQUIRE(v.size() == 38);
  std::size_t k = 0;
  for (const auto& c : rec.cameras) {
    if (!c.solved) continue;
    CHECK(u[k] == Approx(c.p_wc.x()).margin(1e-6));
    CHECK(v[k] == Approx(c.p_wc.y()).margin(1e-6));
    ++k;
  }
  CHECK(html.find("data-series=\"points\" data-count=\"60\"") != std::string::npos);
  CHECK(html.find("data-series=\"object\"") == std::string::npos);  // no object, no marker
  // Without augmented frames the strip says how to get them.
  CHECK(html.find("No augmented frames") != std::string::npos);
}

TEST_CASE("report strip selection is evenly spaced", "[render][report]") {
  using epitrack::render::stripSelection;
  CHECK(stripSelection(0, 6).empty());
  CHECK(stripSelection(3, 6) == std::vector<std::size_t>{0, 1, 2});
  CHECK(stripSelection(11, 6) == std::vector<std::size_t>{0, 2, 4, 6, 8, 10});
  CHECK(stripSelection(150, 6).back() == 149);
}

TEST_CASE("report renders in headless Chromium", "[render][report][browser]") {
  std::string browser;
  for (const char* name : {"chromium", "chromium-browser", "google-chrome"})
    if (epitrack::test::run(std::string("command -v ") + name + " >/dev/null 2>&1") == 0) {
      browser = name;
      break;
    }
  if (browser.empty()) {
    std::printf("EPITRACK-SKIP: chromium not installed (tools/deps.sh browser)\n");
    return;
  }
  epitrack::test::TempDir dir("report");
  std::string error;
  REQUIRE(epitrack::hal::makeDirectories(dir.file("augmented"), error));
  const Reconstruction rec = makeReconstruction();
  ReportOptions options;
  // Six small colour frames so the strip has real images to load.
  epitrack::hal::JpegEncoder encoder;
  std::vector<uint8_t> rgb(160 * 120 * 3);
  for (int f = 0; f < 6; ++f) {
    for (int y = 0; y < 120; ++y)
      for (int x = 0; x < 160; ++x) {
        uint8_t* p = &rgb[static_cast<std::size_t>((y * 160 + x) * 3)];
        p[0] = static_cast<uint8_t>(x + 20 * f);
        p[1] = static_cast<uint8_t>(2 * y);
        p[2] = static_cast<uint8_t>(((x / 20 + y / 20) % 2) * 200);
      }
    REQUIRE(encoder.encodeRgb(rgb.data(), 160, 120, 160 * 3, 85, error));
    char name[40];
    std::snprintf(name, sizeof(name), "augmented/%06d.jpg", f);
    REQUIRE(epitrack::hal::writeFileAtomic(dir.file(name), encoder.data(), encoder.size(), error));
    options.augmented_frames.emplace_back(f, name);
  }
  REQUIRE(epitrack::render::writeReportHtml(rec, options, dir.file("report.html"), error));

  // The DOM as Chromium parsed it keeps every section and plot (nothing swallowed by bad markup):
  // 8 sections, 6 plots (the side view with them: the fixture has a ground plane).
  const std::string flags = " --headless --no-sandbox --disable-gpu --hide-scrollbars";
  const std::string dom_cmd = browser + flags + " --dump-dom 'file://" + dir.file("report.html") +
                              "' > '" + dir.file("dom.html") + "' 2>/dev/null";
  REQUIRE(epitrack::test::run(dom_cmd) == 0);
  std::string dom;
  REQUIRE(epitrack::hal::readTextFile(dir.file("dom.html"), dom, error));
  CHECK(openTags(dom, "section") == 8);
  CHECK(openTags(dom, "svg") == 6);
  CHECK(openTags(dom, "img") == 6);

  const std::string shot_cmd = browser + flags + " --window-size=1200,3000 --screenshot='" +
                               dir.file("report.png") + "' 'file://" + dir.file("report.html") +
                               "' >/dev/null 2>&1";
  REQUIRE(epitrack::test::run(shot_cmd) == 0);
  std::vector<uint8_t> png;
  REQUIRE(epitrack::hal::readFileInto(dir.file("report.png"), png, error));
  epitrack::hal::ImageHeader header;
  REQUIRE(epitrack::hal::readPngHeader(png.data(), png.size(), header, error));
  CHECK(header.width == 1200);
  CHECK(header.height == 3000);
  // Not a blank page: plenty of non-white pixels.
  epitrack::Image<uint8_t> gray(header.width, header.height);
  epitrack::hal::PngScratch scratch;
  REQUIRE(epitrack::hal::decodePng(png.data(), png.size(), gray.view(), scratch, error));
  int dark = 0;
  for (int y = 0; y < gray.height(); ++y)
    for (int x = 0; x < gray.width(); ++x) dark += gray.view()(x, y) < 200 ? 1 : 0;
  CHECK(dark > 20000);
  if (const char* keep = std::getenv("EPITRACK_REPORT_SCREENSHOT")) {
    const std::string copy = std::string("cp '") + dir.file("report.png") + "' '" + keep + "'";
    CHECK(epitrack::test::run(copy) == 0);
  }
}

TEST_CASE("report's scene frame shows the ground, up and the object, and warns when weak",
          "[render][report]") {
  Reconstruction rec = makeReconstruction();
  rec.up_confidence = 0.97;
  rec.up_spread_deg = 4.0;
  rec.object.at = Eigen::Vector3d(0.25, -0.5, 0.0);
  rec.object.scale = 0.5;
  rec.object.height = 0.3;
  rec.object.solved_frames = 38;
  rec.object.visible_frames = 38;
  rec.object.upright_cosine_median = 0.98;
  ReportOptions options;
  options.has_object = true;
  options.render_object = "towers";
  options.object_at = rec.object.at;
  options.scene_frame_image = "scene_frame.jpg";
  options.scene_frame_index = 19;
  std::string html = formatReportHtml(rec, options);

  // The side view: the ground at z = 0, up = +z, every solved camera's height, the object standing
  // on the ground with its height (u: its coordinate along the view's horizontal axis).
  CHECK(seriesValues(html, "ground") == std::vector<double>{0.0});
  CHECK(seriesValues(html, "up") == std::vector<double>{0.0, 0.0, 1.0});
  const auto heights = seriesValues(html, "camera_height");
  REQUIRE(heights.size() == 38);
  for (const double z : heights) CHECK(z == Approx(1.2));
  const auto object = seriesValues(html, "object");  // top view's first: (x, y)
  CHECK(object == std::vector<double>{0.25, -0.5});
  const auto side_section = html.substr(html.find("<section id=\"scene-frame\""));
  const auto side_object = seriesValues(side_section, "object");
  REQUIRE(side_object.size() == 3);
  CHECK(side_object[1] == 0.0);
  CHECK(side_object[2] == Approx(0.3));
  CHECK(side_section.find("src=\"scene_frame.jpg\"") != std::string::npos);
  CHECK(side_section.find("Frame 19 ") != std::string::npos);
  CHECK(side_section.find("class=\"warn\"") == std::string::npos);

  // Weak up, a hidden object, an object on its side: one warning each.
  rec.up_confidence = 0.55;
  rec.object.visible_frames = 10;
  rec.object.upright_cosine_median = 0.1;
  html = formatReportHtml(rec, options);
  CHECK(countOf(html, "<p class=\"warn\">") == 3);
  CHECK(html.find("confidence 0.55") != std::string::npos);
  CHECK(html.find("only 10 of 38 frames") != std::string::npos);

  // No ground: no side view, and a warning that says what the frame is instead.
  rec.ground = "none";
  rec.up_confidence = std::nan("");
  rec.object.visible_frames = 38;
  rec.object.upright_cosine_median = 0.95;
  html = formatReportHtml(rec, options);
  CHECK(html.find("plot-side-view") == std::string::npos);
  CHECK(countOf(html, "<p class=\"warn\">") == 1);
  CHECK(html.find("No ground") != std::string::npos);
}

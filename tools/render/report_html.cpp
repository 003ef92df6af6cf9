#include "tools/render/report_html.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace epitrack::render::report_html {

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

std::string figure(const std::string& id, const std::string& title, const std::string& svg,
                   const std::string& caption) {
  return "<section id=\"" + id + "\">\n<h2>" + escapeHtml(title) + "</h2>\n<figure>\n" + svg +
         "</svg>\n<figcaption>" + caption + "</figcaption>\n</figure>\n</section>\n";
}

}  // namespace epitrack::render::report_html

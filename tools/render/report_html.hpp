#pragma once

// Small HTML/SVG helpers shared by the sections of report.html (report_writer.cpp,
// report_views.cpp). Internal to tools/render.

#include <limits>
#include <string>
#include <vector>

namespace epitrack::render::report_html {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Escapes &, <, > and " for text and attribute values.
std::string escapeHtml(const std::string& s);
/// `v` with `digits` decimals, "n/a" when not finite (shown text never says nan).
std::string fmt(int digits, double v);
/// A number in a data-values attribute: 7 significant digits, "nan" for gaps.
std::string dataNumber(double v);
/// Space-separated dataNumber()s.
std::string dataValues(const std::vector<double>& values);
/// An SVG coordinate (one decimal).
std::string px(double v);
/// A 1-2-5 step giving about `target` intervals over [lo, hi].
double niceStep(double lo, double hi, int target);
/// A tick label with as many decimals as `step` needs.
std::string tickLabel(double v, double step);
/// The value below which `fraction` of the finite values lie (NaN when there are none).
double quantile(std::vector<double> v, double fraction);
/// A <section> with a title and a <figure> around `svg` (an open <svg> element: closed here).
std::string figure(const std::string& id, const std::string& title, const std::string& svg,
                   const std::string& caption);

}  // namespace epitrack::render::report_html

// SVG rendering of stacked line plots. Axis ranges come from the data (with reference lines and
// bands included), ticks are 1-2-5 multiples, long series are drawn as one polyline each.
#include "app/svg_plot.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>

#include "core/number_text.hpp"

namespace ncd::app {
namespace {

struct Range {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  void add(double v) {
    if (std::isfinite(v)) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
  }
  void pad() {
    if (!std::isfinite(lo)) lo = 0.0, hi = 1.0;
    if (hi - lo < 1e-12 * std::max(1.0, std::abs(hi))) {
      const double d = std::max(1e-9, 0.05 * std::abs(hi));
      lo -= d;
      hi += d;
    }
    const double m = 0.05 * (hi - lo);
    lo -= m;
    hi += m;
  }
};

// Tick step: 1, 2 or 5 times a power of ten, about `count` ticks over the range.
double tick_step(double span, int count) {
  const double raw = span / count;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * p >= raw) return m * p;
  }
  return 10.0 * p;
}

std::string esc(const std::string& s) {
  std::string out;
  for (const char c : s) {
    switch (c) {
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '&':
        out += "&amp;";
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

}  // namespace

std::string render_svg(const Figure& fig) {
  const int left = 80, right = 210, top = 64, gap = 50, bottom = 50;
  const int plot_w = fig.width_px - left - right;
  const int n = static_cast<int>(fig.panels.size());
  const int height = top + n * fig.panel_height_px + (n - 1) * gap + bottom;
  Range xr;
  for (const Panel& p : fig.panels) {
    for (const Series& s : p.series) {
      for (const double v : s.x) xr.add(v);
    }
  }
  if (!std::isfinite(xr.lo)) xr.lo = 0.0, xr.hi = 1.0;
  if (xr.hi <= xr.lo) xr.hi = xr.lo + 1.0;
  std::ostringstream o;
  o << std::setprecision(7);
  o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << fig.width_px << "\" height=\""
    << height << "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  o << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  o << "<text x=\"" << fig.width_px / 2 << "\" y=\"22\" text-anchor=\"middle\" font-size=\"16\">"
    << esc(fig.title) << "</text>\n";
  for (int i = 0; i < n; ++i) {
    const Panel& p = fig.panels[static_cast<std::size_t>(i)];
    const int y0 = top + i * (fig.panel_height_px + gap);
    const int h = fig.panel_height_px;
    Range yr;
    for (const Series& s : p.series) {
      for (const double v : s.y) yr.add(v);
    }
    for (const RefLine& l : p.lines) yr.add(l.y);
    for (const Band& b : p.bands) yr.add(b.y_lo), yr.add(b.y_hi);
    yr.pad();
    const auto px = [&](double x) { return left + (x - xr.lo) / (xr.hi - xr.lo) * plot_w; };
    const auto py = [&](double y) { return y0 + h - (y - yr.lo) / (yr.hi - yr.lo) * h; };
    o << "<text x=\"" << left << "\" y=\"" << y0 - 8 << "\" font-size=\"13\">" << esc(p.title)
      << "</text>\n";
    for (const Band& b : p.bands) {
      o << "<rect x=\"" << left << "\" y=\"" << py(b.y_hi) << "\" width=\"" << plot_w
        << "\" height=\"" << py(b.y_lo) - py(b.y_hi) << "\" fill=\"" << b.color
        << "\" fill-opacity=\"0.15\"/>\n";
    }
    // Grid and ticks.
    const double ys = tick_step(yr.hi - yr.lo, 5);
    for (double v = std::ceil(yr.lo / ys) * ys; v <= yr.hi; v += ys) {
      o << "<line x1=\"" << left << "\" x2=\"" << left + plot_w << "\" y1=\"" << py(v) << "\" y2=\""
        << py(v) << "\" stroke=\"#ddd\"/>\n";
      o << "<text x=\"" << left - 6 << "\" y=\"" << py(v) + 4 << "\" text-anchor=\"end\">"
        << text::tick(v, ys) << "</text>\n";
    }
    const double xs = tick_step(xr.hi - xr.lo, 8);
    for (double v = std::ceil(xr.lo / xs) * xs; v <= xr.hi; v += xs) {
      o << "<line x1=\"" << px(v) << "\" x2=\"" << px(v) << "\" y1=\"" << y0 << "\" y2=\"" << y0 + h
        << "\" stroke=\"#eee\"/>\n";
      o << "<text x=\"" << px(v) << "\" y=\"" << y0 + h + 16 << "\" text-anchor=\"middle\">"
        << text::tick(v, xs) << "</text>\n";
    }
    o << "<rect x=\"" << left << "\" y=\"" << y0 << "\" width=\"" << plot_w << "\" height=\"" << h
      << "\" fill=\"none\" stroke=\"black\"/>\n";
    o << "<text transform=\"translate(" << 18 << "," << y0 + h / 2
      << ") rotate(-90)\" text-anchor=\"middle\">" << esc(p.y_label) << "</text>\n";
    int legend_y = y0 + 12;
    const int legend_x = left + plot_w + 12;
    for (const RefLine& l : p.lines) {
      o << "<line x1=\"" << left << "\" x2=\"" << left + plot_w << "\" y1=\"" << py(l.y)
        << "\" y2=\"" << py(l.y) << "\" stroke=\"" << l.color << "\" stroke-dasharray=\"6,4\"/>\n";
      o << "<line x1=\"" << legend_x << "\" x2=\"" << legend_x + 20 << "\" y1=\"" << legend_y - 4
        << "\" y2=\"" << legend_y - 4 << "\" stroke=\"" << l.color
        << "\" stroke-dasharray=\"6,4\"/><text x=\"" << legend_x + 26 << "\" y=\"" << legend_y
        << "\">" << esc(l.label) << "</text>\n";
      legend_y += 16;
    }
    for (const Band& b : p.bands) {
      o << "<rect x=\"" << legend_x << "\" y=\"" << legend_y - 10 << "\" width=\"20\" height=\"10\""
        << " fill=\"" << b.color << "\" fill-opacity=\"0.3\"/><text x=\"" << legend_x + 26
        << "\" y=\"" << legend_y << "\">" << esc(b.label) << "</text>\n";
      legend_y += 16;
    }
    for (const Series& s : p.series) {
      o << "<polyline fill=\"none\" stroke=\"" << s.color << "\" stroke-width=\"1.5\""
        << (s.dashed ? " stroke-dasharray=\"4,3\"" : "") << " points=\"";
      const std::size_t m = std::min(s.x.size(), s.y.size());
      for (std::size_t k = 0; k < m; ++k) {
        if (std::isfinite(s.x[k]) && std::isfinite(s.y[k])) {
          o << px(s.x[k]) << "," << py(s.y[k]) << " ";
        }
      }
      o << "\"/>\n";
      o << "<line x1=\"" << legend_x << "\" x2=\"" << legend_x + 20 << "\" y1=\"" << legend_y - 4
        << "\" y2=\"" << legend_y - 4 << "\" stroke=\"" << s.color << "\" stroke-width=\"2\""
        << (s.dashed ? " stroke-dasharray=\"4,3\"" : "") << "/><text x=\"" << legend_x + 26
        << "\" y=\"" << legend_y << "\">" << esc(s.name) << "</text>\n";
      legend_y += 16;
    }
  }
  o << "<text x=\"" << left + plot_w / 2 << "\" y=\"" << height - 12 << "\" text-anchor=\"middle\">"
    << esc(fig.x_label) << "</text>\n";
  o << "</svg>\n";
  return o.str();
}

}  // namespace ncd::app

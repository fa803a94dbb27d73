// A small SVG line-plot writer for the figures a person would rather look at than read:
// stacked panels sharing an x axis, each with series, reference lines and shaded bands.
#pragma once

#include <string>
#include <vector>

namespace ncd::app {

struct Series {
  std::string name;
  std::vector<double> x, y;
  std::string color = "#1f77b4";
  bool dashed = false;
};

struct RefLine {
  double y = 0.0;
  std::string label;
  std::string color = "#d62728";
};

struct Band {
  double y_lo = 0.0, y_hi = 0.0;
  std::string label;
  std::string color = "#2ca02c";
};

struct Panel {
  std::string title;
  std::string y_label;
  std::vector<Series> series;
  std::vector<RefLine> lines;
  std::vector<Band> bands;
};

struct Figure {
  std::string title;
  std::string x_label;
  std::vector<Panel> panels;
  int width_px = 900;
  int panel_height_px = 220;
};

// Renders the figure as a standalone SVG document. Non-finite samples are skipped.
std::string render_svg(const Figure& figure);

}  // namespace ncd::app

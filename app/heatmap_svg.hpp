// A height or roughness map as an SVG: the values as a PNG image (zlib-compressed, embedded as
// a data URI) on axes in mm, with a colour scale. Used by `ncd simulate`.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ncd::app {

struct HeatMap {
  std::string title;
  std::string value_label;  // the colour scale's name with its unit
  int nx = 0, ny = 0;       // values row-major, row 0 at y_min
  std::vector<double> values;
  double x_min_mm = 0.0, x_max_mm = 1.0, y_min_mm = 0.0, y_max_mm = 1.0;
  std::string x_label = "x (mm)", y_label = "y (mm)";
  std::vector<std::string> notes;  // lines under the title
  int max_image_px = 1200;         // larger grids are subsampled for the picture
};

// An 8-bit RGB PNG (colour type 2) of w × h pixels, rows top to bottom.
std::string encode_png_rgb(int width, int height, const std::vector<std::uint8_t>& rgb);

// Non-finite values are drawn grey and left out of the colour scale.
std::string render_heatmap_svg(const HeatMap& map);

}  // namespace ncd::app

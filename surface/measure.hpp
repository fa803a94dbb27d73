// Roughness measured on a Z-map (docs/surface-simulation.md §4): R_max, the peak-to-valley
// height of the residual surface measured normal to a reference plane, over a region, along
// each row (x, the raster's feed direction) and each column (y, across the feed); and a map of
// R_max over windows of the patch beside the model's prediction for the move that cut each one.
#pragma once

#include <cstdint>
#include <vector>

#include "surface/zmap.hpp"

namespace ncd::surface {

// z = z0 + gx·x + gy·y: the surface the tool was meant to leave.
struct Plane {
  double z0_mm = 0.0, grad_x = 0.0, grad_y = 0.0;
  double at_mm(double x_mm, double y_mm) const { return z0_mm + grad_x * x_mm + grad_y * y_mm; }
};

struct CellRegion {
  int i0 = 0, i1 = 0, j0 = 0, j1 = 0;  // cells [i0, i1) × [j0, j1)
};

struct Roughness {
  double rmax_um = 0.0;                   // areal peak to valley of the residual
  double along_um = 0.0;                  // largest peak to valley along a row (x)
  double across_um = 0.0;                 // largest peak to valley along a column (y)
  double peak_um = 0.0, valley_um = 0.0;  // extremes of the residual above the reference
  double peak_x_mm = 0.0, peak_y_mm = 0.0, valley_x_mm = 0.0, valley_y_mm = 0.0;
  std::int64_t cells = 0, uncut_cells = 0;  // uncut: never lowered by an edge
};

// The residual is (z − reference)/sqrt(1 + gx² + gy²), the distance normal to the reference.
// Throws InputError if the region is empty or outside the map.
Roughness measure(const ZMap& map, const Plane& reference, const CellRegion& region);

// The least-squares plane through the heights of a region.
Plane fit_plane(const ZMap& map, const CellRegion& region);

struct RmaxWindow {
  double x_mm = 0.0, y_mm = 0.0;  // centre
  double rmax_um = 0.0;           // peak to valley from the reference (or the best plane)
  double model_um = 0.0;          // the model for the move that cut the centre cell; NaN if none
  bool cut = false;               // every cell of the window was cut
};

struct RmaxMap {
  int nx = 0, ny = 0;  // windows along x and y
  double window_x_mm = 0.0, window_y_mm = 0.0;
  std::vector<RmaxWindow> windows;  // row-major, nx·ny
};

// R_max over windows of about window_x × window_y (whole cells, at least 3 × 3), tiling the map,
// measured from `reference` when given (the nominal surface), else from each window's own
// least-squares plane; model_um_by_move[k] is the model's R_max for move k. Throws InputError on a
// window that is not positive and finite.
RmaxMap rmax_map(const ZMap& map, double window_x_mm, double window_y_mm,
                 const std::vector<double>& model_um_by_move, const Plane* reference = nullptr);

}  // namespace ncd::surface

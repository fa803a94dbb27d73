// See measure.hpp. R_max is the peak-to-valley height of the residual surface (the definition of
// paper 004's eqs. 2–3: the highest point left above the deepest cut, normal to the surface),
// measured areally, along rows and along columns (docs/surface-simulation.md §4).
#include "surface/measure.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "core/error.hpp"

namespace ncd::surface {
namespace {

void check(const ZMap& map, const CellRegion& r) {
  if (r.i0 < 0 || r.j0 < 0 || r.i1 > map.nx() || r.j1 > map.ny() || r.i0 >= r.i1 || r.j0 >= r.j1) {
    throw InputError("the region of cells [" + std::to_string(r.i0) + ", " + std::to_string(r.i1) +
                     ") x [" + std::to_string(r.j0) + ", " + std::to_string(r.j1) +
                     ") is empty or outside the map of " + std::to_string(map.nx()) + " x " +
                     std::to_string(map.ny()) + " cells");
  }
}

}  // namespace

Roughness measure(const ZMap& map, const Plane& ref, const CellRegion& region) {
  check(map, region);
  const double norm = std::sqrt(1.0 + ref.grad_x * ref.grad_x + ref.grad_y * ref.grad_y);
  Roughness out;
  double hi = -std::numeric_limits<double>::infinity(), lo = -hi;
  const int w = region.i1 - region.i0;
  std::vector<double> col_hi(static_cast<std::size_t>(w), hi),
      col_lo(static_cast<std::size_t>(w), lo);
  for (int j = region.j0; j < region.j1; ++j) {
    double row_hi = -std::numeric_limits<double>::infinity(), row_lo = -row_hi;
    for (int i = region.i0; i < region.i1; ++i) {
      const double e = (map.z_mm(i, j) - ref.at_mm(map.x_mm(i), map.y_mm(j))) / norm;
      row_hi = std::max(row_hi, e);
      row_lo = std::min(row_lo, e);
      const auto c = static_cast<std::size_t>(i - region.i0);
      col_hi[c] = std::max(col_hi[c], e);
      col_lo[c] = std::min(col_lo[c], e);
      if (e > hi) {
        hi = e;
        out.peak_x_mm = map.x_mm(i);
        out.peak_y_mm = map.y_mm(j);
      }
      if (e < lo) {
        lo = e;
        out.valley_x_mm = map.x_mm(i);
        out.valley_y_mm = map.y_mm(j);
      }
      ++out.cells;
      if (map.cut_by(i, j) < 0) ++out.uncut_cells;
    }
    out.along_um = std::max(out.along_um, (row_hi - row_lo) * 1e3);
  }
  for (std::size_t c = 0; c < col_hi.size(); ++c) {
    out.across_um = std::max(out.across_um, (col_hi[c] - col_lo[c]) * 1e3);
  }
  out.peak_um = hi * 1e3;
  out.valley_um = lo * 1e3;
  out.rmax_um = (hi - lo) * 1e3;
  return out;
}

Plane fit_plane(const ZMap& map, const CellRegion& region) {
  check(map, region);
  // Centred coordinates keep the normal equations well conditioned.
  const double xc = 0.5 * (map.x_mm(region.i0) + map.x_mm(region.i1 - 1));
  const double yc = 0.5 * (map.y_mm(region.j0) + map.y_mm(region.j1 - 1));
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (int j = region.j0; j < region.j1; ++j) {
    for (int i = region.i0; i < region.i1; ++i) {
      const Eigen::Vector3d v(1.0, map.x_mm(i) - xc, map.y_mm(j) - yc);
      a += v * v.transpose();
      b += v * map.z_mm(i, j);
    }
  }
  const Eigen::Vector3d p = a.ldlt().solve(b);
  Plane out;
  out.grad_x = (region.i1 - region.i0 > 1) ? p(1) : 0.0;
  out.grad_y = (region.j1 - region.j0 > 1) ? p(2) : 0.0;
  out.z0_mm = p(0) - out.grad_x * xc - out.grad_y * yc;
  return out;
}

RmaxMap rmax_map(const ZMap& map, double window_x_mm, double window_y_mm,
                 const std::vector<double>& model_um_by_move, const Plane* reference) {
  require_positive("window_x_mm", window_x_mm);
  require_positive("window_y_mm", window_y_mm);
  const double h = map.cell_mm();
  const int wx = std::max(3, static_cast<int>(std::lround(window_x_mm / h)));
  const int wy = std::max(3, static_cast<int>(std::lround(window_y_mm / h)));
  RmaxMap out;
  out.nx = std::max(1, map.nx() / wx);
  out.ny = std::max(1, map.ny() / wy);
  out.window_x_mm = wx * h;
  out.window_y_mm = wy * h;
  for (int wj = 0; wj < out.ny; ++wj) {
    for (int wi = 0; wi < out.nx; ++wi) {
      const CellRegion reg{wi * wx, std::min(map.nx(), (wi + 1) * wx), wj * wy,
                           std::min(map.ny(), (wj + 1) * wy)};
      const Roughness r = measure(map, reference ? *reference : fit_plane(map, reg), reg);
      RmaxWindow w;
      w.x_mm = 0.5 * (map.x_mm(reg.i0) + map.x_mm(reg.i1 - 1));
      w.y_mm = 0.5 * (map.y_mm(reg.j0) + map.y_mm(reg.j1 - 1));
      w.rmax_um = r.rmax_um;
      w.cut = r.uncut_cells == 0;
      const std::int32_t k = map.cut_by((reg.i0 + reg.i1) / 2, (reg.j0 + reg.j1) / 2);
      w.model_um = (k >= 0 && static_cast<std::size_t>(k) < model_um_by_move.size())
                       ? model_um_by_move[static_cast<std::size_t>(k)]
                       : std::numeric_limits<double>::quiet_NaN();
      out.windows.push_back(w);
    }
  }
  return out;
}

}  // namespace ncd::surface

// See zmap.hpp; the grid's validation lives here.
#include "surface/zmap.hpp"

#include <cmath>
#include <string>

#include "core/error.hpp"

namespace ncd::surface {
namespace {

std::string num(double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

int cells_along(const char* axis, double lo, double hi, double h) {
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(hi > lo)) {
    throw InputError(std::string("the patch's ") + axis + " range [" + num(lo) + ", " + num(hi) +
                     "] mm is empty or not finite: give a minimum below the maximum");
  }
  const double n = std::ceil((hi - lo) / h - 1e-9);
  if (n > static_cast<double>(kMaxCells)) {
    throw InputError(std::string("the patch's ") + axis + " range of " + num(hi - lo) +
                     " mm at a cell of " + num(h) + " mm needs " + num(n) + " cells, above " +
                     num(static_cast<double>(kMaxCells)) +
                     ": use a coarser cell or a smaller patch");
  }
  return static_cast<int>(n);
}

}  // namespace

ZMap::ZMap(const GridSpec& spec, const InitialSurface& surface)
    : x0_(spec.x_min_mm), y0_(spec.y_min_mm), h_(spec.cell_mm), surface_(surface) {
  require_positive("cell_mm", spec.cell_mm);
  nx_ = cells_along("x", spec.x_min_mm, spec.x_max_mm, h_);
  ny_ = cells_along("y", spec.y_min_mm, spec.y_max_mm, h_);
  const double total = static_cast<double>(nx_) * static_cast<double>(ny_);
  if (total > static_cast<double>(kMaxCells)) {
    throw InputError("the patch needs " + num(total) + " cells (" + std::to_string(nx_) + " x " +
                     std::to_string(ny_) + " at " + num(h_) + " mm), above the limit of " +
                     num(static_cast<double>(kMaxCells)) +
                     ": use a coarser cell (--cell-um) or a smaller patch");
  }
  const std::size_t n = static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_);
  z_.resize(n);
  cut_by_.assign(n, -1);
  for (int j = 0; j < ny_; ++j) {
    for (int i = 0; i < nx_; ++i) {
      const double z = surface_.at_mm(x_mm(i), y_mm(j));
      if (!std::isfinite(z)) {
        throw InputError("the initial surface is not finite at x = " + num(x_mm(i)) +
                         " mm, y = " + num(y_mm(j)) + " mm: give a height function defined " +
                         "over the whole patch");
      }
      z_[index(i, j)] = z;
    }
  }
}

}  // namespace ncd::surface

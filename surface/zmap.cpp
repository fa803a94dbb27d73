// See zmap.hpp; the grid's validation lives here.
#include "surface/zmap.hpp"

#include <cmath>
#include <string>

#include "core/error.hpp"
#include "core/number_text.hpp"

namespace ncd::surface {
namespace {

int cells_along(const char* axis, double lo, double hi, double h) {
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(hi > lo)) {
    throw InputError(std::string("the patch's ") + axis + " range [" + text::sig(lo) + ", " +
                     text::sig(hi) +
                     "] mm is empty or not finite: give a minimum below the maximum");
  }
  const double n = std::ceil((hi - lo) / h - 1e-9);
  if (n > static_cast<double>(kMaxCells)) {
    throw InputError(std::string("the patch's ") + axis + " range of " + text::sig(hi - lo) +
                     " mm at a cell of " + text::sig(h) + " mm needs " + text::sig(n) +
                     " cells, above " + text::sig(static_cast<double>(kMaxCells)) +
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
    throw InputError("the patch needs " + text::sig(total) + " cells (" + std::to_string(nx_) +
                     " x " + std::to_string(ny_) + " at " + text::sig(h_) +
                     " mm), above the limit of " + text::sig(static_cast<double>(kMaxCells)) +
                     ": use a coarser cell (--cell-um) or a smaller patch");
  }
  const std::size_t n = static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_);
  z_.resize(n);
  cut_by_.assign(n, -1);
  for (int j = 0; j < ny_; ++j) {
    for (int i = 0; i < nx_; ++i) {
      const double z = surface_.at_mm(x_mm(i), y_mm(j));
      if (!std::isfinite(z)) {
        throw InputError("the initial surface is not finite at x = " + text::sig(x_mm(i)) +
                         " mm, y = " + text::sig(y_mm(j)) + " mm: give a height function defined " +
                         "over the whole patch");
      }
      z_[index(i, j)] = z;
    }
  }
}

}  // namespace ncd::surface

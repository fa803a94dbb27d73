// The Z-map: a grid of heights over a rectangular patch of the workpiece
// (docs/surface-simulation.md §2). Cell (i, j) covers [x0 + i h, x0 + (i+1) h) × [y0 + j h, y0 +
// (j+1) h); its height is that of the surface at the cell's centre. Each cell also remembers which
// move of the tool cut it last (−1: never cut), so that a roughness map can ask the model about the
// feed and the inclination that made each place.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

namespace ncd::surface {

// The initial surface: the plane z = z0 + gx·x + gy·y (a slope of angle atan(gx) along x for the
// paper's up- and down-milling), or any height function; a height function also names the
// plane that lies on or above it everywhere on the patch (the simulation skips every edge point
// above that plane).
struct InitialSurface {
  double z0_mm = 0.0;
  double grad_x = 0.0;                                     // dz/dx
  double grad_y = 0.0;                                     // dz/dy
  std::function<double(double x_mm, double y_mm)> height;  // empty: the plane itself

  double plane_mm(double x_mm, double y_mm) const { return z0_mm + grad_x * x_mm + grad_y * y_mm; }
  double at_mm(double x_mm, double y_mm) const {
    return height ? height(x_mm, y_mm) : plane_mm(x_mm, y_mm);
  }
};

// The patch and its resolution. Throws InputError naming the value when the extent is empty or
// not finite, the cell is not positive, or the grid would exceed kMaxCells.
struct GridSpec {
  double x_min_mm = 0.0, x_max_mm = 1.0;
  double y_min_mm = 0.0, y_max_mm = 1.0;
  double cell_mm = 0.005;
};

inline constexpr std::int64_t kMaxCells = 200'000'000;  // 1.6 GB of heights: a clear limit

class ZMap {
 public:
  ZMap(const GridSpec& spec, const InitialSurface& surface);

  int nx() const { return nx_; }
  int ny() const { return ny_; }
  double cell_mm() const { return h_; }
  double x0_mm() const { return x0_; }
  double y0_mm() const { return y0_; }
  double x_mm(int i) const { return x0_ + (i + 0.5) * h_; }  // centre of column i
  double y_mm(int j) const { return y0_ + (j + 0.5) * h_; }  // centre of row j
  std::int64_t cells() const { return static_cast<std::int64_t>(nx_) * ny_; }

  double z_mm(int i, int j) const { return z_[index(i, j)]; }
  std::int32_t cut_by(int i, int j) const { return cut_by_[index(i, j)]; }
  // Raw rows for the simulation's inner loop: row j starts at z_row(j)[0].
  double* z_row(int j) {
    return z_.data() + static_cast<std::size_t>(j) * static_cast<std::size_t>(nx_);
  }
  std::int32_t* cut_row(int j) {
    return cut_by_.data() + static_cast<std::size_t>(j) * static_cast<std::size_t>(nx_);
  }
  const InitialSurface& initial() const { return surface_; }

 private:
  std::size_t index(int i, int j) const {
    return static_cast<std::size_t>(j) * static_cast<std::size_t>(nx_) +
           static_cast<std::size_t>(i);
  }
  double x0_, y0_, h_;
  int nx_, ny_;
  InitialSurface surface_;
  std::vector<double> z_;
  std::vector<std::int32_t> cut_by_;
};

}  // namespace ncd::surface

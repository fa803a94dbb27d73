// The runs the simulation cuts (docs/surface-simulation.md §5): a raster of straight passes at a
// pick feed over a plane or a slope, as in paper 004's Figs. 13–15 and its Fig. 6 map, and the
// setpoints of a run recorded by `ncd replay --setpoints`.
#pragma once

#include <istream>
#include <string>
#include <vector>

#include "surface/cutter.hpp"
#include "surface/measure.hpp"
#include "surface/zmap.hpp"

namespace ncd::surface {

struct RasterSpec {
  double pick_feed_mm = 0.5;       // f_p, between neighbouring passes (along y)
  double feed_per_tooth_mm = 0.5;  // f_t, along each pass (the path, on the slope)
  double inclination_deg = 0.0;    // α: the surface rises by tan α along +x; passes go +x, so
                                   // α > 0 is up-milling and α < 0 down-milling
  double stock_mm = 0.05;          // material above the final surface, normal to it
  double patch_x_mm = 0.0;         // evaluated patch [0, X] × [0, Y]; 0: two revolutions' feed
  double patch_y_mm = 0.0;         // 0: two pick feeds
  double cell_mm = 0.0;            // 0: f_t / 100
  bool zigzag = false;             // odd passes run −x (alternating up- and down-milling)
  double phase_step_deg = 0.0;     // the spindle angle at the start of pass j is j·phase_step
};

struct RasterRun {
  GridSpec grid;
  InitialSurface initial;
  Plane nominal;  // the surface the ball touches: z = tan α · x
  std::vector<Move> moves;
  double feed_mm_per_min = 0.0;
  int passes = 0;
};

// Passes at y = j·f_p covering the patch and every pass whose cut can reach it, each long enough
// that the patch lies wholly inside the cut. Throws InputError naming the value for f_p, f_t,
// stock or cell not positive, |α| ≥ 60°, f_p ≥ 2r, stock ≥ r, or an invalid tool.
RasterRun make_raster(const RasterSpec& spec, const BallEndMill& tool);

// The setpoints CSV of `ncd replay --setpoints` (header t_s,x_mm,y_mm,z_mm,...; the positions
// are the tool tip) as moves between consecutive rows, the spindle turning continuously from
// angle 0 at the first row. Throws InputError naming the line for a missing header, a short or
// unreadable row, a time going backwards, or fewer than two rows.
std::vector<Move> read_setpoints_csv(std::istream& in, const std::string& name,
                                     const BallEndMill& tool);

}  // namespace ncd::surface

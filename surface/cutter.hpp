// The ball-end mill over the Z-map: z cutting edges on the sphere turn at the spindle speed while
// the tool moves, and every edge point lowers the height of the cell it passes over (min-z).
// The algorithm (edge model, time resolution, tiles) is explained once, in cutter.cpp; the
// decisions are in docs/surface-simulation.md.
#pragma once

#include <cstdint>
#include <vector>

#include "core/geometry.hpp"
#include "surface/zmap.hpp"

namespace ncd::surface {

struct BallEndMill {
  double radius_mm = 5.0;        // r
  int teeth = 2;                 // z edges, evenly spaced around the axis
  double spindle_rpm = 10000.0;  // N
  double helix_deg = 0.0;        // 0: straight edges in axial planes; else the edge lags the tip
                                 // by tan(helix)·(1 − cos φ) rad at polar angle φ from the tip
  bool clockwise = true;         // M3: clockwise seen from the spindle, a turn about −Z
};

// Throws InputError naming the value: r, N not positive; teeth outside [1, 64]; helix outside
// [0, 60)°.
void validate(const BallEndMill& tool);

// A straight motion of the tool tip (the lowest point of the ball; its centre is r above) from
// `from` at t0 to `to` at t1 with the spindle turning; edge 0 points along spindle0_rad (from
// +X towards +Y) at t0. Moves need not be contiguous in time (a raster's passes).
struct Move {
  Vec3 from_mm = Vec3::Zero();
  Vec3 to_mm = Vec3::Zero();
  double t0_s = 0.0;
  double t1_s = 0.0;
  double spindle0_rad = 0.0;
};

struct SimOptions {
  int threads = 0;               // 0: every core (std::thread::hardware_concurrency)
  double sample_fraction = 0.5;  // edge samples and time steps at most this many cells apart
  int tile_cells = 192;          // side of the square tiles the threads share out
};

struct SimStats {
  std::int64_t cell_updates = 0;  // edge samples that fell on a cell and compared heights
  std::int64_t time_steps = 0;    // time steps over all moves (each tile walks its own subset)
  double seconds = 0.0;           // wall time of simulate()
  int threads = 0;
  int tiles = 0;
  double updates_per_s() const {
    return seconds > 0.0 ? static_cast<double>(cell_updates) / seconds : 0.0;
  }
};

// Cuts the moves into the map. Deterministic: the result does not depend on the number of
// threads. Throws InputError for an invalid tool, a non-finite move, t1 < t0, more than 2^31
// moves, or a sample_fraction outside (0, 1].
SimStats simulate(ZMap& map, const BallEndMill& tool, const std::vector<Move>& moves,
                  const SimOptions& options = {});

}  // namespace ncd::surface

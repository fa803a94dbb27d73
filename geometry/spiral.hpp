// A long synthetic path for benchmarks and the latency harness: an Archimedean spiral as a
// cubic B-spline, the kind of long smooth program a pocketing or finishing pass produces.
#pragma once

#include "geometry/path.hpp"

namespace ncd::toolpath {

// `turns` turns from r = 100 mm inwards at 0.1 mm pitch (so at most 999), z waving ±2 mm,
// 16 control points per turn, integer knots (as LinuxCNC's G5.2 builds them). Throws
// InputError outside 1..999 turns.
Path spiral_path(int turns);

// Its arc length, about 2π (100 k − 0.05 k²) mm for k turns.
double spiral_length_mm(int turns);

}  // namespace ncd::toolpath

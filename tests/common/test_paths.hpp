// Paths that several test binaries walk, as JSON path files (gcode/path_io.hpp reads them).
#pragma once

namespace ncd::test {

// The cubic of examples/cubic.json without its feed: a degree-3 B-spline from (0, 0, 0) to
// (100, 0, 0) with three interior knots, rising to z = 4 mm.
inline constexpr const char* kCubicJson =
    R"({"nurbs": {"degree": 3, "knots": [0,0,0,0,0.25,0.5,0.75,1,1,1,1],
  "points": [[0,0,0],[10,25,0],[30,-10,2],[45,30,4],[60,0,3],[80,20,0],[100,0,0]]}})";

// A full circle of radius 20 mm about the origin in the XY plane: four rational quadratic
// quarter arcs (middle weights √2/2) joined at double knots.
inline constexpr const char* kCircleJson = R"({"nurbs": {"degree": 2,
  "knots": [0,0,0,0.25,0.25,0.5,0.5,0.75,0.75,1,1,1],
  "points": [[20,0,0],[20,20,0],[0,20,0],[-20,20,0],[-20,0,0],[-20,-20,0],[0,-20,0],
             [20,-20,0],[20,0,0]],
  "weights": [1,0.7071067811865476,1,0.7071067811865476,1,0.7071067811865476,1,
              0.7071067811865476,1]}})";

}  // namespace ncd::test

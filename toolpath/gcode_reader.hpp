// RS-274/NGC reader for the subset of LinuxCNC G-code that describes a 3-axis path in mm.
//
// Read and turned into geometry:
//   G0 / G1 (modal)  straight moves; X Y Z absolute mm; consecutive moves with the same rapid
//                    state, feed and spindle speed form one Polyline segment
//   G5.2 … G5.3      LinuxCNC NURBS block in the XY plane (X Y P per control point, L order):
//                    one NurbsCurve segment, knot vector as LinuxCNC builds it (gcode_reader.cpp)
//   F                feed, mm/min (> 0)        S   spindle speed, rpm (≥ 0)
//   M3 / M5          spindle on (clockwise) / off      M2 / M30   end of program
// Accepted and ignored because they leave the programmed geometry unchanged:
//   G17 (XY plane), G21 (mm), G40 (cutter compensation off), G49 (tool length offset off),
//   G61, G61.1, G64 [P- [Q-]] (path blending, tolerance), G80 (cancel canned cycle: no motion
//   mode), G90 (absolute), G94 (feed per minute), N line numbers, comments ( … ) and ; …,
//   % lines, blank lines. Spaces inside words are removed, letters are case-insensitive (as
//   LinuxCNC does).
// Everything else is an InputError with the line number and text: G20 (inch) and G91
// (incremental) say they are unsupported; G2/G3 arcs, other G and M codes, other letters (T, I,
// J, O, …), parameters and expressions (#, [ ]), block delete (/), malformed numbers, a letter
// or modal group twice on one line, a G1 or G5.2 before X, Y and Z are all known, an unclosed
// G5.2 block, a program with no move.
//
// Moves made before X, Y and Z have all been programmed start from an unknown machine position:
// a G0 there only sets the position, it adds no segment; a G1 or G5.2 there is an error. A move
// to the current position adds nothing. Reading stops at M2, M30 or a closing % line.
#pragma once

#include <istream>
#include <string>

#include "toolpath/path.hpp"

namespace ncd::toolpath {

// Reads a whole program; `name` (a file name) prefixes every error message and becomes
// Path::source. Throws InputError.
Path read_gcode(std::istream& in, const std::string& name);

}  // namespace ncd::toolpath

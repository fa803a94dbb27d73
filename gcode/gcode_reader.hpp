// The planner's entry to RS-274/NGC: the interpreter (ngc_interpreter.hpp, LinuxCNC's dialect,
// docs/ngc-interpreter.md) followed by to_path (program.hpp): lines become Polyline runs, arcs
// exact rational NURBS, everything in mm and machine coordinates.
//
// Kept from the former reader: moves made before X, Y and Z have all been programmed start
// from an unknown machine position, so a rapid there only sets the position and a feed move
// there is an error; a move to the current position adds nothing; a program with no move is
// an error.
#pragma once

#include <istream>
#include <string>

#include "gcode/ngc/interpreter.hpp"
#include "geometry/path.hpp"

namespace ncd::toolpath {

// Reads a whole program; `name` (a file name) prefixes every error message and becomes
// Path::source. Throws InputError.
Path read_gcode(std::istream& in, const std::string& name, const InterpretOptions& options = {});

}  // namespace ncd::toolpath

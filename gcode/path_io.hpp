// Reading a Path from a file, whatever wrote it. The content decides the format:
//
// (a) the JSON of `ncd chamfer` (an object with "points", each with "cl" [x,y,z] and "e"):
//     one closed Polyline through the cutter locations (ball centres, part frame; not the
//     program point of the NC program), the first point repeated at the end, contact normal
//     −e at every point; feed from input.feed_mm_per_min, spindle from input.spindle_rpm;
// (b) a JSON path file, lengths in mm:
//       {"nurbs": {"degree": 3, "knots": [...], "points": [[x,y,z], ...], "weights": [...]}}
//       {"polyline": {"points": [[x,y,z], ...], "normals": [[x,y,z], ...]}}
//     "weights" and "normals" optional; optional top-level "feed_mm_per_min" and "spindle_rpm";
// (c) RS-274/NGC, anything whose first non-blank character is not '{' (gcode_reader.hpp).
#pragma once

#include <string>

#include "gcode/ngc/interpreter.hpp"
#include "geometry/path.hpp"

namespace ncd::toolpath {

// Throws InputError naming the file, for JSON the key, and the way out.
// `ngc` applies to RS-274/NGC only (tool table, parameter file, units, subroutine path).
Path read_path_file(const std::string& filename, const InterpretOptions& ngc = {});

// The same on text already in memory; `name` stands for the file in messages.
Path read_path_text(const std::string& text, const std::string& name,
                    const InterpretOptions& ngc = {});

}  // namespace ncd::toolpath

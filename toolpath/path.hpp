// The path `ncd replay` walks: plain data handed from the readers (path_io, gcode_reader) to the
// planner. Each segment is one piece of geometry at one feed, spindle speed and rapid state;
// consecutive segments join end to start.
#pragma once

#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "toolpath/nurbs.hpp"
#include "toolpath/polyline.hpp"

namespace ncd::toolpath {

struct PathSegment {
  std::variant<Polyline, NurbsCurve> geometry;
  std::optional<double> feed_mm_per_min;  // programmed feed; none for rapids or when not given
  std::optional<double> spindle_rpm;      // spindle speed while it turns; none when stopped
  bool rapid = false;                     // G0: the machine's rapid rate, not a cutting feed
  int source_line = 0;                    // 1-based line of the source that opened it; 0 if none
};

struct Path {
  std::vector<PathSegment> segments;
  std::string source;  // file name or stream name the path was read from
};

}  // namespace ncd::toolpath

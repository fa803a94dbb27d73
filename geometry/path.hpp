// The path `ncd replay` walks: plain data handed from the readers (path_io, gcode_reader) to the
// planner. Each segment is one piece of geometry at one feed, spindle speed and rapid state;
// consecutive segments join end to start.
#pragma once

#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "geometry/nurbs.hpp"
#include "geometry/polyline.hpp"
#include "geometry/tool.hpp"

namespace ncd::toolpath {

// How the planner joins a segment to the one before it (RS-274/NGC G61, G61.1, G64).
enum class PathControl {
  blend,       // G64: corners may be rounded within blend_tolerance_mm (or the machine's default)
  exact_path,  // G61: no rounding; the tool passes through every programmed corner exactly
  exact_stop,  // G61.1: the machine comes to rest at the end of every move
};

// An index of the rotary axis (docs/planner.md §3g): the part turned from from_deg to to_deg
// (machine degrees) while X, Y and Z stand still, from rest to rest, with the axis's own limits.
struct RotaryIndex {
  char axis = 'a';  // 'a' (about X) or 'b' (about Y)
  double from_deg = 0.0;
  double to_deg = 0.0;
  std::optional<double> feed_deg_per_min;  // G1: the programmed feed; none: G0, the axis's max
  int source_line = 0;                     // 1-based line of the source; 0 if none
};

struct PathSegment {
  std::variant<Polyline, NurbsCurve> geometry;
  std::optional<double> feed_mm_per_min;  // programmed feed; none for rapids or when not given
  std::optional<double> spindle_rpm;      // spindle speed while it turns; none when stopped
  bool rapid = false;                     // G0: the machine's rapid rate, not a cutting feed
  int source_line = 0;                    // 1-based line of the source that opened it; 0 if none
  PathControl path_control = PathControl::blend;  // mode in force for this segment's corners
  std::optional<double> blend_tolerance_mm;       // G64 P: deviation allowed at a blended corner
  std::optional<double> smoothing_tolerance_mm;   // G64 Q: deviation allowed when smoothing runs
  bool stop_before = false;  // the machine must be at rest where this segment starts (an event
                             // that needs rest precedes it: M0/M1, M6, dwell, spindle change)
  CutterTool tool;           // the tool that cuts it (geometry/tool.hpp): a ball end by default
  // Rotary indexes made at rest where this segment starts, in order, before it moves (stop_before
  // is then set): the programmed A or B moves between the move before and this one.
  std::vector<RotaryIndex> indexes_before;
};

// What a path made by `ncd chamfer` says about itself (its JSON's "input" and "checks"): the
// tool it was made for and whether its interference checks passed. Consumers refuse a failed
// one unless told otherwise, and a machine whose ball radius differs (docs/hardening.md).
struct ChamferOrigin {
  double ball_radius_mm = 0.0;
  bool checks_ok = true;
  std::string failed_checks;  // "local, rod" …; empty when checks_ok
  // What the whole job around the loop needs (docs/whole-program.md): an inner edge is reached
  // down the drill axis, a lower edge is cut with the part turned over, and the clearance plane
  // is the chamfer's own (its "safe_z_mm", drill frame, for the point "program_point" names).
  // A file without them: an upper inner edge, no clearance of its own.
  bool inner_edge = true;
  bool lower_side = false;
  std::optional<double> safe_z_mm;
  bool safe_z_for_tip = true;  // safe_z_mm is a height of the ball tip (false: of its centre)
};

struct Path {
  std::vector<PathSegment> segments;
  std::string source;                    // file name or stream name the path was read from
  std::optional<ChamferOrigin> chamfer;  // set for the JSON of `ncd chamfer`
  // The rotary index axis the path turns ('a', 'b'; 0: none), where it stands at the start
  // (degrees), and the indexes after the last segment (at rest at the path's end).
  char rotary_axis = 0;
  double rotary_start_deg = 0.0;
  std::vector<RotaryIndex> indexes_at_end;
  bool has_indexes() const {
    if (!indexes_at_end.empty()) return true;
    for (const PathSegment& s : segments) {
      if (!s.indexes_before.empty()) return true;
    }
    return false;
  }
};

}  // namespace ncd::toolpath

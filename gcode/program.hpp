// The NC program as the readers hand it on: an ordered list of motions and the events between
// them (spindle, coolant, dwell, tool change, stops, messages, path-control mode), each with its
// source file and line. The RS-274/NGC interpreter (ngc_interpreter.hpp) writes it in the
// program's own units and coordinates, exactly as LinuxCNC's canonical commands carry them; the
// planner reads the Path that to_path() makes of it (millimetres, machine coordinates).
// See docs/ngc-interpreter.md.
#pragma once

#include <array>
#include <map>
#include <optional>
#include <ostream>
#include <string>
#include <variant>
#include <vector>

#include "core/geometry.hpp"
#include "geometry/nurbs.hpp"
#include "geometry/path.hpp"
#include "geometry/polyline.hpp"
#include "geometry/tool.hpp"

namespace ncd::toolpath {

enum class Units { mm, inch };                     // G21, G20
enum class Plane { xy, xz, yz };                   // G17, G18, G19
enum class FeedMode { per_minute, inverse_time };  // G94, G93
enum class SpindleDir { off, cw, ccw };            // M5, M3, M4

constexpr double kMmPerInch = 25.4;
inline double mm_per_unit(Units u) {
  return u == Units::inch ? kMmPerInch : 1.0;
}

struct SourceRef {
  int file = 0;  // index into Program::files
  int line = 0;  // 1-based; 0 when generated
};

// Straight move to `end`.
struct LineMove {
  Vec3 end;
};

// Circular or helical arc in `plane` about `centre`: the centre's two in-plane coordinates
// are what counts, its third coordinate is the start's. `turns` follows LinuxCNC's ARC_FEED
// rotation: +n counter-clockwise (G3), −n clockwise (G2), |n| − 1 extra full turns (P word).
// The axis coordinate moves linearly with the angle from the start's to end's (helix rise).
struct ArcMove {
  Vec3 end;
  Vec3 centre;
  Plane plane = Plane::xy;
  int turns = 1;
};

// G5.2/G5.3 NURBS (control points in program coordinates).
struct NurbsMove {
  NurbsCurve curve;
};

// Generated paths (chamfer, teach) that come as one polyline.
struct PolylineMove {
  Polyline polyline;
};

struct Motion {
  std::variant<LineMove, ArcMove, NurbsMove, PolylineMove> geometry;
  Vec3 start{0, 0, 0};  // program coordinates, program units
  Units units = Units::mm;
  bool rapid = false;
  FeedMode feed_mode = FeedMode::per_minute;
  double feed = 0.0;  // units/min (G94) or 1/min (G93); 0 for rapids
  SpindleDir spindle = SpindleDir::off;
  double spindle_rpm = 0.0;  // programmed S
  int tool = 0;              // tool in the spindle
  Vec3 offset{0, 0, 0};      // program → machine: work offset + G92 + tool length, program units
  bool start_known = true;   // false until X, Y and Z have all been programmed (or homed)
  // Axes whose end the program has given (or a move before it); false: the end on that axis is
  // where the interpreter assumes the machine stands, which nothing on the machine promises.
  std::array<bool, 3> end_known{true, true, true};
  SourceRef src;
};

struct SpindleEvent {
  SpindleDir dir = SpindleDir::off;
  double rpm = 0.0;
};
struct CoolantEvent {
  bool mist = false;   // M7
  bool flood = false;  // M8
};
struct DwellEvent {
  double seconds = 0.0;
};
struct ToolChangeEvent {  // M6 (T selects, M6 changes)
  int tool = 0;
  double length = 0.0;  // the new tool's Z offset in the tool table, program units
};
struct ToolOffsetEvent {  // G43 / G43.1 / G49: the tool length offset now in force
  Vec3 offset{0, 0, 0};   // program units (units below): what the planned coordinates hold
  Units units = Units::mm;
  // G43 H n: the tool table's entry n (the controller's own table gives the length when the
  // program is written out); -1: G43.1 (a length the program states) or G49 (none).
  int h = -1;
};
enum class StopKind { program_stop, optional_stop, pallet_shuttle };  // M0, M1, M60
struct StopEvent {
  StopKind kind = StopKind::program_stop;
};
struct EndEvent {  // M2, M30
  int m = 2;
};
struct MessageEvent {
  std::string text;
};
struct PathControlEvent {
  PathControl mode = PathControl::blend;
  std::optional<double> p;  // G64 P (blend tolerance), program units
  std::optional<double> q;  // G64 Q (naive CAM tolerance), program units
  Units units = Units::mm;  // units of p and q
};
struct UnitsEvent {
  Units units = Units::mm;
};
// An index of the rotary axis: a G0 or G1 that moves the machine's A (or B) and no X, Y, Z
// (docs/ngc-interpreter.md, "Rotary index axis"). It is an event of the program model, not a
// Motion: nothing of the tool's path moves; to_path makes it a stop with the index at it
// (PathSegment::indexes_before), planned rest to rest with the axis's own limits. Machine
// degrees (the work offset applied); G20/G21 do not scale them.
struct RotaryIndexMove {
  char axis = 'a';  // 'a' or 'b'
  double from_deg = 0.0;
  double to_deg = 0.0;
  bool rapid = true;              // G0; G1 moves at feed_deg_per_min
  double feed_deg_per_min = 0.0;  // G1's F (inverse time made per minute); 0 for G0
};

using Event =
    std::variant<SpindleEvent, CoolantEvent, DwellEvent, ToolChangeEvent, ToolOffsetEvent,
                 StopEvent, EndEvent, MessageEvent, PathControlEvent, UnitsEvent, RotaryIndexMove>;

struct Step {
  std::variant<Motion, Event> item;
  SourceRef src;
};

struct Program {
  std::vector<std::string> files;  // files[0] is the main program
  std::vector<Step> steps;
  Units units = Units::mm;  // units at the start
  // Where the machine stands when the program starts (InterpretOptions::start_machine_mm, mm,
  // machine coordinates), if given: the path's first move starts there (to_path).
  std::optional<Vec3> start_machine_mm;
  // The parameter file (InterpretOptions::parameter_file) as it must read after the program:
  // LinuxCNC's persistent parameters (5161-5169, 5181-5189, 5210-5390 as its required list)
  // and every parameter the file already held, with their values at the end, in ascending
  // order; other lines of the old file kept in place. Empty when no parameter file was given.
  // Writing it back is the caller's choice (docs/ngc-interpreter.md, "Persistent parameters").
  std::string parameter_file_text;
  // What is known of each tool the program may cut with (geometry/tool.hpp): the interpreter's
  // tool table and machine file (tool_catalogue, gcode/ngc/tool_table.hpp), or the generator's
  // ball end. A tool not listed is of unknown kind: the roughness law does not cap it.
  std::map<int, ToolSpec> tools;
  // The machine's rotary index axis (InterpretOptions::rotary_axis: 'a', 'b', 0 for none) and
  // where it stands at the start, machine degrees (0, as LinuxCNC's rs274 and the simulator).
  char rotary_axis = 0;
  double rotary_start_deg = 0.0;
};

// Geometry of an arc: radius, signed sweep (rad, + counter-clockwise about the plane's normal
// +Z, +Y, +X for G17, G18, G19), rise along the axis. Program units.
struct ArcGeometry {
  double radius = 0.0;
  double sweep_rad = 0.0;
  double rise = 0.0;
};
ArcGeometry arc_geometry(const Vec3& start, const ArcMove& arc);

// Indices (first, second, axis) of a plane: XY → (0,1,2), XZ → (2,0,1) as LinuxCNC (Z is the
// first axis of G18), YZ → (1,2,0).
struct PlaneAxes {
  int first, second, axis;
};
PlaneAxes plane_axes(Plane plane);

// Length of a motion in program units (arcs and helices exactly, NURBS by quadrature).
double motion_length(const Motion& m);
Vec3 motion_end(const Motion& m);

struct ToPathOptions {
  // Helical arcs become rational quadratic pieces whose axis coordinate may deviate from the
  // exact helix; pieces are halved until the deviation is at most this (mm).
  double helix_tolerance_mm = 1e-4;
  // When set, receives for each of program.steps: an event's place (the index of the segment
  // that follows it; every event ends a polyline run, so it sits at a segment boundary), a
  // planned motion's segment, or kNoSegment (a motion that adds nothing to the path).
  std::vector<std::size_t>* segment_of_step = nullptr;
};
inline constexpr std::size_t kNoSegment = static_cast<std::size_t>(-1);

// The planner's Path: lines → Polyline runs, arcs → rational quadratic NURBS (exact circles),
// all in mm and machine coordinates (offset applied), each segment with the tool in the spindle
// as program.tools describes it (a tool not listed: ToolKind::unknown). Rapids before X, Y and Z
// are known add nothing; a feed move from an unknown position is an InputError. Events that need
// the machine at rest (M0/M1/M60, M6, dwell, spindle changes) set stop_before on the next segment.
Path to_path(const Program& program, const ToPathOptions& options = {});

// "file:line" of a step.
std::string where(const Program& program, const SourceRef& src);

// The first tool change (M6) followed by a feed move, or by a rapid that moves Z, before any
// tool length offset (G43 H, G43.1, G49): a message naming both lines and the way out; none
// when every change is followed by its offset. Programs written for a controller with a tool
// table need it (comms::ProgramBlocks refuses them).
std::optional<std::string> change_without_length_offset(const Program& program);

// One line per motion or event: "file:line KIND values", the program's units.
void write_canonical(std::ostream& out, const Program& program);

}  // namespace ncd::toolpath

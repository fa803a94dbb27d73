// The chamfer loop as an RS-274/NGC program that LinuxCNC reads.
#pragma once

#include <string>

#include "cam/chamfer.hpp"

namespace ncd::toolpath {

enum class ProgramPoint { Tip, Centre };
// The frame the program is written in (docs/chamfer.md, "Frames"). Drill: Z along the drill
// axis, the part set up with the hole vertical (the default). Pipe: Z0 on the pipe axis, pipe
// along Y; only for an untilted drill, whose axis is then the machine's Z.
enum class ProgramFrame { Drill, Pipe };

struct NgcOptions {
  double feed_mm_per_min = 300.0;  // the paper's experiments
  double spindle_rpm = 3000.0;
  ProgramPoint point = ProgramPoint::Tip;
  double safe_z_mm = 0.0;  // clearance height in the program's frame, above the part
  int decimals = 4;        // digits after the point in coordinates (0.1 µm)
  ProgramFrame frame = ProgramFrame::Drill;
  // G64 P (LinuxCNC's blending within the tolerance); false for a controller without it (grbl
  // 1.1 answers error:20): the line is left out and the header says so.
  bool path_blending = true;
  // `%` lines open and close the program (LinuxCNC, ISO); false for grbl, which takes `%` for
  // no word (error:1).
  bool percent = true;
  // The tool ([tool] number of the machine file): "T n M6" before the spindle starts; false for
  // a controller without a tool change (grbl: M6 is its error:20), whose header then asks the
  // operator to load tool n before the start (docs/whole-program.md).
  int tool = 1;
  bool tool_change = true;
  // "G43 H n" after the change (before any move): the controller's tool table gives tool n's
  // length to the programmed point. False for a controller without a tool table (grbl): the
  // header says to set the length in the work offset (or with G43.1) before the start.
  bool length_offset = true;
  // "G4 P" after M3 for the spindle to reach its speed ([tool] spindle_dwell_s); 0: none.
  double spindle_dwell_s = 0.0;
};

std::string to_string(ProgramFrame frame);

// The header line (without parentheses) saying how the tool's length reaches the programmed
// point: "G43 H n" from the controller's table, or, without one, the work offset or G43.1.
std::string tool_length_text(ProgramPoint point, int tool, bool length_offset);

// Default clearance: the highest point of the hole's rim on the outer surface (the edge's own
// surface when the thickness is not given) plus two ball diameters, in the frame the program is
// written in (lower edges turned over).
double default_safe_z_mm(const ChamferSpec& spec);

// Throws InputError when an option is out of range (feed, spindle, safe Z below the path, the
// pipe frame for a tilted drill, a negative tool number or spindle dwell).
std::string chamfer_program(const ChamferPath& path, const NgcOptions& options);

// A point of the model (drill frame) in the program's frame: the pipe frame if asked, then the
// part turned over for lower edges (rotated 180° about Y: X → −X, Z → −Z).
Vec3 program_frame_point(const ChamferSpec& spec, const Vec3& p, ProgramFrame frame);
// Where the program moves the machine for a pose: program_frame_point of the ball centre,
// minus R_B in z for the tip.
Vec3 program_point(const ChamferSpec& spec, const CutterPose& pose, ProgramPoint point,
                   ProgramFrame frame = ProgramFrame::Drill);

}  // namespace ncd::toolpath

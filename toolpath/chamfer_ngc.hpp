// The chamfer loop as an RS-274/NGC program that LinuxCNC reads.
#pragma once

#include <string>

#include "toolpath/chamfer.hpp"

namespace ncd::toolpath {

enum class ProgramPoint { Tip, Centre };

struct NgcOptions {
  double feed_mm_per_min = 300.0;  // the paper's experiments
  double spindle_rpm = 3000.0;
  ProgramPoint point = ProgramPoint::Tip;
  double safe_z_mm = 0.0;  // clearance height in the program's frame, above the part
  int decimals = 4;        // digits after the point in coordinates (0.1 µm)
};

// Default clearance: the pipe surface of the edge plus two ball diameters, in the frame the
// program is written in (lower edges turned over).
double default_safe_z_mm(const ChamferSpec& spec);

// Throws InputError when an option is out of range (feed, spindle, safe Z below the path).
std::string chamfer_program(const ChamferPath& path, const NgcOptions& options);

// Where the program moves the machine for a pose: the part turned over for lower edges
// (rotated 180° about the pipe axis y), minus R_B in z for the tip.
Vec3 program_point(const ChamferSpec& spec, const CutterPose& pose, ProgramPoint point);

}  // namespace ncd::toolpath

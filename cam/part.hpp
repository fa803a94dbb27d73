// A part, not a hole: every hole of a pipe (or manifold) chamfered in one program, the pipe
// lying on a rotary table that indexes each hole under a vertical spindle (docs/part.md). The
// part file, the frames, the per-hole checks and the order of the holes; the method is
// explained once, in part.cpp.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "cam/chamfer.hpp"
#include "cam/chamfer_ngc.hpp"

namespace ncd::toolpath {

// The rotary axis the pipe lies on: A turns about X (the pipe along X), B about Y (along Y).
enum class RotaryAxis { A, B };
std::string to_string(RotaryAxis axis);  // "A", "B"

// [pipe]: a cylinder or cone, its axis on the rotary axis, from station 0 to length_mm.
struct PartPipe {
  double outer_radius_mm = 0.0;  // at station 0
  double wall_mm = 0.0;          // normal to the surface
  double half_angle_rad = 0.0;   // ψ of a cone, the radius growing with the station; 0: cylinder
  double length_mm = 0.0;
  double outer_radius_at(double station_mm) const;
  double max_outer_radius_mm() const;  // at one end
};

// [tool]: the ball-end cutter of every hole.
struct PartTool {
  double ball_radius_mm = 0.0;
  std::optional<double> rod_radius_mm;
  std::optional<double> non_knife_angle_rad;
  int number = 1;         // T of the tool change
  int length_offset = 1;  // H of G43 (default: the tool number)
};

// [cut]: feeds, tolerance and the clearance plane.
struct PartCut {
  double feed_mm_per_min = 300.0;
  double spindle_rpm = 3000.0;
  double spindle_dwell_s = 0.0;
  double tolerance_mm = 0.01;
  std::optional<double> clearance_margin_mm;  // above the pipe's top; default 4 R_B
  double approach_gap_mm = 1.0;               // the rapid descent stops this far above the cut
};

// [rotary]: the table the pipe lies on, where the machine file does not say.
struct PartRotary {
  RotaryAxis axis = RotaryAxis::A;
  bool axis_given = false;  // the file says which (a machine file's [axis.a]/[axis.b] must agree)
  // +1: a positive A (B) turns the part right-handed about +X (+Y); −1: the other way (a
  // machine whose positive A follows the ISO rule for the tool relative to the part).
  double sense = 1.0;
  double max_feed_deg_per_min = 3600.0;  // the index's rate and acceleration, for the time model
  double max_accel_deg_per_s2 = 1800.0;
  // Where the rotary axis stands when the program starts (machine A or B, degrees, as the
  // controller reads it): the order's first index and the program's first rotary word leave
  // from here.
  double start_deg = 0.0;
};

// [[hole]]: one drilled hole and the edge to chamfer.
struct PartHole {
  std::string name;         // optional, for messages and the program's comments
  double station_mm = 0.0;  // position along the pipe where the drill axis passes nearest its axis
  double angle_rad = 0.0;   // around: the index that brings the hole's radial direction up
  double drill_radius_mm = 0.0;
  double tilt_rad = 0.0;     // τ from the radial direction, as ChamferSpec
  double azimuth_rad = 0.0;  // φ: 0 tilts along the pipe (+station), 90° across it
  double eccentricity_mm = 0.0;
  double width_mm = 0.0;
  Edge edge = Edge::Outer;
  Side side = Side::Upper;
};

struct Part {
  PartPipe pipe;
  PartTool tool;
  PartCut cut;
  PartRotary rotary;
  std::vector<PartHole> holes;
  std::string source = "part";  // the file, for messages
};

// Limits of the part file (docs/part.md), shared by the parser and its messages.
struct PartLimits {
  static constexpr std::size_t kMaxHoles = 200;
  static constexpr double kMaxLengthMm = 10000.0;
  static constexpr double kMaxStartDeg = 36000.0;  // [rotary] start_deg: 100 turns either way
  // The overlap check's edges: chords within this of the curve (docs/part.md).
  static constexpr double kOverlapSagMm = 5e-4;
};

// Reads a part file (TOML); throws InputError naming the file, the hole (index and name), the
// key, the value, the limit and a way out.
Part parse_part(const std::string& text, const std::string& name);
Part load_part(const std::string& path);

// "hole 3 (\"lateral 1\")", 1-based as the file lists them.
std::string hole_label(const Part& part, std::size_t index);

// Where a hole sits on the machine at its index (part.cpp, "Frames").
struct HoleSetup {
  ChamferSpec spec;            // the hole alone; tool_axis set where the drill axis stays tilted
  double index_rad = 0.0;      // the part's turn (right-handed about the pipe axis) that brings
                               // the spindle side of the drill axis up, in (−π, π]
  bool perpendicular = true;   // the drill axis ⟂ the rotary axis: vertical after the index
  double tilt_left_rad = 0.0;  // the drill axis's angle from the vertical after the index
  Vec3 origin;                 // the hole's pipe-frame origin in part coordinates (s, v, w)
  std::array<Vec3, 3> axes;    // the pipe frame's X, Y, Z in part coordinates
  Vec3 pipe_to_part(const Vec3& p) const;
};
// Throws InputError (naming the hole) where its values make no hole.
HoleSetup hole_setup(const Part& part, std::size_t index);

// Part coordinates (s along the pipe axis, v, w; w up at no index) turned by `turn_rad` about
// the pipe axis, as machine X Y Z (A: X = s; B: Y = s, X = −v).
Vec3 part_to_machine(RotaryAxis axis, const Vec3& part, double turn_rad);

// The time model of the air moves (part.cpp, "Order"): trapezoids under these limits.
struct AirModel {
  double rapid_mm_per_s = 100.0;  // the path's rapid rate and acceleration
  double rapid_accel_mm_per_s2 = 1000.0;
  std::array<double, 3> axis_mm_per_s{1e300, 1e300, 1e300};  // each axis's own (inf: none)
  std::array<double, 3> axis_accel_mm_per_s2{1e300, 1e300, 1e300};
  double index_deg_per_s = 60.0;
  double index_accel_deg_per_s2 = 1800.0;
};
// Time of a rest-to-rest move of `distance` at most `rate` and `accel` (a trapezoid, or a
// triangle when it cannot reach the rate).
double trapezoid_time_s(double distance, double rate, double accel);
double rapid_time_s(const AirModel& model, const Vec3& from, const Vec3& to);
double index_time_s(const AirModel& model, double delta_deg);
// The shortest turn from a to b (degrees), in [−180, 180).
double shortest_turn_deg(double from_deg, double to_deg);

// Air times between holes: from[i] the start's cost to hole i (the first index from [rotary]
// start_deg), and
// between[i][j] from hole i's retract to hole j's approach, symmetric.
struct AirCosts {
  std::vector<double> from_start;
  std::vector<std::vector<double>> between;
  double tour_s(const std::vector<std::size_t>& order) const;
};
// Nearest neighbour from each first hole in turn, each then improved by 2-opt; the file's order
// improved by 2-opt too; the shortest of them (never longer than the file's order).
std::vector<std::size_t> order_holes(const AirCosts& costs);

// One hole of the program, in cutting order.
struct HoleCut {
  std::size_t hole = 0;  // index in Part::holes
  HoleSetup setup;
  ChamferPath path;          // the hole's chamfer computed alone
  double a_deg = 0.0;        // the rotary word as written (continuous from the previous hole)
  std::vector<Vec3> points;  // the loop in machine coordinates, programmed point, not closed
  Vec3 over;                 // entry and exit at the clearance plane (the drill axis for an
                             // inner edge, over the first point for an outer one)
};

// A hole's chamfered edge in part coordinates (s, v, w): the edge curve (ChamferModel::point)
// at equal steps of θ, fine enough that each chord leaves the curve by at most sag_mm; the
// loop not closed.
std::vector<Vec3> edge_in_part(const HoleCut& cut, double sag_mm);

struct PartProgram {
  Part part;
  NgcOptions options;  // point, feed, spindle, tool, dialect choices of the writer
  std::vector<HoleCut> cuts;
  std::vector<std::size_t> order;   // hole indices, cutting order
  double clearance_z_mm = 0.0;      // the programmed point's Z of the clearance plane
  double clearance_tip_z_mm = 0.0;  // the ball tip's: the pipe's top + the margin
  double air_ordered_s = 0.0;
  double air_file_order_s = 0.0;
  double cut_length_mm = 0.0;
};

// Every hole computed alone and checked (an interference refused naming the hole), two holes
// whose chamfers meet refused naming both (docs/part.md, "Overlapping holes"), placed, ordered; the
// options' tool, feed and spindle are taken from the part.
PartProgram plan_part(const Part& part, const AirModel& air, NgcOptions options);
// The RS-274/NGC program (LinuxCNC dialect with an A or B axis).
std::string part_program_text(const PartProgram& program);

}  // namespace ncd::toolpath

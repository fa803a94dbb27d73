// G-code reader: the accepted dialect, LinuxCNC's G5.2 knot vector, the chamfer program that
// `ncd chamfer --format ngc` writes, and an error with line number for each rejected input.
#include "gcode/gcode_reader.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "cam/chamfer.hpp"
#include "cam/chamfer_ngc.hpp"
#include "core/error.hpp"

namespace ncd::toolpath {
namespace {

Path read(const std::string& text) {
  std::istringstream in(text);
  return read_gcode(in, "test.ngc");
}

const Polyline& polyline(const Path& p, std::size_t i) {
  return std::get<Polyline>(p.segments.at(i).geometry);
}

TEST(GcodeReader, CommentsPercentLineNumbersAndModalMoves) {
  const Path p = read(
      "%\n"
      "(header comment)\n"
      "\n"
      "N10 G21 G90 G94 G17 G40 G49 ; setup\n"
      "N20 G64 P0.01\n"
      "n30 s1200 m3\n"
      "N40 G0 X1 Y2 Z3 (rapid to start)\n"
      "N50 G1 X 4 Y2 F600\n"
      "N60 Y6 (modal G1)\n"
      "N70 x4.0 y6.0 z+3.000 ; same point: adds nothing\n"
      "N80 Z-1.5\n"
      "N90 G0 Z10\n"
      "M5\n"
      "M2\n"
      "%\n"
      "G1 X99 (after the end: ignored)\n");
  EXPECT_EQ(p.source, "test.ngc");
  ASSERT_EQ(p.segments.size(), 2u);
  const PathSegment& cut = p.segments[0];
  EXPECT_FALSE(cut.rapid);
  EXPECT_EQ(cut.feed_mm_per_min, 600.0);
  EXPECT_EQ(cut.spindle_rpm, 1200.0);
  EXPECT_EQ(cut.source_line, 8);
  EXPECT_EQ(polyline(p, 0).points,
            (std::vector<Vec3>{{1, 2, 3}, {4, 2, 3}, {4, 6, 3}, {4, 6, -1.5}}));
  EXPECT_TRUE(polyline(p, 0).normals.empty());
  const PathSegment& up = p.segments[1];
  EXPECT_TRUE(up.rapid);
  EXPECT_FALSE(up.feed_mm_per_min);
  EXPECT_EQ(up.spindle_rpm, 1200.0);
  EXPECT_EQ(polyline(p, 1).points, (std::vector<Vec3>{{4, 6, -1.5}, {4, 6, 10}}));
}

TEST(GcodeReader, MovesBeforeThePositionIsKnownAddNoSegment) {
  const Path p = read("G0 Z40\nG0 X0 Y0\nG0 X5\nG1 X6 F100\nM2\n");
  ASSERT_EQ(p.segments.size(), 2u);  // G0 X5 is the first move from a known point
  EXPECT_EQ(polyline(p, 0).points, (std::vector<Vec3>{{0, 0, 40}, {5, 0, 40}}));
  EXPECT_TRUE(p.segments[0].rapid);
  EXPECT_FALSE(p.segments[0].spindle_rpm);  // never started
  EXPECT_EQ(polyline(p, 1).points, (std::vector<Vec3>{{5, 0, 40}, {6, 0, 40}}));
}

TEST(GcodeReader, SplitsWhereFeedSpindleOrRapidStateChange) {
  const Path p = read(
      "G0 X0 Y0 Z0\n"
      "G1 X1 F100\n"
      "X2\n"
      "X3 F200\n"  // feed change
      "S500 M3\n"  // spindle starts
      "X4\n"       //
      "S800\n"     // speed change
      "X5\n"       //
      "G0 X6\n"    // rapid
      "X7\n"       // still rapid: each rapid is a segment of its own (comms::ProgramBlocks)
      "G1 X8\n"    // feed again (F200 is modal)
      "M5\n"       // spindle stops
      "X9\n");
  ASSERT_EQ(p.segments.size(), 8u);
  const std::vector<std::vector<double>> xs = {{0, 1, 2}, {2, 3}, {3, 4}, {4, 5},
                                               {5, 6},    {6, 7}, {7, 8}, {8, 9}};
  for (std::size_t i = 0; i < xs.size(); ++i) {
    const auto& pts = polyline(p, i).points;
    ASSERT_EQ(pts.size(), xs[i].size()) << "segment " << i;
    for (std::size_t k = 0; k < pts.size(); ++k) EXPECT_EQ(pts[k].x(), xs[i][k]);
  }
  EXPECT_EQ(p.segments[0].feed_mm_per_min, 100.0);
  EXPECT_EQ(p.segments[1].feed_mm_per_min, 200.0);
  EXPECT_FALSE(p.segments[1].spindle_rpm);
  EXPECT_EQ(p.segments[2].spindle_rpm, 500.0);
  EXPECT_EQ(p.segments[3].spindle_rpm, 800.0);
  EXPECT_TRUE(p.segments[4].rapid);
  EXPECT_TRUE(p.segments[5].rapid);
  EXPECT_EQ(p.segments[6].feed_mm_per_min, 200.0);
  EXPECT_FALSE(p.segments[7].spindle_rpm);
  EXPECT_EQ(p.segments[7].source_line, 13);
}

TEST(GcodeReader, LinuxCncNurbsBlockOfTheManual) {
  // The example of the LinuxCNC manual (G-codes, G5.2 G5.3), at Z = 1.
  const Path p = read(
      "G0 X0 Y0 Z1 (rapid move)\n"
      "F10 (set feed rate)\n"
      "G5.2 P1 L3\n"
      "     X0 Y1 P1\n"
      "     X2 Y2 P1\n"
      "     X2 Y0 P1\n"
      "     X0 Y0 P2\n"
      "G5.3\n"
      "G1 X5\n"
      "M2\n");
  ASSERT_EQ(p.segments.size(), 2u);
  const auto& c = std::get<NurbsCurve>(p.segments[0].geometry);
  EXPECT_EQ(p.segments[0].source_line, 3);
  EXPECT_EQ(p.segments[0].feed_mm_per_min, 10.0);
  EXPECT_FALSE(p.segments[0].rapid);
  EXPECT_EQ(c.degree(), 2);  // order L = 3
  // knot_vector_creator(n = 4, k = 3): 0 0 0 1 2 3 3 3.
  EXPECT_EQ(c.knots(), (std::vector<double>{0, 0, 0, 1, 2, 3, 3, 3}));
  EXPECT_EQ(c.points(), (std::vector<Vec3>{{0, 0, 1}, {0, 1, 1}, {2, 2, 1}, {2, 0, 1}, {0, 0, 1}}));
  EXPECT_EQ(c.weights(), (std::vector<double>{1, 1, 1, 1, 2}));
  // The G1 after the block starts where the curve ends.
  EXPECT_EQ(polyline(p, 1).points, (std::vector<Vec3>{{0, 0, 1}, {5, 0, 1}}));
}

TEST(GcodeReader, NurbsOrderFirstWeightAndKnotsForHigherOrder) {
  const Path p = read(
      "G0 X1 Y1 Z-2\n"
      "G1 F300\n"
      "G5.2 P0.5\n"  // weight of the start point only
      "X2 Y3 P1 L4\n"
      "G5.2 X4 Y3 P3\n"  // G5.2 again continues the same block
      "X5 Y1 P1\n"
      "X6 Y0 P1\n"
      "G5.3\n");
  ASSERT_EQ(p.segments.size(), 1u);
  const auto& c = std::get<NurbsCurve>(p.segments[0].geometry);
  EXPECT_EQ(c.degree(), 3);
  // n = 4, k = 4: 0 0 0 0 1 2 2 2 2.
  EXPECT_EQ(c.knots(), (std::vector<double>{0, 0, 0, 0, 1, 2, 2, 2, 2}));
  EXPECT_EQ(c.weights(), (std::vector<double>{0.5, 1, 3, 1, 1}));
  EXPECT_EQ(c.eval(c.u_begin()).p, Vec3(1, 1, -2));
  EXPECT_LE((c.eval(c.u_end()).p - Vec3(6, 0, -2)).norm(), 1e-14);
}

TEST(GcodeReader, ReadsBackTheChamferProgram) {
  // The exact text `ncd chamfer --format ngc` writes (app/chamfer_cmd.cpp calls
  // chamfer_program), for an inner upper and an outer lower edge.
  for (const auto& [edge, side] :
       {std::pair{Edge::Inner, Side::Upper}, {Edge::Outer, Side::Lower}}) {
    ChamferSpec spec;
    spec.edge = edge;
    spec.side = side;
    if (edge == Edge::Outer) spec.pipe_radius_mm = 21.0;
    const ChamferPath chamfer = generate_chamfer(spec);
    NgcOptions o;
    o.safe_z_mm = default_safe_z_mm(spec);
    // It changes to its tool (T1 M6): a tool the machine holds, as a machine file's [tool]
    // number makes it (service/machine_config.hpp).
    InterpretOptions machine;
    machine.machine_tools = {o.tool};
    std::istringstream text(chamfer_program(chamfer, o));
    const Path p = read_gcode(text, "test.ngc", machine);
    const std::size_t n = chamfer.points.size();
    const Vec3 first = program_point(spec, chamfer.points.front(), o.point);
    ASSERT_EQ(p.segments.size(), 2u);
    const PathSegment& cut = p.segments[0];
    EXPECT_EQ(cut.feed_mm_per_min, o.feed_mm_per_min);
    EXPECT_EQ(cut.spindle_rpm, o.spindle_rpm);
    EXPECT_FALSE(cut.rapid);
    const auto& pts = polyline(p, 0).points;
    // Inner: (0,0,safe) ↓ (0,0,z1) → loop (n + 1 points, closed) → (0,0,z1). Outer: above the
    // first point ↓ loop.
    const std::size_t lead = edge == Edge::Inner ? 2 : 1;
    ASSERT_EQ(pts.size(), lead + n + 1 + (edge == Edge::Inner ? 1 : 0));
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3 want = program_point(spec, chamfer.points[i], o.point);
      EXPECT_LE((pts[lead + i] - want).cwiseAbs().maxCoeff(), 0.5e-4 + 1e-12) << "point " << i;
    }
    EXPECT_EQ(pts[lead + n], pts[lead]);  // loop closed
    EXPECT_LE((pts[lead] - first).cwiseAbs().maxCoeff(), 0.5e-4 + 1e-12);
    EXPECT_NEAR(pts.front().z(), o.safe_z_mm, 0.5e-4);
    const PathSegment& retract = p.segments[1];
    EXPECT_TRUE(retract.rapid);
    EXPECT_NEAR(polyline(p, 1).points.back().z(), o.safe_z_mm, 0.5e-4);
  }
}

// Every rejected input names the line and the reason.
void expect_error(const std::string& program, const std::string& line_tag,
                  const std::string& needle) {
  try {
    read(program);
    ADD_FAILURE() << "no InputError for:\n" << program;
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(line_tag), std::string::npos) << m;
    EXPECT_NE(m.find(needle), std::string::npos) << m;
  }
}

// A tool the machine holds (InterpretOptions::machine_tools) is changed to with no table entry;
// another tool is still refused, naming it.
TEST(GcodeReader, MachineToolsAreKnownWithoutATable) {
  InterpretOptions machine;
  machine.machine_tools = {4};
  std::istringstream ok("G21 G90\nT4 M6\nS1000 M3\nG0 X0 Y0 Z5\nG1 Z0 F100\nM5\nM2\n");
  EXPECT_FALSE(read_gcode(ok, "t4.ngc", machine).segments.empty());
  std::istringstream other("G21 G90\nT5 M6\nG0 X0 Y0 Z5\nG1 Z0 F100\nM2\n");
  try {
    read_gcode(other, "t5.ngc", machine);
    ADD_FAILURE() << "T5 was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("tool T5 is not in the tool table"), std::string::npos)
        << e.what();
  }
}

// A tool change with its length offset on the same line (T3 M6 G43 H3, as CAM posts write it):
// the interpreter keeps the program position there, as rs274 does, and the machine does not
// jump: the next line starts where the machine stands (5 mm, no offset) and ends at the
// programmed Z plus the new length (1 + 28.575). Every segment starts where the one before
// ended. An arc right after such a change is refused, naming its line.
TEST(GcodeReader, ToolLengthSetOnTheChangesLineMovesTheMachineOnlyWithTheNextMove) {
  const std::filesystem::path table =
      std::filesystem::temp_directory_path() / ("ncd_tl_" + std::to_string(getpid()) + ".tbl");
  std::ofstream(table) << "T3 P3 Z28.575 D3.175\n";
  InterpretOptions o;
  o.tool_table = table.string();
  std::istringstream in("G21 G90\nG0 X0 Y0 Z5\nG1 X4 F100\nT3 M6 G43 H3\nG0 Z1\nG1 X8\nM2\n");
  const Path p = read_gcode(in, "tl.ngc", o);
  ASSERT_GE(p.segments.size(), 3u);
  Vec3 end = polyline(p, 0).points.back();
  EXPECT_NEAR(end.z(), 5.0, 1e-12);
  for (std::size_t i = 1; i < p.segments.size(); ++i) {
    const Polyline& l = polyline(p, i);
    EXPECT_NEAR((l.points.front() - end).norm(), 0.0, 1e-12) << "segment " << i;
    end = l.points.back();
  }
  EXPECT_NEAR(polyline(p, 1).points.back().z(), 1.0 + 28.575, 1e-12);
  std::istringstream arc("G21 G90\nG0 X0 Y0 Z5\nG1 X4 F100\nT3 M6 G43 H3\nG2 X8 Y0 I2 J0\nM2\n");
  try {
    read_gcode(arc, "tl_arc.ngc", o);
    ADD_FAILURE() << "an arc from a position the machine is not at was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("tl_arc.ngc:5: an arc or curve right after a tool change"),
              std::string::npos)
        << e.what();
  }
  std::filesystem::remove(table);
}

TEST(GcodeReader, RejectsUnsupportedAndMalformedInputWithLineNumbers) {
  const std::string start = "G21 G90\nG0 X0 Y0 Z0\nF100\n";  // lines 1-3
  // Out of scope: refused with the construct and a way out.
  expect_error(start + "G41.1 D4 G1 X1\n",
               "test.ngc:4:", "entry move is not longer than the tool radius");
  expect_error(start + "G33 Z-1 K1\n", "test.ngc:4:", "G33 (spindle-synchronised motion");
  expect_error(start + "G38.2 Z-1\n", "test.ngc:4:", "G38.2 (probing)");
  expect_error(
      start + "G1 A1\n", "test.ngc:4:",
      "A1: the machine has no A axis (rotary about X); if it has one, declare it with an [axis.a]");
  expect_error(start + "M101\n", "test.ngc:4:", "M101 (user M code)");
  expect_error(start + "G86 R1 Z-1\n", "test.ngc:4:", "G86 (tapping/boring cycle");
  expect_error(start + "T1 M6\n", "test.ngc:4:", "tool T1 is not in the tool table");
  expect_error(start + "M6\n", "test.ngc:4:", "M6 without a T word");
  // Malformed.
  expect_error(start + "G1 X1 X2\n", "test.ngc:4:", "word X appears twice");
  expect_error(start + "G0 G1 X1\n", "test.ngc:4:", "same modal group");
  expect_error(start + "G1 X1.2.3\n", "test.ngc:4:", "malformed number");
  expect_error(start + "G1 X-\n", "test.ngc:4:", "expected a number");
  expect_error(start + "G1 X[1+]\n", "test.ngc:4:", "expected a number");
  expect_error(start + "G1 X[1+2\n", "test.ngc:4:", "not closed");
  expect_error(start + "G1 X#<nope>\n", "test.ngc:4:", "#<nope> is not defined");
  expect_error(start + "G1 X1 (open comment\n", "test.ngc:4:", "not closed");
  expect_error(start + "G1.5 X1\n", "test.ngc:4:", "G1.5 is not supported");
  expect_error(start + "G1 X1 N5\n", "test.ngc:4:", "must come first");
  expect_error(start + "G1 X1 F0\n", "test.ngc:4:", "zero feed rate");
  expect_error(start + "G1 X1 F-1\n", "test.ngc:4:", "negative feed F-1");
  expect_error("X1\n", "test.ngc:1:", "no motion mode");
  expect_error(start + "G80\nX1\n", "test.ngc:5:", "no motion mode");
  expect_error(start + "G64 L3\n", "test.ngc:4:", "L3 with no code that uses it");
  expect_error("G1 X1 Y1 Z1 F100\n", "test.ngc:1:", "unknown position");
  expect_error("G0 X0 Y0 Z0\nG1 X1\n", "test.ngc:2:", "zero feed rate");
  expect_error("%\nG0 X0 Y0 Z0\nG0 X1\n", "test.ngc:3:", "neither a closing % line");
  expect_error("(nothing)\n", "test.ngc: ", "moves nothing");
  expect_error(start + "G2 X1 Y1\n", "test.ngc:4:", "arc without R or I, J, K");
  expect_error(start + "G2 X1 Y1 R0.1\n", "test.ngc:4:", "too small to reach the end point");
  expect_error(start + "G2 X1 Y0 I3\n", "test.ngc:4:", "differs from radius to start");
  expect_error(start + "G1 X[1/0]\n", "test.ngc:4:", "divide by zero");
  expect_error(start + "G1 X[SQRT[-1]]\n", "test.ngc:4:", "SQRT is negative");
  // G5.2 blocks.
  expect_error(start + "G5.2 X1 Y1 P1\nX2 Y0 P1\n", "test.ngc:4:", "is not closed");
  expect_error(start + "G5.3\n", "test.ngc:4:", "G5.3 without an open G5.2 block");
  expect_error(start + "G5.2 X1 Y1\n", "test.ngc:4:", "without a weight; add P");
  expect_error(start + "G5.2 X1 Y1 P0\n", "test.ngc:4:", "weight P0 must be greater than 0");
  expect_error(start + "G5.2 X1 Y1 Z2 P1\n", "test.ngc:4:", "Z in a G5.2 block");
  expect_error(start + "G5.2 X1 P1\n", "test.ngc:4:", "needs both X and Y");
  expect_error(start + "G5.2 L2\n", "test.ngc:4:", "order L2 is out of range");
  expect_error(start + "G5.2 L9\n", "test.ngc:4:", "order L9 is out of range");
  expect_error(start + "G5.2 X1 Y1 P1\nP2\n", "test.ngc:5:", "P without X and Y");
  expect_error(start + "G5.2 X1 Y1 P1\nG1 X3\n", "test.ngc:5:", "inside the G5.2 block");
  expect_error(start + "G5.2 X1 Y1 P1\nS100\n", "test.ngc:5:", "inside the G5.2 block opened");
  expect_error(start + "G5.2 X1 Y1 P1\nG5.3\n", "test.ngc:5:", "2 control points");
  expect_error(start + "G5.2 L4 X1 Y1 P1\nX2 Y2 P1\nG5.3\n", "test.ngc:6:", "order L = 4");
  expect_error(start + "G5.2 X1 Y1 P1\nX2 Y2 P1\nG5.3 X3\n", "test.ngc:6:", "G5.3 closes");
  expect_error("G0 X0 Y0 Z0\nG5.2 X1 Y1 P1\n", "test.ngc:2:", "zero feed rate");
}

// Arcs become exact rational quadratic NURBS: every sampled point lies on the circle, the
// ends are the programmed ones, and a helix stays within the stated tolerance of the exact
// helix (z linear in the angle).
TEST(GcodeReader, ArcsBecomeExactNurbs) {
  const Path p = read(
      "G21 G17 G90 F600\nG0 X10 Y0 Z0\nG3 X0 Y10 I-10 J0\nG2 X10 Y0 I0 J-10 P2\n"
      "G3 X10 Y0 Z-6 I-10 J0 P3\nM2\n");
  ASSERT_EQ(p.segments.size(), 3u);
  for (std::size_t s = 0; s < 3; ++s) {
    const auto& c = std::get<NurbsCurve>(p.segments[s].geometry);
    EXPECT_EQ(c.degree(), 2);
    double max_r_err = 0.0, max_z_err = 0.0;
    double prev_angle = std::atan2(c.eval(c.u_begin()).p.y(), c.eval(c.u_begin()).p.x());
    double turned = 0.0;
    for (int i = 0; i <= 4000; ++i) {
      const double u = c.u_begin() + (c.u_end() - c.u_begin()) * i / 4000.0;
      const Vec3 q = c.eval(u).p;
      max_r_err = std::max(max_r_err, std::abs(std::hypot(q.x(), q.y()) - 10.0));
      const double a = std::atan2(q.y(), q.x());
      turned += std::remainder(a - prev_angle, 2 * kPi);
      prev_angle = a;
      if (s == 2) max_z_err = std::max(max_z_err, std::abs(q.z() - (-6.0 * turned / (6 * kPi))));
    }
    EXPECT_LE(max_r_err, 1e-9) << "segment " << s;
    EXPECT_LE(max_z_err, 1e-4 + 1e-9) << "segment " << s;  // ToPathOptions::helix_tolerance_mm
    const double want_turn = s == 0 ? kPi / 2 : s == 1 ? -(2 * kPi + kPi / 2) : 6 * kPi;
    EXPECT_NEAR(turned, want_turn, 1e-6) << "segment " << s;
  }
}

// Found by the fuzzer (tests/fuzz/ngc_interpreter_fuzz.cpp): an O-word number too long for a
// long integer, and labels with leading zeros, which name the same label.
TEST(GcodeReader, LongAndZeroPaddedOWordNumbers) {
  const std::string digits(300, '9');
  expect_error("G0 X0 Y0 Z0\no" + digits + " repeat [2]\nG0 X1\n",
               "test.ngc:2:", "is not closed before the end of the file");
  const Path p = read("G21 G0 X0 Y0 Z0\no010 repeat [2]\nG91 G0 X1\no10 endrepeat\nM2\n");
  ASSERT_EQ(p.segments.size(), 2u);  // two rapids, each a segment
  EXPECT_EQ(polyline(p, 0).points, (std::vector<Vec3>{{0, 0, 0}, {1, 0, 0}}));
  EXPECT_EQ(polyline(p, 1).points, (std::vector<Vec3>{{1, 0, 0}, {2, 0, 0}}));
}

// The same change where the machine stands is known only from the start given (no move before
// it, or moves of zero length only: skeleton.ngc's G53 G0 Z0 and X0 Y0 from machine 0,0,0). The
// path's first move starts at the start, not at the program point plus the new length; and a
// line to the program point the change left (G0 Z0 after T3 M6 G43 H3 at Z0) is no move of zero
// length: the machine goes up by the length, as rs274's STRAIGHT_TRAVERSE with the new offset
// says.
TEST(GcodeReader, ToolLengthSetOnTheChangesLineFromTheGivenStartAfterZeroLengthMoves) {
  const std::filesystem::path table =
      std::filesystem::temp_directory_path() / ("ncd_tl0_" + std::to_string(getpid()) + ".tbl");
  std::ofstream(table) << "T3 P3 Z28.575 D3.175\nT4 P4 Z10 D3\n";
  InterpretOptions o;
  o.tool_table = table.string();
  o.start_machine_mm = Vec3(0.0, 0.0, 0.0);
  for (const char* before : {"", "G53 G0 Z0\nX0 Y0\n"}) {
    std::istringstream in(std::string("G21 G90\n") + before + "T3 M6 G43 H3\nG0 X4 Y2\nM2\n");
    const Path p = read_gcode(in, "tl0.ngc", o);
    ASSERT_EQ(p.segments.size(), 1u) << before;
    EXPECT_EQ(polyline(p, 0).points.front(), Vec3(0.0, 0.0, 0.0)) << before;
    EXPECT_EQ(polyline(p, 0).points.back(), Vec3(4.0, 2.0, 28.575)) << before;
  }
  std::istringstream same("G21 G90\nG0 X0 Y0 Z0\nT4 M6 G43 H4\nG0 Z0\nG0 X1\nM2\n");
  const Path p = read_gcode(same, "tl0.ngc", o);
  ASSERT_EQ(p.segments.size(), 2u);
  EXPECT_EQ(polyline(p, 0).points.front(), Vec3(0.0, 0.0, 0.0));
  EXPECT_EQ(polyline(p, 0).points.back(), Vec3(0.0, 0.0, 10.0));
  EXPECT_EQ(polyline(p, 1).points.back(), Vec3(1.0, 0.0, 10.0));
  std::filesystem::remove(table);
}

// Events in the path: those that need the machine at rest mark the next segment; coolant does
// not. Path control and its tolerances go to the segments in mm; inch moves become mm; an
// inverse-time feed becomes mm/min (F × length).
TEST(GcodeReader, EventsPathControlInchAndInverseTime) {
  const std::string tools = (std::filesystem::temp_directory_path() /
                             ("gcode_reader_tools_" + std::to_string(::getpid()) + ".tbl"))
                                .string();
  std::ofstream(tools) << "T3 P3 Z1 D6\n";
  InterpretOptions opt;
  opt.tool_table = tools;
  std::istringstream in(
      "G21 G90 G0 X0 Y0 Z0\n"     // 1
      "G1 X1 F100\n"              // 2  seg 0
      "M8\n"                      // 3  coolant: no stop, but the run ends (an event's place)
      "G1 X2\n"                   // 4  seg 1
      "M0\n"                      // 5
      "G1 X3\n"                   // 6  seg 2: stop before
      "S1000 M3\n"                // 7
      "G1 X4\n"                   // 8  seg 3: stop before (spindle starts)
      "G4 P1\n"                   // 9
      "G1 X5\n"                   // 10 seg 4: stop before (dwell)
      "T3 M6\n"                   // 11
      "G1 X6\n"                   // 12 seg 5: stop before (tool change stops the spindle)
      "G20 G64 P0.001 Q0.0005\n"  // 13
      "G1 X1 F10\n"               // 14 seg 6: inch, 25.4 mm, 254 mm/min, G64 P in mm
      "G61.1 G93 G1 X2 F3\n"      // 15 seg 7: exact stop, 25.4 mm × 3/min
      "M2\n");
  const Path p = read_gcode(in, "events.ngc", opt);
  std::remove(tools.c_str());
  ASSERT_EQ(p.segments.size(), 8u);
  const std::vector<bool> stops = {false, false, true, true, true, true, false, false};
  for (std::size_t i = 0; i < stops.size(); ++i) {
    EXPECT_EQ(p.segments[i].stop_before, stops[i]) << "segment " << i;
  }
  EXPECT_EQ(polyline(p, 0).points.size(), 2u);  // the coolant change ends the run, no stop
  EXPECT_EQ(polyline(p, 1).points.back(), Vec3(2, 0, 0));
  EXPECT_FALSE(p.segments[5].spindle_rpm);  // M6 stopped the spindle
  const PathSegment& inch = p.segments[6];
  EXPECT_EQ(polyline(p, 6).points.back(), Vec3(25.4, 0, 0));
  EXPECT_NEAR(*inch.feed_mm_per_min, 254.0, 1e-9);
  EXPECT_EQ(inch.path_control, PathControl::blend);
  EXPECT_NEAR(*inch.blend_tolerance_mm, 0.0254, 1e-15);
  EXPECT_NEAR(*inch.smoothing_tolerance_mm, 0.0127, 1e-15);
  const PathSegment& inverse = p.segments[7];
  EXPECT_EQ(inverse.path_control, PathControl::exact_stop);
  EXPECT_NEAR(*inverse.feed_mm_per_min, 25.4 * 3.0, 1e-9);
}

TEST(GcodeReader, ErrorQuotesTheLineText) {
  try {
    read("G0 X0 Y0 Z0\nF100\nG1 X1 Q7 (bad)\n");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("test.ngc:3: Q7 with no code that uses it"),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("(line: \"G1 X1 Q7 (bad)\")"), std::string::npos)
        << e.what();
  }
}

// The start position (machine coordinates): every axis is known from the first line, as in
// LinuxCNC, so a program may begin with a feed move; the G54 offset of the parameter file and a
// G92 on the way are applied to the program's words, not to where the machine stands.
TEST(GcodeReader, AGivenStartPositionMakesEveryAxisKnownFromTheFirstLine) {
  InterpretOptions o;
  o.start_machine_mm = Vec3(1.0, 2.0, 3.0);
  std::istringstream in("G21 G90\nG1 X10 F100\nG92 X0\nG1 X5\nM2\n");
  const Path p = read_gcode(in, "start.ngc", o);
  ASSERT_EQ(p.segments.size(), 1u);
  const Polyline& l = polyline(p, 0);
  ASSERT_EQ(l.points.size(), 3u);
  EXPECT_EQ(l.points[0], Vec3(1.0, 2.0, 3.0));
  EXPECT_EQ(l.points[1], Vec3(10.0, 2.0, 3.0));
  EXPECT_EQ(l.points[2], Vec3(15.0, 2.0, 3.0));  // G92 X0 at X10: X5 is machine X15
  // A rapid first is planned from the start, not taken as an unplanned positioning.
  std::istringstream rapid("G0 Z50\nM2\n");
  const Path r = read_gcode(rapid, "rapid.ngc", o);
  ASSERT_EQ(r.segments.size(), 1u);
  EXPECT_EQ(polyline(r, 0).points.front(), Vec3(1.0, 2.0, 3.0));
  EXPECT_EQ(polyline(r, 0).points.back(), Vec3(1.0, 2.0, 50.0));
  // Not given: the same program is refused, naming the way out.
  std::istringstream again("G21 G90\nG1 X10 F100\nM2\n");
  try {
    (void)read_gcode(again, "start.ngc");
    FAIL() << "a feed move from an unknown position was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--start X,Y,Z"), std::string::npos) << e.what();
  }
  o.start_machine_mm = Vec3(0.0, std::nan(""), 0.0);
  std::istringstream nan_start("G1 X1 F100\n");
  EXPECT_THROW((void)read_gcode(nan_start, "nan.ngc", o), InputError);
}

}  // namespace
}  // namespace ncd::toolpath

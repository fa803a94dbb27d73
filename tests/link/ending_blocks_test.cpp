// The blocks that end a job early (comms::ending_blocks, docs/whole-program.md "Ending early"),
// against the rules written out by hand: in the bore of an inner edge back to the drill axis at
// the stop's Z, then straight up; elsewhere below the plane straight up; never down; nothing
// moves where the position is not known; after a controller reset the modes and the spindle
// first. And the retract's clearance for an NC program (toolpath::program_retract): the highest
// Z it reaches, and its own program end.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cam/whole_program.hpp"
#include "gcode/ngc/interpreter.hpp"
#include "link/program_blocks.hpp"

namespace {

using namespace ncd;
using Blocks = std::vector<std::string>;

toolpath::SafeRetract inner_edge() {
  toolpath::SafeRetract r;
  r.clearance_z_mm = 30.0;
  r.axis_xy = Vec3(0.0, 0.0, 0.0);
  r.bore_radius_mm = 10.9;
  r.feed_mm_per_min = 300.0;
  r.spindle_rpm = 3000.0;
  r.spindle_dwell_s = 0.5;
  return r;
}

TEST(EndingBlocks, InTheBoreBackToTheAxisLevelThenUp) {
  EXPECT_EQ(comms::ending_blocks(inner_edge(), Vec3(9.732, 3.809, 9.045), 3, 1, false),
            (Blocks{"G1X0.Y0.Z9.045F300.", "G0X0.Y0.Z30.", "M5", "M9", "M2"}));
  // At the edge of the bore radius (+ 0.01 mm) still in it; beyond it, straight up.
  EXPECT_EQ(comms::ending_blocks(inner_edge(), Vec3(10.909, 0.0, 8.0), 3, 1, false).front(),
            "G1X0.Y0.Z8.F300.");
  EXPECT_EQ(comms::ending_blocks(inner_edge(), Vec3(10.92, 0.0, 8.0), 3, 1, false),
            (Blocks{"G0X10.92Y0.Z30.", "M5", "M9", "M2"}));
  // On the axis already (the approach down it): no move to it.
  EXPECT_EQ(comms::ending_blocks(inner_edge(), Vec3(0.0, 0.0, 12.0), 3, 1, false),
            (Blocks{"G0X0.Y0.Z30.", "M5", "M9", "M2"}));
}

TEST(EndingBlocks, AfterAResetTheModesAndTheSpindleComeFirst) {
  EXPECT_EQ(comms::ending_blocks(inner_edge(), Vec3(8.536, 6.293, 10.092), 3, 1, true),
            (Blocks{"G21G90", "M3S3000", "G4P0.5", "G1X0.Y0.Z10.092F300.", "G0X0.Y0.Z30.", "M5",
                    "M9", "M2"}));
  // Straight up needs no spindle.
  toolpath::SafeRetract r = inner_edge();
  r.axis_xy.reset();
  EXPECT_EQ(comms::ending_blocks(r, Vec3(13.829, 0.0, -1.0), 3, 1, true),
            (Blocks{"G21G90", "G0X13.829Y0.Z30.", "M5", "M9", "M2"}));
}

TEST(EndingBlocks, NeverDownAndNothingMovesWhereThePositionIsNotKnown) {
  EXPECT_EQ(comms::ending_blocks(inner_edge(), Vec3(5.0, 5.0, 30.0), 3, 1, false),
            (Blocks{"M5", "M9", "M2"}));
  EXPECT_EQ(comms::ending_blocks(inner_edge(), Vec3(0.0, 0.0, 80.0), 3, 1, false),
            (Blocks{"M5", "M9", "M2"}));
  EXPECT_EQ(comms::ending_blocks(inner_edge(), std::nullopt, 3, 1, false),
            (Blocks{"M5", "M9", "M2"}));
  toolpath::SafeRetract r = inner_edge();
  r.end_m = 30;
  EXPECT_EQ(comms::ending_blocks(r, std::nullopt, 3, 1, false).back(), "M30");
}

TEST(ProgramRetract, TheHighestZTheProgramReachesAndItsOwnEnd) {
  const toolpath::Program p = toolpath::interpret_ngc(
      "G21 G90\nS2000 M3\nG0 Z12.5\nG0 X0 Y0\nG1 Z-1 F200\nG1 X10\nG0 Z5\nM5\nM30\n", "p.ngc");
  const toolpath::SafeRetract r = toolpath::program_retract(p, toolpath::to_path(p));
  EXPECT_DOUBLE_EQ(r.clearance_z_mm, 12.5);
  EXPECT_FALSE(r.axis_xy);
  EXPECT_EQ(r.end_m, 30);
  EXPECT_DOUBLE_EQ(r.spindle_rpm, 2000.0);
  // An inch program: the plane in mm, as the blocks are written.
  const toolpath::Program q =
      toolpath::interpret_ngc("G20 G90\nG0 X0 Y0 Z1\nG1 X1 F10\nM2\n", "q.ngc");
  EXPECT_DOUBLE_EQ(toolpath::program_retract(q, toolpath::to_path(q)).clearance_z_mm, 25.4);
}

}  // namespace

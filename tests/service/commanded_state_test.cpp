// The trace of queued blocks (service/commanded_state.hpp): which block carries an N word, and
// how many blocks the line has carried in full, against a count the test makes character by
// character; and the program's state move by move of a small program read by the interpreter.
#include "service/commanded_state.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "gcode/ngc/interpreter.hpp"
#include "gcode/program.hpp"
#include "tests/common/seed.hpp"

namespace {

using ncd::service::BlockTrace;

TEST(BlockTrace, CarriedCountsTheBlocksWhoseLastCharacterLeft) {
  const std::uint64_t seed = ncd::test::seed();
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> chars(1, 40);
  BlockTrace trace;
  std::vector<int> sizes;
  for (int k = 0; k < 200; ++k) {
    sizes.push_back(chars(rng));
    trace.add(k % 3 == 0 ? 0 : k + 1, k, k + 1, 0.1 * k, 0.1 * (k + 1), sizes.back());
  }
  std::uniform_int_distribution<int> pick(0, 200);
  for (int round = 0; round < 1000; ++round) {
    const int written = pick(rng);
    std::int64_t total = 0;
    for (int k = 0; k < written; ++k) total += sizes[static_cast<std::size_t>(k)];
    const std::int64_t in_flight = std::uniform_int_distribution<std::int64_t>(0, total)(rng);
    // The slow count: blocks, from the first, whose characters all lie before total − in_flight.
    std::size_t want = 0;
    std::int64_t through = 0;
    for (int k = 0; k < written; ++k) {
      through += sizes[static_cast<std::size_t>(k)];
      if (through <= total - in_flight) want = static_cast<std::size_t>(k) + 1;
    }
    ASSERT_EQ(trace.carried(written, in_flight), want)
        << "seed " << seed << ", written " << written << ", in flight " << in_flight;
  }
  EXPECT_EQ(trace.carried(0, 0), 0u);
  EXPECT_EQ(trace.carried(500, 0), 200u);  // never more than were queued
  EXPECT_EQ(trace.carried(200, 1u << 30), 0u);
  EXPECT_EQ(trace.with_number(5), std::optional<std::size_t>(4));
  EXPECT_EQ(trace.with_number(4), std::nullopt);  // block 3 has no N
  EXPECT_EQ(trace.with_number(0), std::nullopt);
}

// A G20 program with G43 H1 (50 mm), M3, M8 and three feed moves at one feed (one path
// segment): each move's line, the inch units, the tool length apart from the work offset.
TEST(CommandedTable, EachMoveKeepsItsLineAndTheToolLengthIsApart) {
  const std::filesystem::path table_file =
      std::filesystem::temp_directory_path() /
      ("ncd_commanded_state_" + std::to_string(::getpid()) + ".tbl");
  std::ofstream(table_file) << "T1 P1 Z50 D6 ;\n";
  ncd::toolpath::InterpretOptions o;
  o.tool_table = table_file.string();
  o.start_machine_mm = ncd::Vec3(0, 0, 100);
  const ncd::toolpath::Program program = ncd::toolpath::interpret_ngc(
      "G20 G90\nT1 M6\nG43 H1\nM3 S1000\nM8\nG0 X0 Y0 Z0.5\nG1 Z-0.125 F10\nG1 Y0.5 F20\n"
      "G1 X4\nG1 X5\nM2\n",
      "t.ngc", o);
  std::filesystem::remove(table_file);
  const ncd::service::CommandedTable table(program);
  ASSERT_FALSE(table.empty());
  const ncd::toolpath::Path path = ncd::toolpath::to_path(program);
  ASSERT_EQ(table.segments(), path.segments.size());
  // The run G1 Y0.5, X4, X5 at F20: find its segment by its first line.
  std::size_t run = path.segments.size();
  for (std::size_t k = 0; k < path.segments.size(); ++k) {
    if (path.segments[k].source_line == 8) run = k;
  }
  ASSERT_LT(run, path.segments.size());
  const double y_mm = 0.5 * 25.4, x4_mm = 4 * 25.4;
  EXPECT_EQ(table.at(run, 0.5 * y_mm).line, 8);
  EXPECT_EQ(table.at(run, y_mm + 1e-6).line, 9);
  EXPECT_EQ(table.at(run, y_mm + x4_mm - 1e-6).line, 9);
  EXPECT_EQ(table.at(run, y_mm + x4_mm + 1e-6).line, 10);
  const ncd::service::CommandedModal& m = table.at(run, y_mm + 1.0);
  EXPECT_EQ(m.units, ncd::toolpath::Units::inch);
  EXPECT_NEAR(m.tool_length_mm.z(), 50.0, 1e-9);
  EXPECT_NEAR(m.work_offset_mm.norm(), 0.0, 1e-9);
  EXPECT_EQ(m.tool_length_h, 1);
  EXPECT_EQ(m.tool, 1);
  EXPECT_EQ(m.spindle, ncd::toolpath::SpindleDir::cw);
  EXPECT_EQ(m.spindle_rpm, 1000.0);
  EXPECT_TRUE(m.flood);
  EXPECT_FALSE(m.mist);
}

}  // namespace

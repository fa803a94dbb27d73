// Restart from a line (service/restart.hpp): the job's path is the program from the line's own
// vertex on, even inside a run of lines merged into one polyline; the preamble is the modes in
// force at the line and the re-entry through the clearance plane, written out here by hand from
// docs/dnc-link.md; a job restarted so runs, in the service, exactly the program's moves from
// the line on (checked against the program's own end points). Programs the restart cannot
// follow are refused naming the line.
#include "service/restart.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "gcode/ngc/interpreter.hpp"

namespace {

using namespace ncd;

// Lines 6, 7 and 8 are feed moves at one feed: one polyline in the whole program's path.
const char* kProgram =
    "G21 G90 G54\n"  // 1
    "S1000 M3\n"     // 2
    "G0 Z5\n"        // 3
    "G0 X0 Y0\n"     // 4
    "G1 Z-1 F300\n"  // 5
    "G1 X10 Y0\n"    // 6
    "G1 X10 Y10\n"   // 7
    "G1 X0 Y10\n"    // 8
    "M8\n"           // 9
    "G1 X0 Y20\n"    // 10
    "M5 M9\n"        // 11
    "M2\n";          // 12

service::JobSpec job_of(const toolpath::Program& program) {
  service::JobSpec j;
  j.name = "prog.ngc";
  j.path = std::make_shared<toolpath::Path>(toolpath::to_path(program));
  j.rules = service::LiveLimitRules::from(j.motion.limits);
  return j;
}

std::vector<Vec3> vertices(const toolpath::Path& path) {
  std::vector<Vec3> out;
  for (const auto& seg : path.segments) {
    for (const Vec3& p : std::get<toolpath::Polyline>(seg.geometry).points) {
      if (out.empty() || (out.back() - p).norm() > 0.0) out.push_back(p);
    }
  }
  return out;
}

TEST(Restart, FromALineInsideAMergedRunItsModesAndReentry) {
  const toolpath::Program program = toolpath::interpret_ngc(kProgram, "prog.ngc");
  service::JobSpec whole = job_of(program);
  const std::vector<Vec3> all = vertices(*whole.path);
  // (0,0,5) (0,0,-1) (10,0,-1) (10,10,-1) (0,10,-1) (0,20,-1): the rapids before X, Y and Z are
  // all known add nothing.
  ASSERT_EQ(all.size(), 6u);
  service::JobSpec j = job_of(program);
  service::restart_job(j, program, kProgram, 7, std::nullopt);
  ASSERT_TRUE(j.restart.has_value());
  EXPECT_EQ(j.restart->line, 7);
  const std::vector<Vec3> cut = vertices(*j.path);
  const std::vector<Vec3> want = {{10, 0, -1}, {10, 10, -1}, {0, 10, -1}, {0, 20, -1}};
  ASSERT_EQ(cut.size(), want.size());
  for (std::size_t k = 0; k < want.size(); ++k) EXPECT_EQ(cut[k], want[k]) << k;
  EXPECT_EQ(j.path->segments.front().source_line, 7);
  // Modes at line 7, then up to the clearance plane (the highest Z before: 5), the spindle, over
  // line 7's start, down at the feed in force, then line 7's distance and motion mode.
  const std::vector<std::string> preamble = {
      "(ncd restart: the modes in force at the restart block)",
      "G21 G90 G54",
      "G0 Z5",
      "S1000 M3",
      "G0 X10 Y0",
      "G1 Z-1 F300",
      "G90 G1 F300"};
  EXPECT_EQ(j.restart->preamble, preamble);
  // A clearance given, and the coolant line 9 turns on.
  service::JobSpec j10 = job_of(program);
  service::restart_job(j10, program, kProgram, 10, 12.5);
  EXPECT_EQ(j10.restart->preamble[2], "G0 Z12.5");
  EXPECT_NE(std::find(j10.restart->preamble.begin(), j10.restart->preamble.end(), "M8"),
            j10.restart->preamble.end());
  EXPECT_EQ(vertices(*j10.path).front(), Vec3(0, 10, -1));
}

// With a tool table giving tool 1 75.5 mm, the planned path holds the length (machine
// coordinates); the preamble takes it back with G43 H1, and the restart records it so that the
// live blocks leave it out of their coordinates (as ProgramBlocks does for the whole program).
TEST(Restart, TheLengthOffsetInForceTravelsWithTheRestart) {
  const std::string text =
      "G21 G90 G54\nT1 M6\nG43 H1\nS1000 M3\nG0 Z5\nG0 X0 Y0\nG1 Z-1 F300\nG1 X10 Y0\n"
      "G1 X10 Y10\nM5\nM2\n";
  const auto table = std::filesystem::temp_directory_path() /
                     ("ncd_restart_tool_" + std::to_string(::getpid()) + ".tbl");
  std::ofstream(table) << "T1 P1 Z75.5 D6\n";
  toolpath::InterpretOptions o;
  o.tool_table = table.string();
  const toolpath::Program program = toolpath::interpret_ngc(text, "prog.ngc", o);
  std::filesystem::remove(table);
  service::JobSpec j = job_of(program);
  service::restart_job(j, program, text, 9, std::nullopt);
  ASSERT_TRUE(j.restart.has_value());
  EXPECT_EQ(j.restart->length_offset_mm, Vec3(0, 0, 75.5));
  EXPECT_NE(std::find(j.restart->preamble.begin(), j.restart->preamble.end(), "G43 H1"),
            j.restart->preamble.end());
  // The path: line 9's start (10, 0, -1) and end, in machine coordinates (the length added).
  const std::vector<Vec3> cut = vertices(*j.path);
  ASSERT_EQ(cut.size(), 2u);
  EXPECT_EQ(cut[0] - j.restart->length_offset_mm, Vec3(10, 0, -1));
  EXPECT_EQ(cut[1] - j.restart->length_offset_mm, Vec3(10, 10, -1));
}

TEST(Restart, ARestartedJobRunsTheMovesFromTheLineOnce) {
  const toolpath::Program program = toolpath::interpret_ngc(kProgram, "prog.ngc");
  service::JobSpec j = job_of(program);
  service::restart_job(j, program, kProgram, 7, std::nullopt);
  j.motion.limits.blend_tolerance_mm = 0.0;  // sharp corners: the walk is the program's moves
  service::ServiceOptions o;
  o.clock = motion::ClockKind::Simulated;
  o.realtime = false;
  service::Service s(o);
  s.submit(std::move(j));
  s.start();
  while (s.poll()) {
  }
  ASSERT_EQ(s.state(), service::State::Done) << s.status().error;
  const service::Status st = s.status();
  EXPECT_EQ(st.restart_line, 7);
  // From (10, 0, -1): 10 + 10 + 10 mm, against 50 mm for the whole program's feed moves.
  EXPECT_NEAR(st.length_mm, 30.0, 1e-9);
  EXPECT_NEAR((st.position_mm - Vec3(0, 20, -1)).norm(), 0.0, 1e-9);
}

TEST(Restart, WhatTheRestartCannotFollowIsRefusedNamingTheLine) {
  const auto refused = [](const std::string& text, int line, std::optional<double> clearance,
                          const std::string& part) {
    const toolpath::Program program = toolpath::interpret_ngc(text, "prog.ngc");
    service::JobSpec j = job_of(program);
    try {
      service::restart_job(j, program, text, line, clearance);
      ADD_FAILURE() << "line " << line << " accepted; expected \"" << part << "\"";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("\"restart_from\""), std::string::npos) << e.what();
    }
  };
  refused(kProgram, 12, std::nullopt, "no motion starts on that line or after it");
  refused(kProgram, 0, std::nullopt, "is not a line");
  refused(kProgram, 7, -3.0, "below line 7's start");
  refused("G21 G90\nG0 X0 Y0 Z5\nG92 X3\nG1 X10 F100\nG1 Y10\nM2\n", 5, std::nullopt,
          "G28, G30, G53, G92");
}

}  // namespace

// Polar coordinates (@ radius, ^ angle) that LinuxCNC refuses are refused by ncd on the same
// line: X or Y with them, a plane other than G17, @ alone at the origin in G90, ^ in G91 at the
// origin. rs274 must refuse each (exit status, no program end) and ncd must throw naming the polar
// words. The programs it accepts are judged move by move in tests/ngc/polar_coordinates.ngc and
// the LinuxCNC samples hole-circle, polar and spiral (ngc_conformance_test.cpp).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "core/error.hpp"
#include "gcode/ngc/interpreter.hpp"
#include "tests/common/rs274.hpp"
#include "tests/common/temp_dir.hpp"

namespace {

namespace fs = std::filesystem;
using namespace ncd;

struct PolarCase {
  const char* name;
  const char* program;
};

const PolarCase kCases[] = {
    {"x_with_polar", "G21 G90 G17\nG0 X1 Y1 Z1\nG1 X2 @3 ^10 F100\nM2\n"},
    {"xz_plane", "G21 G90 G18\nG0 X1 Y1 Z1\nG1 @3 ^10 F100\nM2\n"},
    {"radius_alone_at_origin", "G21 G90 G17\nG0 X0 Y0 Z1\nG1 @3 F100\nM2\n"},
    {"incremental_at_origin", "G21 G90 G17\nG0 X0 Y0 Z1\nG91 G1 ^30 F100\nM2\n"},
};

TEST(PolarCoordinates, WhatRs274RefusesNcdRefusesOnTheSameLine) {
  if (!fs::exists(test::kRs274)) GTEST_SKIP() << test::kRs274 << " not installed";
  test::TempDir dir("ncd_polar_");
  for (const PolarCase& c : kCases) {
    SCOPED_TRACE(c.name);
    std::ofstream(dir / "p.ngc") << c.program;
    const std::string cmd = "cd '" + dir.path().string() + "' && " +
                            test::rs274_command(dir.path(), "-g p.ngc out.txt") + " > log.txt 2>&1";
    const int rc = std::system(cmd.c_str());
    std::ifstream lf(dir / "log.txt"), of(dir / "out.txt");
    const std::string log((std::istreambuf_iterator<char>(lf)), std::istreambuf_iterator<char>());
    const std::string out((std::istreambuf_iterator<char>(of)), std::istreambuf_iterator<char>());
    // rs274 exits 1 and prints its message (e.g. "Cannot specify both polar coordinate and X
    // word"), without the word "error".
    EXPECT_NE(rc, 0) << "rs274 accepted it: " << log << out;
    EXPECT_EQ(out.find("PROGRAM_END"), std::string::npos) << out;
    try {
      toolpath::InterpretOptions opt;
      (void)toolpath::interpret_ngc(c.program, "p.ngc", opt);
      ADD_FAILURE() << "ncd accepted it";
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("p.ngc:3"), std::string::npos) << what;
      EXPECT_TRUE(what.find("polar") != std::string::npos || what.find('@') != std::string::npos)
          << what;
    }
  }
}

}  // namespace

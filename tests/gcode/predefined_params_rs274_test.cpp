// LinuxCNC's read-only named parameters (#<_imperial>, #<_motion_mode>, ...) as ncd's
// interpreter gives them, against rs274's own values: one program prints every parameter in a
// DEBUG comment after each change of state (units, distance and feed modes, the coordinate
// system, the plane, the retract mode, the spindle, coolant, feed and speed, the tool and its
// length offset, a move), and rs274's MESSAGE lines must equal ncd's messages, text for text.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "gcode/ngc/interpreter.hpp"
#include "tests/common/rs274.hpp"
#include "tests/common/temp_dir.hpp"

namespace {

namespace fs = std::filesystem;
using namespace ncd;

const char* const kNames[] = {"_line",
                              "_motion_mode",
                              "_plane",
                              "_ccomp",
                              "_metric",
                              "_imperial",
                              "_absolute",
                              "_incremental",
                              "_inverse_time",
                              "_units_per_minute",
                              "_units_per_rev",
                              "_coord_system",
                              "_tool_offset",
                              "_retract_r_plane",
                              "_retract_old_z",
                              "_spindle_rpm_mode",
                              "_spindle_css_mode",
                              "_ijk_absolute_mode",
                              "_lathe_diameter_mode",
                              "_lathe_radius_mode",
                              "_spindle_on",
                              "_spindle_cw",
                              "_mist",
                              "_flood",
                              "_speed_override",
                              "_feed_override",
                              "_adaptive_feed",
                              "_feed_hold",
                              "_feed",
                              "_rpm",
                              "_x",
                              "_y",
                              "_z",
                              "_a",
                              "_w",
                              "_vmajor",
                              "_vminor"};

std::string print_all() {
  std::string s;
  for (const char* n : kNames) s += std::string("(DEBUG, ") + n + " = #<" + n + ">)\n";
  return s;
}

std::vector<std::string> rs274_messages(const std::string& out) {
  std::vector<std::string> m;
  std::istringstream in(out);
  for (std::string line; std::getline(in, line);) {
    const auto at = line.find("MESSAGE(\"");
    if (at == std::string::npos) continue;
    const auto end = line.rfind("\")");
    m.push_back(line.substr(at + 9, end - at - 9));
  }
  return m;
}

TEST(PredefinedParameters, EveryValueIsRs274s) {
  if (!fs::exists(test::kRs274)) GTEST_SKIP() << test::kRs274 << " not installed";
  test::TempDir dir("ncd_predef_");
  const fs::path table = dir / "tool.tbl", prog = dir / "p.ngc", out = dir / "out.txt";
  std::ofstream(table) << "T1 P1 Z12.5 D6 ;\nT2 P2 Z30 D10 ;\n";
  const std::string all = print_all();
  std::ofstream(prog) << all << "G21 G90 G94 G17 G54 G99\n"
                      << all << "G20 G91 G93 G55 G18 G98 G90.1\n"
                      << all << "G21 G90 G94 G17 G59.3 G91.1\nF250 S1200 M3 M8\n"
                      << all << "M4 M7\nT1 M6\nG43 H1\nG0 X10 Y5 Z20\nG1 X12 F300\n"
                      << all << "T2\nG49\nM5\nG2 X14 Y5 I1 J0\n"
                      << all << "M2\n";
  const fs::path log = dir / "log.txt";
  const std::string cmd = "cd '" + dir.path().string() + "' && " +
                          test::rs274_command(dir.path(), "-t tool.tbl -g p.ngc out.txt") +
                          " > log.txt 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  std::ifstream f(out), lf(log);
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  const std::string rs_log((std::istreambuf_iterator<char>(lf)), std::istreambuf_iterator<char>());
  ASSERT_TRUE(test::rs274_complaint(text + rs_log).empty()) << text << rs_log;
  const std::vector<std::string> theirs = rs274_messages(text);
  toolpath::InterpretOptions opt;
  opt.tool_table = table.string();
  opt.machine_units = toolpath::Units::inch;  // rs274's: the table's lengths are inches
  std::ifstream pf(prog);
  const std::string src((std::istreambuf_iterator<char>(pf)), std::istreambuf_iterator<char>());
  const toolpath::Program p = toolpath::interpret_ngc(src, prog.string(), opt);
  std::vector<std::string> ours;
  for (const auto& s : p.steps) {
    if (const auto* e = std::get_if<toolpath::Event>(&s.item)) {
      if (const auto* m = std::get_if<toolpath::MessageEvent>(e)) ours.push_back(m->text);
    }
  }
  ASSERT_EQ(theirs.size(), 6 * std::size(kNames)) << text;
  ASSERT_EQ(ours.size(), theirs.size());
  int same = 0;
  for (std::size_t i = 0; i < ours.size(); ++i) {
    EXPECT_EQ(ours[i], theirs[i]) << "message " << i;
    same += ours[i] == theirs[i];
  }
  std::printf("[ measured ] %d of %zu predefined-parameter values equal rs274's\n", same,
              ours.size());
}

}  // namespace

// The rotary index axis in the interpreter (gcode/ngc/rotary.cpp) against LinuxCNC's `rs274`:
// each program is read by both, and the positions (X, Y, Z program coordinates, the rotary axis
// in machine degrees: rs274's A or B plus the work and G92 offsets it prints) after each of
// rs274's STRAIGHT_TRAVERSE/STRAIGHT_FEED must be the positions after each of ncd's motions and
// indexes, repeats taken out (rs274 prints a move that goes nowhere; ncd skips an index that
// turns nothing). A feed index's F (degrees per minute) must be rs274's SET_FEED_RATE before it.
// What ncd refuses (an A word with X motion, an A word on a machine with B, G92 A) is refused
// naming the line and the way out.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "gcode/ngc/interpreter.hpp"
#include "tests/common/rs274.hpp"
#include "tests/common/temp_dir.hpp"

namespace {

namespace fs = std::filesystem;
using namespace ncd;
using State = std::array<double, 4>;  // X, Y, Z (program units), rotary (machine degrees)

std::vector<double> numbers_in(const std::string& args) {
  std::string s = args;
  for (char& c : s) {
    if (c == ',') c = ' ';
  }
  std::istringstream in(s);
  std::vector<double> v;
  double x = 0.0;
  while (in >> x) v.push_back(x);
  return v;
}

struct Rs274Run {
  std::vector<State> states;
  std::vector<double> feed_before_index;  // SET_FEED_RATE in force at each feed move of A/B
};

// rs274's moves: X Y Z A B C after each straight move, the rotary one (index 3 for A, 4 for B)
// plus its work offset and G92 offset as SET_G5X_OFFSET / SET_G92_OFFSET print them.
Rs274Run rs274_states(const std::string& out, char axis) {
  Rs274Run r;
  const std::size_t i = axis == 'a' ? 3 : 4;
  double g5x = 0.0, g92 = 0.0, feed = 0.0, last_rot = 0.0;
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    const std::size_t open = line.find('('), close = line.rfind(')');
    if (open == std::string::npos || close == std::string::npos) continue;
    const std::vector<double> v = numbers_in(line.substr(open + 1, close - open - 1));
    if (line.find("SET_G5X_OFFSET(") != std::string::npos && v.size() >= 7) g5x = v[1 + i];
    if (line.find("SET_G92_OFFSET(") != std::string::npos && v.size() >= 6) g92 = v[i];
    if (line.find("SET_FEED_RATE(") != std::string::npos && !v.empty()) feed = v[0];
    const bool traverse = line.find("STRAIGHT_TRAVERSE(") != std::string::npos;
    const bool fed = line.find("STRAIGHT_FEED(") != std::string::npos;
    if ((!traverse && !fed) || v.size() < 6) continue;
    const State s{v[0], v[1], v[2], v[i] + g5x + g92};
    if (fed && std::abs(s[3] - last_rot) > 1e-9) r.feed_before_index.push_back(feed);
    last_rot = s[3];
    r.states.push_back(s);
  }
  return r;
}

struct NcdRun {
  std::vector<State> states;
  std::vector<double> index_feeds;
};

NcdRun ncd_states(const toolpath::Program& p) {
  NcdRun r;
  State at{0.0, 0.0, 0.0, p.rotary_start_deg};
  for (const toolpath::Step& st : p.steps) {
    if (const auto* m = std::get_if<toolpath::Motion>(&st.item)) {
      const Vec3 e = toolpath::motion_end(*m);
      at = {e.x(), e.y(), e.z(), at[3]};
      r.states.push_back(at);
    } else if (const auto* ix =
                   std::get_if<toolpath::RotaryIndexMove>(&std::get<toolpath::Event>(st.item))) {
      EXPECT_EQ(ix->from_deg, at[3]);
      at[3] = ix->to_deg;
      r.states.push_back(at);
      if (!ix->rapid) r.index_feeds.push_back(ix->feed_deg_per_min);
    }
  }
  return r;
}

std::vector<State> without_repeats(const std::vector<State>& in) {
  std::vector<State> out;
  for (const State& s : in) {
    bool same = !out.empty();
    for (std::size_t k = 0; k < 4 && same; ++k) same = std::abs(out.back()[k] - s[k]) <= 6e-5;
    if (!same) out.push_back(s);
  }
  return out;
}

std::string run_rs274(const test::TempDir& dir, const std::string& program,
                      const std::string& var) {
  std::ofstream(dir / "p.ngc") << program;
  std::ofstream(dir / "p.var") << var;
  const std::string cmd = "cd '" + dir.path().string() + "' && " +
                          test::rs274_command(dir.path(), "-v p.var -g p.ngc out.txt") +
                          " > log.txt 2>&1";
  const int rc = std::system(cmd.c_str());
  std::ifstream lf(dir / "log.txt"), of(dir / "out.txt");
  const std::string log((std::istreambuf_iterator<char>(lf)), std::istreambuf_iterator<char>());
  const std::string out((std::istreambuf_iterator<char>(of)), std::istreambuf_iterator<char>());
  EXPECT_EQ(rc, 0) << log;
  EXPECT_TRUE(test::rs274_complaint(log).empty()) << log;
  return out;
}

struct Case {
  const char* name;
  char axis;
  std::string program;
  std::string var;  // LinuxCNC parameter file (machine units: rs274's are inches)
};

const std::vector<Case>& cases() {
  static const std::vector<Case> c = {
      {"b_index_sample", 'b', "", ""},  // /usr/share/linuxcnc/ncfiles/b-index.ngc, read below
      // G20 does not scale A; G91 adds; G1 A with F in degrees per minute; X words that name
      // where X stands on an index line; a full turn and back; negative angles.
      {"inch_incremental_feed", 'a',
       "G20 G90 G17\nG0 X1 Y2 Z3\nG0 A90\nG1 X2 F10\nG91 G0 A-45\nG90 G1 A720 F3600\n"
       "G0 X2 A-30\nG0 Z4\nG91 G1 A15.5 F100\nG90 G0 A0\nM2\n",
       "5220 1\n"},
      // The work offset of A (G54's 5224, G55's 5244) and the G92 offset in the parameter file
      // (5210 on, 5214): machine degrees = program + both; G55 switches, G53 is machine.
      {"work_and_g92_offsets", 'a',
       "G21 G90 G54\nG0 X0 Y0 Z10\nG0 A30\nG55\nG0 A30\nG53 G0 A5\nG54 G0 A0\nM2\n",
       "5210 1\n5214 2.5\n5220 1\n5224 10\n5244 -20\n"},
      // Inverse time (G93): the index takes 1/F minutes, F x the angle per minute.
      {"inverse_time", 'b', "G21 G90\nG0 X0 Y0 Z5\nG93 G1 B90 F2\nG94 G1 X1 F100\nM2\n", ""},
  };
  return c;
}

TEST(RotaryAxisRs274, PositionsAfterEveryMoveAreRs274s) {
  if (!fs::exists(test::kRs274)) GTEST_SKIP() << test::kRs274 << " not installed";
  for (const Case& c : cases()) {
    SCOPED_TRACE(c.name);
    test::TempDir dir(std::string("ncd_rotary_") + c.name + "_");
    std::string program = c.program;
    if (program.empty()) {
      std::ifstream in("/usr/share/linuxcnc/ncfiles/b-index.ngc");
      if (!in) GTEST_SKIP() << "no LinuxCNC samples";
      program.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    const std::string out = run_rs274(dir, program, c.var);
    const Rs274Run ref = rs274_states(out, c.axis);
    std::ofstream(dir / "n.var") << c.var;
    toolpath::InterpretOptions opt;
    opt.rotary_axis = c.axis;
    opt.machine_units = toolpath::Units::inch;  // rs274's
    if (!c.var.empty()) opt.parameter_file = (dir / "n.var").string();
    const toolpath::Program p = toolpath::interpret_ngc(program, "p.ngc", opt);
    const NcdRun got = ncd_states(p);
    const std::vector<State> want = without_repeats(ref.states), have = without_repeats(got.states);
    ASSERT_EQ(have.size(), want.size()) << out;
    for (std::size_t n = 0; n < want.size(); ++n) {
      for (std::size_t k = 0; k < 4; ++k) {
        EXPECT_NEAR(have[n][k], want[n][k], 6e-5) << "move " << n << " axis " << k;
      }
    }
    ASSERT_EQ(got.index_feeds.size(), ref.feed_before_index.size());
    for (std::size_t n = 0; n < got.index_feeds.size(); ++n) {
      // (Under G93 rs274 prints the rate the move runs at: F x the angle, degrees per minute.)
      EXPECT_NEAR(got.index_feeds[n], ref.feed_before_index[n], 5e-5) << "index feed " << n;
    }
  }
}

std::string refusal(const std::string& program, char axis) {
  toolpath::InterpretOptions opt;
  opt.rotary_axis = axis;
  try {
    (void)toolpath::interpret_ngc(program, "r.ngc", opt);
  } catch (const InputError& e) {
    return e.what();
  }
  return "accepted";
}

void expect_all(const std::string& what, const std::vector<std::string>& parts) {
  for (const std::string& p : parts)
    EXPECT_NE(what.find(p), std::string::npos) << "'" << p << "' in: " << what;
}

TEST(RotaryAxisRefusals, EachNamesTheLineWhyAndTheWayOut) {
  const std::string head = "G21 G90\nG0 X0 Y0 Z5\n";
  // Simultaneous XYZ and A: refused with the brief's words.
  expect_all(refusal(head + "G1 X10 A90 F100\nM2\n", 'a'),
             {"r.ngc:3", "A90", "indexes the rotary axis between cuts", "line of its own"});
  // The axis the machine does not have: names the table to add.
  expect_all(refusal(head + "G0 B45\nM2\n", 0), {"r.ngc:3", "B45", "[axis.b]", "machine file"});
  expect_all(refusal(head + "G0 A45\nM2\n", 'b'), {"r.ngc:3", "A45", "[axis.b]", "one rotary"});
  expect_all(refusal(head + "G0 C45\nM2\n", 'a'), {"r.ngc:3", "C45", "not supported"});
  // An arc, a canned cycle, G28 with the word; G92 A and G10 L2 A.
  expect_all(refusal(head + "G2 X10 I5 A10 F100\nM2\n", 'a'), {"r.ngc:3", "G2", "between cuts"});
  expect_all(refusal(head + "G81 X1 Y1 Z-1 R1 A10 F100\nM2\n", 'a'), {"r.ngc:3", "G81"});
  expect_all(refusal(head + "G28 A0\nM2\n", 'a'), {"r.ngc:3", "G28"});
  expect_all(refusal(head + "G92 A10\nM2\n", 'a'), {"r.ngc:3", "G92", "parameter file"});
  expect_all(refusal(head + "G10 L2 P1 A10\nM2\n", 'a'), {"r.ngc:3", "G10", "parameter file"});
  // An incremental index before any absolute word: where the table stands is not known.
  expect_all(refusal(head + "G91 G0 A10\nM2\n", 'a'), {"r.ngc:3", "G91", "absolute A"});
  // Cutter compensation on.
  expect_all(refusal(head + "G41.1 D2\nG1 X5 F100\nG0 A10\nM2\n", 'a'),
             {"r.ngc:5", "compensation", "G40"});
  // Accepted: an X word that names where X stands, an A that names where A stands with X motion.
  EXPECT_EQ(refusal(head + "G0 X0 A90\nG0 X5 A90\nM2\n", 'a'), "accepted");
}

// daisy.ngc turns A with X, Y, Z on every line (a 4-axis contour): refused with the same words.
TEST(RotaryAxisRefusals, DaisyIsSimultaneousAndRefusedClearly) {
  std::ifstream in("/usr/share/linuxcnc/ncfiles/daisy.ngc");
  if (!in) GTEST_SKIP() << "no LinuxCNC samples";
  const std::string program((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  expect_all(refusal(program, 'a'),
             {"r.ngc:", "indexes the rotary axis between cuts", "move A on a line of its own"});
  expect_all(refusal(program, 0), {"[axis.a]"});
}

}  // namespace

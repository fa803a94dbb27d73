// The dialect rules against grbl 1.1h's own parser. Each expected error number below was
// worked out by hand from grbl's source (grbl/protocol.c for the line reader, grbl/gcode.c
// gc_execute_line for the words and checks, grbl/nuts_bolts.c read_float for numbers, the codes
// in grbl/report.h), reading the code path the line takes; the comment on each row names it.
#include "gcode/dialect/dialect.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "core/error.hpp"

namespace ncd::comms {
namespace {

struct Row {
  const char* line;
  int error;        // grbl's error:N, 0 for ok
  int column = 0;   // of the word named, 0: not checked
  const char* why;  // the code path in grbl
};

// Lines checked one by one on a freshly reset grbl (position 0, G0 G17 G21 G90 G94 G54, no F).
const std::vector<Row> kFreshRows = {
    {"G64 P0.0100", 20, 1, "gcode.c: G64 falls to the default case of the G switch"},
    {"G21 G90 G64 P0.01", 20, 9, "the G64 word, after two known codes"},
    {"M6", 20, 1, "M6 is not in the M switch"},
    {"T1 M6", 20, 4, "T is read (a value word), then M6 fails"},
    {"M7", 20, 1, "M7 only with ENABLE_M7 (off in config.h)"},
    {"M56", 20, 1, "M56 only with ENABLE_PARKING_OVERRIDE_CONTROL (off)"},
    {"G43 Z1", 20, 1, "G43 without .1: unsupported G43.x"},
    {"G61.1", 20, 1, "G61 with a mantissa"},
    {"G90.1", 20, 1, "G90.1 is not supported"},
    {"G28.2", 20, 1, "G28 with mantissa 20"},
    {"G38.1 Z-1 F10", 20, 1, "G38 with mantissa 10"},
    {"G5.2 X1", 20, 1, "G5 is unknown"},
    {"G0 A1", 20, 4, "A is not a value word in a 3-axis build"},
    {"G1 X1 Q2 F10", 20, 7, "Q is not a value word"},
    {"G10 L3 P1 X1", 20, 5, "G10 with L other than 2 or 20"},
    {"G10 L2 P1 R1 X1", 20, 5, "G10 L2 with R"},
    {"#1=2", 1, 1, "'#' is not a letter"},
    {"%", 1, 1, "'%' is kept by protocol.c (its % support is commented out) and is no letter"},
    {"[1]", 1, 1, "'[' is not a letter"},
    {"G0 X1.2.3", 1, 8, "read_float stops at the second point, which is then no letter"},
    {"G0 X1..2", 1, 7, "the same: X1. then ."},
    {"G1 X F10", 2, 4, "X has no digit before F"},
    {"G0 X-", 2, 4, "a sign without digits"},
    {"G0 X.", 2, 4, "a point without digits"},
    {"G0 X1 X2", 25, 7, "X repeated"},
    {"G0 G1 X1", 24, 4, "a second motion command: the axis-command conflict check comes first"},
    {"G0 G28 X1", 24, 4, "G28 after a motion command"},
    {"G0 G80", 21, 4, "G80 is in the motion group but not an axis command"},
    {"G17 G18", 21, 5, "plane group twice"},
    {"G90 G91", 21, 5, "distance group twice"},
    {"M3 M5", 21, 4, "spindle group twice"},
    {"M0 M30", 21, 4, "program-flow group twice"},
    {"G1 X1", 22, 1, "no feed rate yet (gc_state.feed_rate 0)"},
    {"G1", 22, 1, "G1 alone is an axis command: F is checked"},
    {"G2 X1 Y1 I1", 22, 1, "no feed rate"},
    {"G93 G1 X1", 22, 5, "inverse time without F"},
    {"G1.5 X1", 23, 1, "G1 with a mantissa"},
    {"M3.5", 23, 1, "M with a fraction"},
    {"G59.1", 23, 1, "G59 with a mantissa (G59.x)"},
    {"N10000001 G0 X1", 27, 1, "N above MAX_LINE_NUMBER"},
    {"G4", 28, 1, "G4 without P"},
    {"G10 X1", 28, 1, "G10 without P and L"},
    {"G10 L2 P7 X1", 29, 8, "P above N_COORDINATE_SYSTEM"},
    {"G53 G2 X1 Y1 R1 F100", 30, 1, "G53 with an arc"},
    {"G80 X1", 31, 1, "axis words in G80"},
    {"G2 Z1 F100", 32, 1, "no axis word in the XY plane"},
    {"G2 F100", 26, 1, "an arc without axis words"},
    {"G92", 26, 1, "G92 without axis words"},
    {"G38.2 F10", 26, 1, "a probe without axis words"},
    {"G38.2 Z0 F10", 33, 1, "a probe to where it stands"},
    {"G2 X0 Y0 R5 F100", 33, 10, "an R arc to its start"},
    {"G2 X10 Y0 R4 F100", 34, 11, "radius 4 < half the 10 mm chord"},
    {"G2 X10 Y0 I4 J0 F100", 33, 1, "end 6 mm from the centre, radius 4"},
    {"G2 X10 Y0 F100", 35, 1, "no I J and no R"},
    {"G43.1 X1", 37, 1, "G43.1 with X"},
    {"P5", 36, 1, "P used by nothing"},
    {"G0 X1 R2", 36, 7, "R with a straight move"},
    {"G1 X1 I2 F10", 36, 7, "I with a straight move"},
    {"T256", 38, 1, "above MAX_TOOL_NUMBER 255"},
    {"G1 X1 F-5", 4, 7, "negative F"},
    {"G4 P-1", 4, 4, "negative P"},
    {"S-1", 4, 1, "negative S"},
    {"N-1", 4, 1, "negative N"},
    {"", 0, 0, "empty: ok (protocol.c: line[0] == 0)"},
    {"(only a comment)", 0, 0, "comments are removed before the parser"},
    {"; only a comment", 0, 0, "';' comments run to the end"},
    {"/G0 X1", 0, 0, "block delete is ignored, the block runs"},
    {"g0 x1 y2", 0, 0, "lower case is raised"},
    {"G0X1Y2Z3", 0, 0, "no spaces needed"},
    {"G91.1", 0, 0, "G91.1 does nothing"},
    {"G4 P0.5", 0, 0, "a dwell"},
    {"M3 S1000", 0, 0, "spindle on"},
    {"G1 X1 F100 M3 S1000", 0, 0, "feed, spindle and a move"},
    {"G2 X10 Y0 I5 J0 F100", 0, 0, "a half circle"},
    {"G2 X10 Y0 R5 F100", 0, 0, "the same with R"},
    {"G93 G1 X1 F2", 0, 0, "inverse time with F"},
    {"G43.1 Z1", 0, 0, "dynamic tool length"},
    {"G38.2 Z-1 F10", 0, 0, "a probe (the parser accepts it)"},
    {"G10 L2 P1 X1", 0, 0, "set G54"},
    {"G10 L20 P0 X1", 0, 0, "set the active system from the position"},
    {"G28", 0, 0, "go home (G28 without axis words)"},
    {"G28.1", 0, 0, "store home"},
    {"G92 X5", 0, 0, "offset"},
    {"N10000000 M5", 0, 0, "N at its maximum"},
    {"N1.5 G0 X1", 0, 0, "grbl truncates N (no integer check)"},
    {"T1.5", 0, 0, "T is truncated"},
    {"G17 G21 G40 G49 G54 G61 G80 G90 G94", 0, 0, "a typical header"},
    {"M2", 0, 0, "program end"},
    {"M30", 0, 0, "program end"},
    {"M0", 0, 0, "program pause"},
    {"M1", 0, 0, "optional stop (ignored by grbl)"},
    {"M8", 0, 0, "flood coolant"},
};

TEST(GrblDialect, LinesAgainstGrblsOwnErrorNumbers) {
  int checked = 0;
  for (const Row& row : kFreshRows) {
    GrblState state;
    const GrblState before = state;
    const auto v = check_grbl_line(row.line, state);
    SCOPED_TRACE(std::string(row.line) + "  (" + row.why + ")");
    if (row.error == 0) {
      EXPECT_FALSE(v) << describe(*v, Dialect::grbl);
    } else {
      ASSERT_TRUE(v);
      EXPECT_EQ(v->grbl_error, row.error) << describe(*v, Dialect::grbl);
      if (row.column > 0) {
        EXPECT_EQ(v->column, row.column) << describe(*v, Dialect::grbl);
      }
      EXPECT_FALSE(v->reason.empty());
      EXPECT_FALSE(v->way_out.empty());
      // A refused line leaves the state untouched.
      EXPECT_EQ(state.feed, before.feed);
      EXPECT_EQ(state.position, before.position);
      EXPECT_EQ(state.motion, before.motion);
    }
    ++checked;
  }
  std::printf("grbl table: %d lines checked against grbl 1.1h's error numbers\n", checked);
}

TEST(GrblDialect, TheIssuesG64IsNamedWithItsWordAndWayOut) {
  GrblState s;
  const auto v = check_grbl_line("G64 P0.0100", s);
  ASSERT_TRUE(v);
  EXPECT_EQ(v->grbl_error, 20);
  EXPECT_EQ(v->word, "G64");
  const std::string text = describe(*v, Dialect::grbl);
  EXPECT_NE(text.find("error:20"), std::string::npos) << text;
  EXPECT_NE(text.find("'G64'"), std::string::npos) << text;
}

// A line's length as grbl's protocol.c counts it: 79 kept characters are taken, the 80th is an
// overflow (LINE_BUFFER_SIZE 80, one byte for the terminator). Spaces and comments are free.
TEST(GrblDialect, LineLengthAt79And80And81) {
  const auto line_of = [](std::size_t kept) {
    std::string s = "G1X";
    while (s.size() < kept) s += '1';
    return s;
  };
  for (std::size_t kept : {78U, 79U, 80U, 81U}) {
    GrblState st;
    st.feed = 100.0;
    const std::string line = line_of(kept);
    ASSERT_EQ(line.size(), kept);
    const auto v = check_grbl_line(line, st);
    if (kept <= 79) {
      EXPECT_FALSE(v) << kept << ": " << describe(*v, Dialect::grbl);
    } else {
      ASSERT_TRUE(v) << kept;
      EXPECT_EQ(v->grbl_error, 11);
      EXPECT_EQ(v->column, 80);
    }
  }
  // 79 kept characters padded with spaces and a comment to 120: still taken.
  std::string padded;
  for (char c : line_of(79)) {
    padded += c;
    padded += ' ';
  }
  padded = padded.substr(0, 100) + "(comment)";
  GrblState st;
  st.feed = 100.0;
  EXPECT_FALSE(check_grbl_line(padded, st));
}

// read_float keeps 8 significant digits; the value of the rest is dropped (fraction) or only
// scales (integer part), as nuts_bolts.c does.
TEST(GrblDialect, NumbersAsReadFloatReadsThem) {
  GrblState st;
  ASSERT_FALSE(check_grbl_line("G0 X1.234567891", st));
  EXPECT_DOUBLE_EQ(st.position[0], 1.2345678);
  ASSERT_FALSE(check_grbl_line("G0 X123456789", st));
  EXPECT_DOUBLE_EQ(st.position[0], 123456780.0);
  ASSERT_FALSE(check_grbl_line("G0 X-.5", st));
  EXPECT_DOUBLE_EQ(st.position[0], -0.5);
}

// The modal model: units, incremental moves, offsets, arcs and the program end, checked
// against values computed by hand.
TEST(GrblDialect, StateFollowsGrblsExecution) {
  GrblState s;
  GrblBlock b;
  ASSERT_FALSE(check_grbl_line("G20 G0 X1", s, &b));
  EXPECT_DOUBLE_EQ(s.position[0], 25.4);
  ASSERT_FALSE(check_grbl_line("G21 G91 G0 X1 Y2", s, &b));
  EXPECT_DOUBLE_EQ(s.position[0], 26.4);
  EXPECT_DOUBLE_EQ(s.position[1], 2.0);
  EXPECT_DOUBLE_EQ(b.path_mm, std::hypot(1.0, 2.0));
  EXPECT_TRUE(b.rapid);
  ASSERT_FALSE(check_grbl_line("G90 G92 X0 Y0", s, &b));  // here is now 0,0
  ASSERT_FALSE(check_grbl_line("G1 X10 F600", s, &b));
  EXPECT_DOUBLE_EQ(s.position[0], 36.4);
  EXPECT_DOUBLE_EQ(b.feed_mm_per_min, 600.0);
  // A half circle of radius 5 from X10 to X20 (work), clockwise: length 5π.
  ASSERT_FALSE(check_grbl_line("G2 X20 Y0 I5 J0", s, &b));
  EXPECT_NEAR(b.path_mm, 5.0 * M_PI, 1e-9);
  // A full circle (IJK form, end = start): 2π·5.
  ASSERT_FALSE(check_grbl_line("G3 X20 Y0 I5 J0", s, &b));
  EXPECT_NEAR(b.path_mm, 10.0 * M_PI, 1e-9);
  // A quarter helix: R form, short arc, 2 mm up.
  ASSERT_FALSE(check_grbl_line("G3 X15 Y5 Z2 R5", s, &b));
  EXPECT_NEAR(b.path_mm, std::hypot(2.5 * M_PI, 2.0), 1e-9);
  ASSERT_FALSE(check_grbl_line("M3 S12000", s, &b));
  EXPECT_EQ(s.spindle, 3);
  EXPECT_EQ(b.spindle_rpm, 12000.0);
  ASSERT_FALSE(check_grbl_line("G4 P1.5", s, &b));
  EXPECT_EQ(b.dwell_s, 1.5);
  ASSERT_FALSE(check_grbl_line("G18 G91 M30", s, &b));
  EXPECT_TRUE(b.program_end);
  EXPECT_EQ(s.spindle, 5);          // M30: spindle off
  EXPECT_EQ(s.plane, 0);            // G17
  EXPECT_FALSE(s.incremental);      // G90
  EXPECT_EQ(s.motion, 10);          // G1
  EXPECT_EQ(s.spindle_rpm, 12000);  // S is not reset
  // An R arc straight up the linear axis (zero chord): accepted as grbl does, timed as the
  // straight move, never a NaN.
  GrblState up;
  up.feed = 100.0;
  ASSERT_FALSE(check_grbl_line("G2 X0 Z5 R3", up, &b));
  EXPECT_DOUBLE_EQ(b.path_mm, 5.0);
  // The feed survives the end: G1 needs no new F.
  EXPECT_FALSE(check_grbl_line("X0", s, &b));
}

TEST(Dialect, ParseNamesTheValueAndTheChoices) {
  EXPECT_EQ(parse_dialect("grbl"), Dialect::grbl);
  EXPECT_EQ(parse_dialect("iso"), Dialect::iso);
  EXPECT_EQ(parse_dialect("linuxcnc"), Dialect::linuxcnc);
  try {
    (void)parse_dialect("fanuc");
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'fanuc'"), std::string::npos) << what;
    EXPECT_NE(what.find("iso"), std::string::npos) << what;
    EXPECT_NE(what.find("grbl"), std::string::npos) << what;
    EXPECT_NE(what.find("linuxcnc"), std::string::npos) << what;
  }
  EXPECT_EQ(rules(Dialect::grbl).max_line_chars, 79);
  EXPECT_FALSE(rules(Dialect::grbl).percent_framing);
  EXPECT_TRUE(rules(Dialect::iso).percent_framing);
  EXPECT_TRUE(rules(Dialect::iso).n_numbers);
}

TEST(Dialect, ProgramCheckNamesTheLine) {
  const std::string program =
      "G21 G90 G94\r\nG17\n\n(approach)\nM3 S12000\nG64 P0.0100\nG1 X1 F100\nM2\n";
  const auto v = check_program(Dialect::grbl, program);
  ASSERT_TRUE(v);
  EXPECT_EQ(v->line, 6);
  EXPECT_EQ(v->word, "G64");
  EXPECT_EQ(v->grbl_error, 20);
  // The same program is fine for LinuxCNC.
  EXPECT_FALSE(check_program(Dialect::linuxcnc, program));
  // The state carries from line to line: G1 without any F is error:22 on its own line.
  const auto f = check_program(Dialect::grbl, "G21\nM3 S1000\nG1 X1\nM2\n");
  ASSERT_TRUE(f);
  EXPECT_EQ(f->line, 3);
  EXPECT_EQ(f->grbl_error, 22);
  EXPECT_FALSE(check_program(Dialect::grbl, "G21\nF100\nM3 S1000\nG1 X1\nM2\n"));
  // Degenerate programs: empty, only comments, only framing blank lines.
  EXPECT_FALSE(check_program(Dialect::grbl, ""));
  EXPECT_FALSE(check_program(Dialect::grbl, "(a)\n;b\n\n"));
  EXPECT_FALSE(check_program(Dialect::iso, "%\n\n%\n"));
}

TEST(Dialect, IsoTakesPlainWordsOnly) {
  DialectState s;
  EXPECT_FALSE(check_line(Dialect::iso, "N10 G01 X1.5 Y-2. F100 (cut)", s));
  EXPECT_FALSE(check_line(Dialect::iso, "%", s));
  EXPECT_FALSE(check_line(Dialect::iso, "/N20 M01", s));
  EXPECT_FALSE(check_line(Dialect::iso, "O1234", s));
  const std::vector<std::pair<const char*, int>> bad = {{"#100=1", 1},     {"G1 X[1+2]", 4},
                                                        {"G1 X1 ;end", 7}, {"G1 X1.2.3", 4},
                                                        {"G1 X", 4},       {"G1 (open", 4}};
  for (const auto& [line, col] : bad) {
    const auto v = check_line(Dialect::iso, line, s);
    ASSERT_TRUE(v) << line;
    EXPECT_EQ(v->column, col) << line << ": " << describe(*v, Dialect::iso);
    EXPECT_EQ(v->grbl_error, 0);
  }
  const auto v = check_program(Dialect::iso, "%\nN1 G0 X0\nN2 #1=3\n%\n");
  ASSERT_TRUE(v);
  EXPECT_EQ(v->line, 3);
  EXPECT_EQ(v->word, "#");
}

TEST(Dialect, LinuxcncUsesTheInterpreter) {
  EXPECT_FALSE(check_program(Dialect::linuxcnc, "G21 G90\n#1=2\nG1 X#1 F100\nM2\n"));
  const auto v = check_program(Dialect::linuxcnc, "G21\nG1 X1 Q F100\nM2\n");
  ASSERT_TRUE(v);
  EXPECT_FALSE(v->reason.empty());
}

}  // namespace
}  // namespace ncd::comms

// The tool table's kind and teeth (gcode/ngc/tool_table.hpp): read from the comment, merged with
// the machine file's [tools.N] and [tool], carried by to_path onto every segment.
#include "gcode/ngc/tool_table.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

#include "core/error.hpp"
#include "gcode/program.hpp"

namespace ncd::toolpath {
namespace {

namespace fs = std::filesystem;

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

class ToolTable : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("ncd_tool_table_" + std::to_string(getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string table(const std::string& text) {
    const fs::path p = dir_ / "tool.tbl";
    std::ofstream(p) << text;
    return p.string();
  }
  fs::path dir_;
};

TEST_F(ToolTable, CommentGivesKindAndTeethOtherTextStays) {
  const auto e = parse_tool_table(
      "T1 P1 D6.35 Z10 ;kind=flat teeth=4 1/4 in end mill\n"
      "T2 P2 D6 ;Kind=BALL\n"
      "T3 P3 D8 ;drill, no kind stated\n"
      "; a comment line\n",
      "t.tbl");
  ASSERT_EQ(e.size(), 3u);
  EXPECT_EQ(e[0].kind, ToolKind::flat);
  EXPECT_EQ(e[0].teeth, 4);
  EXPECT_EQ(e[0].diameter, 6.35);
  EXPECT_EQ(e[0].z, 10.0);
  EXPECT_EQ(e[1].kind, ToolKind::ball);
  EXPECT_EQ(e[1].teeth, 0);
  EXPECT_EQ(e[2].kind, ToolKind::unknown);
  EXPECT_EQ(e[2].line, 3);
}

TEST_F(ToolTable, BadKindOrTeethNameFileLineValueAndTheWayOut) {
  const std::string kind = error_of([] { parse_tool_table("\nT1 D6 ;kind=endmill\n", "t.tbl"); });
  for (const char* part : {"t.tbl:2", "kind=endmill", "ball, flat, bull_nose, drill"}) {
    EXPECT_NE(kind.find(part), std::string::npos) << part << ": " << kind;
  }
  for (const char* bad : {"teeth=0", "teeth=2.5", "teeth=x", "teeth=1001"}) {
    const std::string e =
        error_of([&] { parse_tool_table("T1 D6 ;" + std::string(bad) + "\n", "t.tbl"); });
    EXPECT_NE(e.find("t.tbl:1"), std::string::npos) << e;
    EXPECT_NE(e.find(bad), std::string::npos) << e;
  }
}

// An inch table: D 0.25 in is a radius of 3.175 mm. [tool] is a ball where the table has no
// entry; the table's entry wins where it has one.
TEST_F(ToolTable, CatalogueMergesTableMachineFileAndTool) {
  InterpretOptions o;
  o.machine_units = Units::inch;
  o.tool_table = table("T1 P1 D0.25 Z1 ;kind=flat\nT5 P5 D0.5 Z1\n");
  o.machine_tools = {7};
  o.declared_tools[1] = ToolSpec{ToolKind::flat, 0.0, 3, "m.toml [tools.1]"};
  o.declared_tools[2] = ToolSpec{ToolKind::drill, 4.0, 2, "m.toml [tools.2]"};
  const auto c = tool_catalogue(o);
  ASSERT_EQ(c.size(), 4u);
  EXPECT_EQ(c.at(1).kind, ToolKind::flat);
  EXPECT_DOUBLE_EQ(c.at(1).radius_mm, 3.175);
  EXPECT_EQ(c.at(1).teeth, 3);
  EXPECT_EQ(c.at(2).kind, ToolKind::drill);
  EXPECT_EQ(c.at(5).kind, ToolKind::unknown);
  EXPECT_EQ(c.at(7).kind, ToolKind::ball);
  EXPECT_EQ(c.at(7).radius_mm, 0.0);  // [cutting]'s
  o.machine_tools = {5};              // the table's entry of no kind wins over [tool]
  EXPECT_EQ(tool_catalogue(o).at(5).kind, ToolKind::unknown);
}

TEST_F(ToolTable, DisagreementsNameBothPlaces) {
  InterpretOptions o;
  o.tool_table = table("T1 P1 D6 ;kind=flat teeth=2\n");
  o.declared_tools[1] = ToolSpec{ToolKind::flat, 0.0, 4, "m.toml [tools.1]"};
  const std::string teeth = error_of([&] { tool_catalogue(o); });
  for (const char* part : {"T1", "tool.tbl:1", "m.toml [tools.1]", "teeth 2", "4"}) {
    EXPECT_NE(teeth.find(part), std::string::npos) << part << ": " << teeth;
  }
  o.declared_tools[1] = ToolSpec{ToolKind::flat, 3.5, 0, "m.toml [tools.1]"};
  EXPECT_NE(error_of([&] { tool_catalogue(o); }).find("radius 3 mm"), std::string::npos);
  o.declared_tools[1] = ToolSpec{ToolKind::flat, 3.0, 2, "m.toml [tools.1]"};
  EXPECT_EQ(error_of([&] { tool_catalogue(o); }), "(no error)");
}

// to_path gives each segment the tool in the spindle, as the program's list describes it.
TEST_F(ToolTable, SegmentsCarryTheToolInTheSpindle) {
  InterpretOptions o;
  o.tool_table = table("T1 P1 D6 Z10 ;kind=ball teeth=2\nT2 P2 D8 Z20 ;kind=drill\n");
  const Program p = interpret_ngc(
      "G21 G90\nT1 M6\nG43 H1\nG0 X0 Y0 Z5\nG1 X10 F300\nT2 M6\nG43 H2\nG0 Z30\nG1 Z10 F100\nM2\n",
      "p.ngc", o);
  const Path path = to_path(p);
  bool saw1 = false, saw2 = false;
  for (const PathSegment& s : path.segments) {
    if (s.rapid) continue;
    if (s.tool.number == 1) {
      saw1 = true;
      EXPECT_EQ(s.tool.kind, ToolKind::ball);
      EXPECT_EQ(s.tool.radius_mm, 3.0);
      EXPECT_EQ(s.tool.teeth, 2);
      EXPECT_TRUE(s.tool.roughness_law());
    } else {
      saw2 = true;
      EXPECT_EQ(s.tool.number, 2);
      EXPECT_EQ(s.tool.kind, ToolKind::drill);
      EXPECT_FALSE(s.tool.roughness_law());
    }
  }
  EXPECT_TRUE(saw1 && saw2);
  // No table, no change: T0, of unknown kind.
  const Path bare = to_path(interpret_ngc("G21\nG0 X0 Y0 Z0\nG1 X5 F100\nM2\n", "b.ngc"));
  EXPECT_EQ(bare.segments.back().tool.number, 0);
  EXPECT_EQ(bare.segments.back().tool.kind, ToolKind::unknown);
}

}  // namespace
}  // namespace ncd::toolpath

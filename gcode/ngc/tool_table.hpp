// LinuxCNC's tool table (tool.tbl) and what ncd adds to it: the kind and teeth of each tool,
// which LinuxCNC's table has no column for. They go in the comment after ';', which LinuxCNC
// and its `rs274` ignore:
//
//     T1 P1 D6.35 Z10 ;kind=flat teeth=4 1/4" end mill
//
// `kind=` takes ball, flat, bull_nose or drill; `teeth=` a whole number ≥ 1; other comment text
// is kept as the operator wrote it. The machine file's [tools.N] tables declare the same
// (docs/feedrate.md §1.5); a tool declared in both must agree. tool_catalogue() merges them:
// what the roughness law needs of every tool a program may cut with.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "gcode/ngc/interpreter.hpp"
#include "geometry/tool.hpp"

namespace ncd::toolpath {

struct ToolTableEntry {
  int tool = 0;
  double z = 0.0;                     // length offset, machine units
  double diameter = 0.0;              // machine units
  int orientation = 0;                // Q: lathe tool orientation, 0 for mills
  ToolKind kind = ToolKind::unknown;  // `kind=` in the comment; unknown when not stated
  int teeth = 0;                      // `teeth=` in the comment; 0 when not stated
  int line = 0;                       // 1-based line in the file
};

// The entries of a tool table file, in file order. Throws InputError naming file:line, the word
// and a way out: a malformed word, a kind not among ball, flat, bull_nose, drill, a teeth count
// that is not a whole number from 1 to 1000.
std::vector<ToolTableEntry> parse_tool_table(const std::string& text, const std::string& name);
// The file, read (InputError when it cannot be opened, naming the path).
std::vector<ToolTableEntry> read_tool_table(const std::string& path);

// What is known of every tool a program read with `options` may cut with: the tool table's
// entries (radius D/2 in mm), the machine file's [tools.N] (declared_tools) and [tool] number
// (machine_tools: a ball end of [cutting], where neither the table nor [tools.N] holds it; the
// table's entry wins, as for its length). A field stated by both the table and [tools.N] with two
// values is an InputError naming both places and the values.
std::map<int, ToolSpec> tool_catalogue(const InterpretOptions& options);

}  // namespace ncd::toolpath

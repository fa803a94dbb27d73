// RS-274/NGC interpreter (LinuxCNC 2.9 dialect) producing the program model of program.hpp.
// What it reads, what it refuses and how it was checked against LinuxCNC's own interpreter:
// docs/ngc-interpreter.md.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "gcode/program.hpp"

namespace ncd::toolpath {

struct InterpretOptions {
  Units default_units = Units::mm;  // units before any G20/G21
  // Units of the tool table, the parameter file and the stored positions (LinuxCNC's machine
  // units). LinuxCNC's standalone `rs274` uses inches; a metric machine uses mm.
  Units machine_units = Units::mm;
  std::string tool_table;  // LinuxCNC tool.tbl; empty: no tools (T0 only)
  // Tools the machine holds besides the table's (the machine file's [tool] number, which every
  // program ncd writes selects with T n M6): zero length and diameter, the table's entry wins.
  std::vector<int> machine_tools;
  // Tools the machine file declares ([tools.N]: kind, teeth, radius; geometry/tool.hpp), merged
  // with the tool table's comments by tool_catalogue (gcode/ngc/tool_table.hpp).
  std::map<int, ToolSpec> declared_tools;
  std::string parameter_file;                // LinuxCNC .var; empty: all parameters start at 0
  std::vector<std::string> subroutine_path;  // folders searched for o<name> call → name.ngc
  bool block_delete = false;                 // true: lines starting with '/' are skipped (rs274 -b)
  long max_blocks = 20'000'000;              // executed blocks before a runaway loop is reported
  // Where the machine stands when the program starts (machine coordinates, mm, no tool length
  // offset): `ncd replay --start`, the machine file's [program] start_mm, or the controller's
  // reported position. Given, every axis is known from the first line, as in LinuxCNC; not given,
  // the machine is taken to stand at its origin but no axis is known until the program moves it
  // there, and a feed move before that is refused.
  std::optional<Vec3> start_machine_mm;
  // The machine's rotary index axis (the machine file's [axis.a] or [axis.b]): 'a', 'b', or 0
  // for none. Its words are degrees; a program that turns another axis is refused.
  char rotary_axis = 0;
};

// Interprets a whole program; `name` (a file name) prefixes every error message and becomes
// Program::files[0]. Throws InputError naming file:line, the construct and a way out; nothing
// is returned on error.
Program interpret_ngc(const std::string& text, const std::string& name,
                      const InterpretOptions& options = {});

// Reads the file, then interpret_ngc.
Program interpret_ngc_file(const std::string& path, const InterpretOptions& options = {});

}  // namespace ncd::toolpath

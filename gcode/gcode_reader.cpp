// RS-274/NGC to Path: the interpreter, then to_path (see gcode_reader.hpp).
#include "gcode/gcode_reader.hpp"

#include <algorithm>
#include <sstream>

#include "core/error.hpp"
#include "gcode/program.hpp"

namespace ncd::toolpath {

Path read_gcode(std::istream& in, const std::string& name, const InterpretOptions& options) {
  std::ostringstream text;
  text << in.rdbuf();
  const Program program = interpret_ngc(text.str(), name, options);
  Path path = to_path(program);
  const bool moves = std::any_of(program.steps.begin(), program.steps.end(), [](const Step& s) {
    return std::holds_alternative<Motion>(s.item);
  });
  if (!moves) throw NoMotionError(name + ": the program moves nothing (no G0/G1/G2/G3/G5.2 move)");
  if (path.segments.empty()) {
    throw InputError(
        name +
        ": the program contains no move from a known position; give where the "
        "machine stands (ncd replay --start X,Y,Z in machine mm, \"start_mm\" in an ncd serve "
        "submit, or start_mm in the machine file's [program] table), or begin the program with a "
        "G0 to X, Y "
        "and Z");
  }
  path.source = name;
  return path;
}

}  // namespace ncd::toolpath

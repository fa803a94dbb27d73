// RS-274/NGC to Path: the interpreter, then to_path (see gcode_reader.hpp).
#include "gcode/gcode_reader.hpp"

#include <sstream>

#include "core/error.hpp"
#include "gcode/program.hpp"

namespace ncd::toolpath {

Path read_gcode(std::istream& in, const std::string& name, const InterpretOptions& options) {
  std::ostringstream text;
  text << in.rdbuf();
  const Program program = interpret_ngc(text.str(), name, options);
  Path path = to_path(program);
  if (path.segments.empty()) {
    throw InputError(name +
                     ": the program contains no move from a known position; give where the "
                     "machine stands (ncd replay --start X,Y,Z in machine mm, or start_mm in the "
                     "machine file's [machine] table), or begin the program with a G0 to X, Y "
                     "and Z");
  }
  path.source = name;
  return path;
}

}  // namespace ncd::toolpath

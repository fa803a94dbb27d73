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
                     ": the program contains no move from a known position; it needs a G0 to "
                     "X, Y and Z, then G0/G1/G2/G3/G5.2 moves");
  }
  path.source = name;
  return path;
}

}  // namespace ncd::toolpath

// RS-274/NGC interpreter, LinuxCNC 2.9 dialect (docs/ngc-interpreter.md has the full list of
// what is read and refused, and how the output was checked against LinuxCNC's `rs274`).
//
// Each line goes through:
// 1. Normalisation: comments taken out (the last "( )" comment of a line is the one that counts,
//    as in LinuxCNC; "(MSG," makes a message), whitespace removed, letters lower-cased.
// 2. Reading: words letter + real value, where a real value is a number, a parameter #n,
//    #<name>, a unary function NAME[..] or a bracketed expression [..]. Binary operators
//    group left to right in five precedence levels (LinuxCNC's manual, "Expressions"):
//      **  >  * / MOD  >  + -  >  EQ NE GT GE LT LE  >  AND OR XOR
//    Parameter assignments on a line take effect after the whole line is read.
// 3. Execution in LinuxCNC's order: message, feed mode, F, S, T, M6, M3/M4/M5, M7/M8/M9, G4,
//    plane, units, cutter compensation, tool length offset, coordinate system, path control,
//    distance modes, retract mode, G10/G28/G30/G92, motion (G53 applied), M0/M1/M2/M30/M60.
//
// Every length is kept in mm inside; the program model gets program units (what LinuxCNC's
// canonical commands carry), the stored parameters and the tool table are in machine units.
// Control flow (O-words) works on the file's lines held in memory: a false `if`, a finished
// loop or a `break` scans forward to the line with the same label and the wanted keyword.
//
// Speed (docs/ngc-interpreter.md, "Speed"): long programs are mostly lines such as G1 X.. Y..
// without a comment. Such a line is normalised in one pass over its characters (the lexer runs
// only on lines with a comment, o_words.cpp), the check that each word has a code to read it
// looks further only when the line holds I, J, K, R, P, Q or L (execute.cpp), and the steps are
// reserved one per line (run), so the program's vector is filled in place, not moved as it grows.
#include "gcode/ngc/interp.hpp"
#include "gcode/ngc/tool_table.hpp"

namespace ncd::toolpath::ngc {

Program Interpreter::run(const std::string& text, const std::string& name) {
  load_tool_table();
  load_parameters();
  files_.push_back(std::make_unique<SourceFile>());
  SourceFile& f = *files_.back();
  f.name = name;
  f.text = text;
  split_lines(f);
  // One step per line, what most lines of a long program make (a few make more, comments and
  // blank lines none): the steps are not moved again and again while the program grows, and
  // the unused end of the reservation is never touched (address space, not memory).
  program_.steps.reserve(f.lines.size());
  program_.files.push_back(name);
  program_.rotary_axis = opt_.rotary_axis;
  scan_subs(0);
  coord_sys_ = std::clamp(static_cast<int>(std::lround(params_[5220])), 1, 9);
  g92_ = params_[5210] != 0.0 ? Vec3(param_len(5211), param_len(5212), param_len(5213))
                              : Vec3(0, 0, 0);
  if (opt_.start_machine_mm) {
    if (!opt_.start_machine_mm->allFinite()) {
      throw InputError("the start position (" + text::sig(opt_.start_machine_mm->x()) + ", " +
                       text::sig(opt_.start_machine_mm->y()) + ", " +
                       text::sig(opt_.start_machine_mm->z()) +
                       ") mm is not a position; give three numbers, e.g. --start 0,0,50");
    }
    pos_ = *opt_.start_machine_mm - (g5x() + g92_);
    known_ = {true, true, true};
  } else {
    pos_ = -(g5x() + g92_);  // the machine starts at its origin, no axis known
  }
  execute_all();
  comp_call([&] { comp_.flush(); });  // a file that ends without M2 writes its last move
  return std::move(program_);
}

// Error position of the line being executed.
std::string Interpreter::where() const {
  return files_[cur_file_]->name + ":" + std::to_string(cur_line_ + 1);
}

std::string Interpreter::line_text() const {
  if (cur_file_ >= files_.size()) return {};
  const auto& lines = files_[cur_file_]->lines;
  return cur_line_ < lines.size() ? std::string(lines[cur_line_]) : std::string();
}

}  // namespace ncd::toolpath::ngc

namespace ncd::toolpath {

using ngc::Fail;
using ngc::Interpreter;

Program interpret_ngc(const std::string& text, const std::string& name,
                      const InterpretOptions& options) {
  Interpreter in(options);
  try {
    Program p = in.run(text, name);
    in.finish();
    p.parameter_file_text = in.parameter_file_text();
    p.start_machine_mm = options.start_machine_mm;
    p.tools = tool_catalogue(options);  // each tool's kind, teeth and radius (tool_table.hpp)
    return p;
  } catch (const Fail& f) {
    throw InputError(in.where() + ": " + f.what + " (line: \"" + in.line_text() + "\")");
  }
}

Program interpret_ngc_file(const std::string& path, const InterpretOptions& options) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open; check the path and its permissions");
  std::ostringstream s;
  s << in.rdbuf();
  if (in.bad()) throw InputError(path + ": read error; check the file");
  return interpret_ngc(s.str(), path, options);
}

}  // namespace ncd::toolpath

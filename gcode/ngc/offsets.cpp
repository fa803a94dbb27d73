// The RS-274/NGC interpreter: G10, G28/G30 and G92. The reading and execution order is in
// interpreter.cpp.
#include "gcode/ngc/interp.hpp"

namespace ncd::toolpath::ngc {

void Interpreter::g10(const Block& b) {
  if (!b.has('l')) fail("G10 without L; use G10 L2 or G10 L20");
  const double l = b.v('l');
  if (l != 2 && l != 20)
    fail("G10 L" + text::sig(l) + " is not supported; use L2 or L20 (tool table edits are not)");
  if (!b.has('p')) fail("G10 L" + text::sig(l) + " without P (coordinate system 0-9); add P");
  const double pv = b.v('p');
  if (pv < 0 || pv > 9 || pv != std::floor(pv))
    fail("G10 P" + text::sig(pv) + ": P must be 0 (current) to 9");
  if (b.has('r') && b.v('r') != 0.0)
    fail("G10 R (rotation of the coordinate system) is not supported; remove R");
  const int n = pv == 0 ? coord_sys_ : static_cast<int>(pv);
  const int base = 5201 + 20 * n;
  const Vec3 old = g5x();
  for (int a = 0; a < 3; ++a) {
    const char c = static_cast<char>('x' + a);
    if (!b.has(c)) continue;
    const double v = len_word(b, c);
    const double off = l == 2 ? v : pos_[a] + old[a] - v;
    params_[static_cast<std::size_t>(base + a)] = off / machine_k_;
  }
  if (n == coord_sys_) pos_ += old - g5x();
}

// G28 / G30 (LinuxCNC's convert_home): a rapid to the intermediate point the block's words
// give (in the current frame and distance mode), then a rapid of the block's axes (all three
// when it names none) to the stored position, parameters base..base+2 in machine coordinates
// and units, taken back into the program's frame (less the work offset, G92 and the tool
// length). A stored position nobody gave is refused: every parameter starts at 0, and a move
// to machine zero is what rs274 would print, but on a machine that has its own G28 position
// (or a work offset at the part) a rapid there runs into the part.
void Interpreter::home(const Block& b, int base) {
  const bool any = b.has('x') || b.has('y') || b.has('z');
  if (!any) check_rotary_home(base);
  for (int a = 0; a < 3; ++a) {
    if ((any && !b.has(static_cast<char>('x' + a))) ||
        param_given_[static_cast<std::size_t>(base + a)]) {
      continue;
    }
    const std::string g = base == 5161 ? "G28" : "G30";
    const std::string from = std::to_string(base) + "-" + std::to_string(base + 2);
    fail(g + " moves " + std::string(1, static_cast<char>('X' + a)) + " to the stored " + g +
         " position, but no parameter " + std::to_string(base + a) + " is known: " +
         (opt_.parameter_file.empty()
              ? std::string("no parameter file is given")
              : "the parameter file " + opt_.parameter_file + " does not hold it") +
         ", and a position of 0 would be a rapid to machine zero, on most set-ups into the "
         "part. Give the machine file's [program] parameter_file a LinuxCNC .var that holds " +
         from + " (the " + g + " position in machine coordinates and machine units, as the " +
         "controller has it), set it in the program (" + g + ".1 or #" + std::to_string(base) +
         "=...), or move with G53 G0 instead");
  }
  const Vec3 mid = target(b, false);
  line_to(mid, true);
  Vec3 home_prog = Vec3(param_len(base), param_len(base + 1), param_len(base + 2)) - total_offset();
  Vec3 end = mid;
  for (int a = 0; a < 3; ++a) {
    if (!any || b.has(static_cast<char>('x' + a))) {
      end[a] = home_prog[a];
      pending_known_[static_cast<std::size_t>(a)] = true;
    }
  }
  line_to(end, true);
}

void Interpreter::store_home(int base) {
  const Vec3 abs = pos_ + total_offset();
  for (int a = 0; a < 3; ++a) {
    params_[static_cast<std::size_t>(base + a)] = abs[a] / machine_k_;
    param_given_[static_cast<std::size_t>(base + a)] = true;
  }
}

void Interpreter::g92(const Block& b) {
  if (!(b.has('x') || b.has('y') || b.has('z')))
    fail("G92 without X, Y or Z; give the axes to set");
  for (int a = 0; a < 3; ++a) {
    const char c = static_cast<char>('x' + a);
    if (!b.has(c)) continue;
    const double v = len_word(b, c);
    const double n = pos_[a] + g92_[a] - v;
    pos_[a] = v;
    g92_[a] = n;
    params_[static_cast<std::size_t>(5211 + a)] = n / machine_k_;
  }
  params_[5210] = 1.0;
}

}  // namespace ncd::toolpath::ngc

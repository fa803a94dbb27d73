// The RS-274/NGC interpreter: the rotary index axis (docs/ngc-interpreter.md, "Rotary index
// axis"). A machine file's [axis.a] or [axis.b] gives the machine one rotary axis, which ncd uses
// to index the part between cuts, never while X, Y and Z move:
//   - its words are degrees, G20/G21 do not scale them (LinuxCNC's rotary axes); G90/G91 apply,
//     and G53 (machine degrees). The work offset (G54 … G59.3, the parameters 5204 + 20 n for A,
//     5205 + 20 n for B) and the G92 offset the parameter file holds (5214, 5215 under 5210) are
//     applied, as LinuxCNC does; setting them from the program (G10, G92) is refused;
//   - a G0 or G1 that turns it and leaves X, Y, Z where they stand becomes a RotaryIndexMove
//     event; one that moves both is refused, and so is the word on an arc, a canned cycle,
//     G28/G30 or G92;
//   - it starts at 0 (rs274 and the simulated controller do too); an incremental index before an
//     absolute word has set it is refused, since the controller's table may stand anywhere;
//   - the word of the axis the machine lacks (or of C, U, V, W) is refused, naming the table.
#include "gcode/ngc/interp.hpp"

namespace ncd::toolpath::ngc {
namespace {

constexpr double kMaxRotaryDeg = 1e6;  // beyond it the word is a typo (2 777 turns)

std::string upper(char c) {
  return std::string(1, static_cast<char>(std::toupper(c)));
}

const char* about(char axis) {
  return axis == 'a' ? "about X" : "about Y";
}

}  // namespace

bool Interpreter::rotary_word(const Block& b) const {
  return opt_.rotary_axis != 0 && b.has(opt_.rotary_axis);
}

// Every axis word but X, Y, Z and the machine's rotary axis is refused (a zero is let through
// where the machine has no such axis, as before: it moves nothing).
void Interpreter::check_rotary_words(const Block& b) const {
  const char r = opt_.rotary_axis;
  for (const char c : {'a', 'b', 'c', 'u', 'v', 'w'}) {
    if (c == r || !b.has(c) || b.v(c) == 0.0) continue;
    const std::string word = upper(c) + text::sig(b.v(c));
    if ((c == 'a' || c == 'b') && r == 0) {
      fail(word + ": the machine has no " + upper(c) + " axis (rotary " + about(c) +
           "); if it has one, declare it with an [axis." + std::string(1, c) +
           "] table in the machine file (docs/planner.md section 3g), else remove the word");
    }
    if (c == 'a' || c == 'b') {
      fail(word + ": the machine's rotary axis is " + upper(r) + " ([axis." + std::string(1, r) +
           "] in the machine file) and ncd drives one rotary axis; turn the part with " + upper(r) +
           " or remove the word");
    }
    fail(word +
         ": axes other than X, Y, Z and one rotary index axis (A or B) are not supported; "
         "remove the word");
  }
}

// The rotary axis's work offset and G92 offset, degrees (LinuxCNC's parameters, not scaled by
// the machine units: they are degrees).
double Interpreter::rot_offset_deg() const {
  const int i = opt_.rotary_axis == 'a' ? 3 : 4;
  const auto at = [&](int n) { return params_[static_cast<std::size_t>(n)]; };
  const double g5x = at(5201 + 20 * coord_sys_ + i);
  const double g92 = at(5210) != 0.0 ? at(5211 + i) : 0.0;
  return g5x + g92;
}

double Interpreter::rotary_target_deg(const Block& b, bool g53) const {
  const char r = opt_.rotary_axis;
  const double v = b.v(r);
  if (!std::isfinite(v) || std::abs(v) > kMaxRotaryDeg) {
    fail(upper(r) + text::sig(v) + " is beyond ±" + text::sig(kMaxRotaryDeg) +
         " degrees; check the number");
  }
  if (g53) return v;
  if (incremental_) return rot_deg_ + v;
  return v + rot_offset_deg();
}

// The rotary word on a code other than G0/G1: refused with G10 and G92 (they would set an
// offset of the rotary axis) and G28/G30 (the return would turn it with X, Y, Z); on an arc or
// a canned cycle refused where it would turn the axis. Other codes (G4, G28.1 …) leave it to
// the line's motion.
void Interpreter::refuse_rotary_with(const Block& b, int code) {
  if (!rotary_word(b)) return;
  const char r = opt_.rotary_axis;
  const std::string word = upper(r) + text::sig(b.v(r));
  if (code == 100 || code == 920) {
    fail(word + " with " + g_name(code) +
         ": setting an offset of the rotary axis from the program is not supported; set it in "
         "the parameter file, or remove the word");
  }
  const bool home = code == 280 || code == 300;
  const bool moves = code == 20 || code == 30 || (code >= 730 && code <= 890);
  if (home || (moves && rotary_target_deg(b, false) != rot_deg_)) {
    fail(word + " with " + g_name(code) +
         ": ncd indexes the rotary axis between cuts, never during another motion; move " +
         upper(r) + " with G0 or G1 on a line of its own");
  }
}

// G28/G30 without axis words return every axis, the rotary one too (LinuxCNC): refused where
// that would turn it (its stored position, parameter base + 3 for A, + 4 for B, is elsewhere).
void Interpreter::check_rotary_home(int base) const {
  if (opt_.rotary_axis == 0) return;
  const int i = opt_.rotary_axis == 'a' ? 3 : 4;
  const double stored = params_[static_cast<std::size_t>(base + i)];
  if (stored == rot_deg_) return;
  const std::string g = base == 5161 ? "G28" : "G30";
  fail(g + " without axis words returns every axis, and would turn " + upper(opt_.rotary_axis) +
       " from " + text::sig(rot_deg_) + " to its stored " + text::sig(stored) +
       " degrees (parameter " + std::to_string(base + i) + ") with X, Y, Z; name the axes (" + g +
       " Z0), and index " + upper(opt_.rotary_axis) + " with G0 on a line of its own");
}

// A G0 or G1 with the rotary word: true when the part turns (the index is emitted, X, Y, Z
// stand still); false when the axis stays where it is (the line moves X, Y, Z as usual).
bool Interpreter::index_rotary(const Block& b, int code, bool g53, const Vec3& xyz_target) {
  if (!rotary_word(b)) return false;
  const char r = opt_.rotary_axis;
  const std::string word = upper(r) + text::sig(b.v(r));
  if (incremental_ && !g53 && !rot_known_) {
    fail("incremental " + word + " (G91) before any absolute " + upper(r) +
         ": where the rotary table stands is not known to ncd; give an absolute " + upper(r) +
         " first (G90 G0 " + upper(r) + "0)");
  }
  const double to = rotary_target_deg(b, g53);
  if (!incremental_ || g53) rot_known_ = true;
  if (to == rot_deg_) return false;
  if (b.has_xyz_or_polar()) {
    const Vec3 base = from();
    for (int a = 0; a < 3; ++a) {
      const bool given = b.has(static_cast<char>('x' + a)) || (a < 2 && b.has_polar());
      const double tol = 1e-9 * std::max(1.0, std::abs(base[a]));
      if (given &&
          (!known_[static_cast<std::size_t>(a)] || std::abs(xyz_target[a] - base[a]) > tol)) {
        fail(word +
             " with X, Y or Z motion on the same line: ncd indexes the rotary axis between "
             "cuts (simultaneous 4-axis motion is not supported); move " +
             upper(r) + " on a line of its own");
      }
    }
  }
  if (comp_.on()) {
    fail(word +
         " with cutter radius compensation on: the part cannot turn under a compensated "
         "path; turn compensation off with G40 first");
  }
  RotaryIndexMove ix;
  ix.axis = r;
  ix.from_deg = rot_deg_;
  ix.to_deg = to;
  ix.rapid = code == 0;
  if (!ix.rapid) {
    // Per minute: F is degrees per minute for a rotary-only move (LinuxCNC). Inverse time: the
    // move takes 1/F minutes.
    ix.feed_deg_per_min =
        feed_mode_ == FeedMode::inverse_time ? feed_ * std::abs(to - rot_deg_) : feed_;
  }
  emit(ix);
  rot_deg_ = to;
  return true;
}

}  // namespace ncd::toolpath::ngc

// grbl 1.1h's verdict on a line (check_grbl_line, dialect.hpp).
//
// The grbl model follows grbl 1.1h's own code path for a received line, without copying it:
//  1. protocol.c keeps a line's characters except those ≤ ' ' (spaces, control characters),
//     `/` (block delete, ignored), `(…)` and `;…` comments; lower case is raised; a line that
//     would keep more than 79 characters (LINE_BUFFER_SIZE 80) is answered error:11. An empty
//     kept line is answered ok.
//  2. gcode.c step 2 reads words: a letter A–Z (else error:1) and a number read as read_float
//     does (sign, digits, one point, at most 8 significant digits; no digit: error:2; a second
//     point ends the number and is then not a letter: error:1). G and M numbers are split into
//     an 8-bit integer part and a hundredths mantissa; the G codes G0 G1 G2 G3 G4 G10 G17–G19
//     G20 G21 G28 G28.1 G30 G30.1 G38.2–G38.5 G40 G43.1 G49 G53 G54–G59 G61 G80 G90 G91 G91.1
//     G92 G92.1 G93 G94 and the M codes M0 M1 M2 M30 M3 M4 M5 M8 M9 are known (M7 and M56 only
//     in non-default builds); others error:20, a fraction where none is known error:23, two of
//     one modal group error:21, two axis commands error:24. The value letters are F I J K L N
//     P R S T X Y Z (others error:20); T above 255 error:38, a repeat error:25, a negative F N
//     P S T error:4.
//  3. gcode.c step 3, in its order: N above 10 000 000 (27), F undefined in G93 (22), G4
//     without P (28), G43.1 with other than Z (37), G10 without axis words (26), without P and
//     L (28), with P above 6 (29), with L other than 2 or 20 or L2 with R (20), G92 without axis
//     words (26), G53 outside G0/G1 (30), axis words in G80 (31), a feed motion without a feed
//     (22), arcs without axis words (26), none in the plane (32), R arcs to the start point
//     (33) or too short a radius (34), IJK arcs without an offset in the plane (35) or whose
//     end is off the circle by more than 0.005 mm and 0.1 % (or 0.5 mm) (33), probes without
//     axis words (26) or to the start point (33), and finally words left unused (36).
//  4. The accepted block updates the state as step 4 does (units, distance mode, offsets,
//     G28.1/G30.1, G92, program end resetting G1 G17 G90 G94 G54 M5 M9) and moves the position.
// The state is what a run of the program on a freshly reset grbl would have, so a program check
// and the simulated controller, fed the same lines, give the same verdict on every line.
// Steps 1 and 4 are here, step 2 in grbl_read.cpp, step 3 in grbl_check.cpp.
#include "gcode/dialect/dialect.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "gcode/dialect/grbl_detail.hpp"
#include "gcode/lexer.hpp"

namespace ncd::comms {
namespace grbl_detail {

// Step 1: the kept characters of the line up to its first CR or LF, comments out (the lexer,
// gcode/lexer.hpp, says what a comment is).
Kept grbl_keep(std::string_view raw) {
  Kept k;
  const std::string_view line = raw.substr(0, raw.find_first_of("\r\n"));
  gcode::Lexer lex(line);
  for (gcode::Token t = lex.next(); t.kind != gcode::Token::Kind::End; t = lex.next()) {
    if (t.kind == gcode::Token::Kind::Comment) continue;
    for (std::size_t i = t.at; i < t.end; ++i) {
      const auto c = static_cast<unsigned char>(line[i]);
      if (c <= ' ' || c == '/') continue;
      if (static_cast<int>(k.text.size()) >= kGrblKeptChars) {
        k.overflow_column = static_cast<int>(i) + 1;
        return k;
      }
      k.text += static_cast<char>(std::toupper(c));
      k.column.push_back(static_cast<int>(i) + 1);
    }
  }
  return k;
}

// Step 4: the block takes effect; returns the state after it.
GrblState apply_block(const GrblState& state, const Words& w, const Settled& z, GrblBlock& b) {
  GrblState next = w.blk;
  next.feed = w.f;
  next.spindle_rpm = w.sv;
  if (w.word_col[kS] > 0) b.spindle_rpm = w.sv;
  if (w.word_col[kN] > 0) b.n = static_cast<long>(w.n);
  if (w.word_col[kT] > 0) {
    next.tool = static_cast<int>(w.t);
    b.tool = next.tool;
  }
  if (b.spindle) next.spindle = *b.spindle;
  if (b.flood) next.flood = *b.flood;
  if (w.non_modal == 40) b.dwell_s = w.p;
  if (z.set_tlo) next.tool_length_mm = z.tlo;
  if (z.set_cs) {
    next.coord_system[static_cast<std::size_t>(z.set_cs->first)] = z.set_cs->second;
  }
  if (w.non_modal == 281) next.g28 = state.position;
  if (w.non_modal == 301) next.g30 = state.position;
  if (z.set_g92) next.g92 = *z.set_g92;
  if (w.non_modal == 921) next.g92 = {0.0, 0.0, 0.0};
  // The motion.
  const std::array<double, 3> from = state.position;
  if (w.non_modal == 280 || w.non_modal == 300) {
    b.motion = w.non_modal;
    b.rapid = true;
    b.to = z.home;
    b.path_mm =
        w.axis_words ? dist3(from, z.target) + dist3(z.target, z.home) : dist3(from, z.home);
    next.position = z.home;
  } else if (w.axis_command == kMotion) {
    b.motion = w.blk.motion;
    b.rapid = w.blk.motion == 0;
    b.to = z.target;
    if (w.blk.motion == 20 || w.blk.motion == 30) {
      const auto ua0 = static_cast<std::size_t>(z.a0), ua1 = static_cast<std::size_t>(z.a1);
      const auto ul = static_cast<std::size_t>(z.alin);
      const double sx = from[ua0] - z.center[ua0], sy = from[ua1] - z.center[ua1];
      const double ex = z.target[ua0] - z.center[ua0], ey = z.target[ua1] - z.center[ua1];
      double angle = std::atan2(sx * ey - sy * ex, sx * ex + sy * ey);  // CCW positive
      if (w.blk.motion == 20) {
        if (angle >= -1e-9) angle -= 2.0 * std::numbers::pi;
      } else if (angle <= 1e-9) {
        angle += 2.0 * std::numbers::pi;
      }
      b.path_mm = std::hypot(std::fabs(angle) * std::hypot(sx, sy), z.target[ul] - from[ul]);
      // An R arc whose end differs from its start only along the linear axis divides by a
      // zero chord; grbl's float arithmetic is then undefined. Time it as a straight move.
      if (!std::isfinite(b.path_mm)) b.path_mm = dist3(from, z.target);
    } else {
      b.path_mm = dist3(from, z.target);
    }
    if (!b.rapid) {
      if (w.blk.inverse_time) {
        b.inverse_time_min = 1.0 / w.f;
      } else {
        b.feed_mm_per_min = w.f;
      }
    }
    next.position = z.target;
  }
  if (b.program_end) {
    next.motion = 10;
    next.plane = 0;
    next.incremental = false;
    next.inverse_time = false;
    next.coord_select = 0;
    next.spindle = 5;
    next.flood = false;
  }
  return next;
}

}  // namespace grbl_detail

using namespace grbl_detail;

std::optional<Violation> check_grbl_line(std::string_view line, GrblState& state, GrblBlock* out) {
  const Kept k = grbl_keep(line);
  if (k.overflow_column != 0) {
    return violation(k.overflow_column,
                     std::string(1, line[static_cast<std::size_t>(k.overflow_column - 1)]),
                     kGrblOverflow,
                     "the line keeps more than grbl's 79 characters (spaces and comments not "
                     "counted; LINE_BUFFER_SIZE 80)",
                     "split the block, or drop redundant words and digits");
  }
  GrblBlock b;
  if (k.text.empty()) {
    if (out) *out = b;
    return std::nullopt;
  }
  if (k.text[0] == '$') {
    return violation(k.column[0], "$", 3, "a grbl system command ($…) is not a program block",
                     "send settings and $-commands outside the program");
  }
  b.empty = false;

  Words w;
  w.blk = state;
  std::optional<Violation> v = read_words(k, w, b);
  Settled z;
  if (!v) v = check_modes(k, state, w, z);
  if (!v) v = check_offsets(k, state, w, z);
  if (!v) v = check_motion(k, state, w, z);
  if (!v) v = check_unused(w);
  if (v) return v;
  state = apply_block(state, w, z, b);
  if (out) *out = b;
  return std::nullopt;
}

}  // namespace ncd::comms

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
#include "gcode/dialect/dialect.hpp"

#include <algorithm>
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

#include "gcode/dialect/dialect_detail.hpp"
#include "gcode/lexer.hpp"

namespace ncd::comms {

using dialect_detail::kGrblKeptChars;
using dialect_detail::violation;

namespace {

constexpr double kMmPerInch = 25.4;
constexpr double kGrblMaxLineNumber = 10000000.0;
constexpr double kGrblMaxTool = 255.0;

// grbl's read_float: [+-] digits with at most one point, at most 8 significant digits kept
// (further integer digits scale, further fraction digits are dropped). Advances i past the
// number; false without a digit.
bool grbl_read_float(std::string_view s, std::size_t& i, double& value) {
  std::size_t j = i;
  bool negative = false;
  if (j < s.size() && (s[j] == '-' || s[j] == '+')) negative = s[j++] == '-';
  std::uint32_t intval = 0;
  int exp = 0, ndigit = 0;
  bool decimal = false;
  for (; j < s.size(); ++j) {
    const char c = s[j];
    if (c >= '0' && c <= '9') {
      ++ndigit;
      if (ndigit <= 8) {
        if (decimal) --exp;
        intval = intval * 10U + static_cast<std::uint32_t>(c - '0');
      } else if (!decimal) {
        ++exp;
      }
    } else if (c == '.' && !decimal) {
      decimal = true;
    } else {
      break;
    }
  }
  if (ndigit == 0) return false;
  const double v = static_cast<double>(intval) * std::pow(10.0, exp);
  value = negative ? -v : v;
  i = j;
  return true;
}

struct Kept {
  std::string text;         // the characters grbl keeps, upper case
  std::vector<int> column;  // their 1-based columns in the raw line
  int overflow_column = 0;  // the first character beyond 79, 0 if none
};

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

int bit(int b) {
  return 1 << b;
}

// Modal groups (word_bit of gcode.c) and value words.
enum Group { kG0, kG1, kG2, kG3, kG4, kG5, kG6, kG7, kG8, kG12, kG13, kM4, kM7, kM8 };
enum Word { kF, kI, kJ, kK, kL, kN, kP, kR, kS, kT, kX, kY, kZ };
enum AxisCommand { kNone, kNonModal, kMotion, kToolLength };

double dist3(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

}  // namespace

// ---- grbl: gcode.c's four steps, one function each (the model at the top of this file) ----

namespace {

// The words of a block as step 2 reads them: gc_block before its checks.
struct Words {
  int command_words = 0, value_words = 0, axis_words = 0, ijk_words = 0;
  AxisCommand axis_command = kNone;
  GrblState blk;       // gc_block.modal, copied from the state
  int non_modal = -1;  // G code × 10: 40, 100, 280, 281, 300, 301, 530, 920, 921
  std::array<double, 3> xyz{}, ijk{};
  double f = 0.0, l = 0.0, n = 0.0, p = 0.0, r = 0.0, sv = 0.0, t = 0.0;
  int word_col[13] = {};
  int motion_col = 0;
  bool g49 = false;
  int non_modal_col = 0;
};

// What step 3 settles for step 4: the plane's axes, the tool length, offsets, the target.
struct Settled {
  int a0 = 0, a1 = 1, alin = 2;  // the plane's axes and the linear one
  bool set_tlo = false;
  double tlo = 0.0;
  std::array<double, 3> home{}, target{}, center{};
  std::optional<std::pair<int, std::array<double, 3>>> set_cs;
  std::optional<std::array<double, 3>> set_g92;
};

Violation unsupported(int col, const std::string& word, const std::string& why) {
  return violation(col, word, kGrblUnsupported, why,
                   "grbl 1.1 knows G0 G1 G2 G3 G4 G10 G17-G19 G20 G21 G28 G30 G38.2-G38.5 "
                   "G40 G43.1 G49 G53 G54-G59 G61 G80 G90 G91 G92 G93 G94, M0 M1 M2 M3 M4 "
                   "M5 M8 M9 M30 and the words F I J K L N P R S T X Y Z: use the ncd "
                   "writer's grbl dialect");
}

// A G word (step 2): its modal group, the motion or non-modal command, the axis command.
// Longer than the house's 100 lines on purpose: it is gcode.c's table of G codes in full, one
// case per code as grbl has it, so the two can be read side by side.
std::optional<Violation> read_g(const std::string& word, int col, int int_value, int mantissa,
                                Words& w) {
  int group = 0;
  switch (int_value) {
    case 10:
    case 28:
    case 30:
    case 92:
      if (mantissa == 0) {
        if (w.axis_command != kNone) {
          return violation(col, word, kGrblAxisConflict,
                           "two commands that use the axis words in one block",
                           "put each in its own block");
        }
        w.axis_command = kNonModal;
      }
      [[fallthrough]];
    case 4:
    case 53:
      group = kG0;
      w.non_modal = int_value * 10;
      w.non_modal_col = col;
      if (int_value == 28 || int_value == 30 || int_value == 92) {
        if (mantissa != 0 && mantissa != 10)
          return unsupported(col, word, word + " is not a grbl code");
        w.non_modal += mantissa / 10;
        mantissa = 0;
      }
      break;
    case 0:
    case 1:
    case 2:
    case 3:
    case 38:
      if (w.axis_command != kNone) {
        return violation(col, word, kGrblAxisConflict,
                         "two commands that use the axis words in one block",
                         "put each in its own block");
      }
      w.axis_command = kMotion;
      [[fallthrough]];
    case 80:
      group = kG1;
      w.blk.motion = int_value * 10;
      w.motion_col = col;
      if (int_value == 38) {
        if (mantissa != 20 && mantissa != 30 && mantissa != 40 && mantissa != 50) {
          return unsupported(col, word, word + " is not a probe cycle grbl knows (G38.2 to G38.5)");
        }
        w.blk.motion = 380 + mantissa / 10;
        mantissa = 0;
      }
      break;
    case 17:
    case 18:
    case 19:
      group = kG2;
      w.blk.plane = int_value - 17;
      break;
    case 90:
    case 91:
      if (mantissa == 0) {
        group = kG3;
        w.blk.incremental = int_value == 91;
      } else {
        group = kG4;
        if (mantissa != 10 || int_value == 90) {
          return unsupported(col, word, word + " is not supported (grbl has only G91.1)");
        }
        mantissa = 0;
      }
      break;
    case 93:
    case 94:
      group = kG5;
      w.blk.inverse_time = int_value == 93;
      break;
    case 20:
    case 21:
      group = kG6;
      w.blk.inches = int_value == 20;
      break;
    case 40:
      group = kG7;
      break;
    case 43:
    case 49:
      group = kG8;
      if (w.axis_command != kNone) {
        return violation(col, word, kGrblAxisConflict,
                         "a tool length command with another axis command in one block",
                         "put each in its own block");
      }
      w.axis_command = kToolLength;
      w.g49 = int_value == 49;
      if (int_value == 43 && mantissa != 10) {
        return unsupported(col, word, word + " is not supported: grbl has only G43.1 (dynamic, Z)");
      }
      mantissa = 0;
      break;
    case 54:
    case 55:
    case 56:
    case 57:
    case 58:
    case 59:
      group = kG12;
      w.blk.coord_select = int_value - 54;
      break;
    case 61:
      group = kG13;
      if (mantissa != 0)
        return unsupported(col, word, word + " is not supported (grbl has only G61)");
      break;
    default:
      return unsupported(col, word, word + " is not a G code grbl 1.1 knows");
  }
  if (mantissa > 0) {
    return violation(col, word, kGrblNotInteger, word + " has a fraction grbl does not know",
                     "use the integer code");
  }
  if (w.command_words & bit(group)) {
    return violation(col, word, kGrblModalGroup,
                     word + " is the second code of its modal group in the block",
                     "give one code per modal group a block");
  }
  w.command_words |= bit(group);
  return std::nullopt;
}

// An M word (step 2).
std::optional<Violation> read_m(const std::string& word, int col, int int_value, int mantissa,
                                Words& w, GrblBlock& b) {
  if (mantissa > 0) {
    return violation(col, word, kGrblNotInteger, word + " has a fraction", "M codes are integers");
  }
  int group = 0;
  switch (int_value) {
    case 0:
    case 1:
    case 2:
    case 30:
      group = kM4;
      b.pause = int_value == 0;
      b.optional_stop = int_value == 1;
      b.program_end = int_value == 2 || int_value == 30;
      break;
    case 3:
    case 4:
    case 5:
      group = kM7;
      b.spindle = int_value;
      break;
    case 8:
    case 9:
      group = kM8;
      b.flood = int_value == 8;
      break;
    default:
      return unsupported(
          col, word,
          word + (int_value == 6 ? " (tool change) is not supported by grbl 1.1"
                                 : " is not an M code grbl 1.1 knows (default build)"));
  }
  if (w.command_words & bit(group)) {
    return violation(col, word, kGrblModalGroup,
                     word + " is the second code of its modal group in the block",
                     "give one code per modal group a block");
  }
  w.command_words |= bit(group);
  return std::nullopt;
}

// A value word F I J K L N P R S T X Y Z (step 2).
std::optional<Violation> read_value(char letter, double value, int int_value, int col,
                                    const std::string& word, Words& w) {
  int word_id = 0;
  switch (letter) {
    case 'F':
      word_id = kF, w.f = value;
      break;
    case 'I':
      word_id = kI, w.ijk[0] = value, w.ijk_words |= 1;
      break;
    case 'J':
      word_id = kJ, w.ijk[1] = value, w.ijk_words |= 2;
      break;
    case 'K':
      word_id = kK, w.ijk[2] = value, w.ijk_words |= 4;
      break;
    case 'L':
      word_id = kL, w.l = int_value;
      break;
    case 'N':
      word_id = kN, w.n = std::trunc(value);
      break;
    case 'P':
      word_id = kP, w.p = value;
      break;
    case 'R':
      word_id = kR, w.r = value;
      break;
    case 'S':
      word_id = kS, w.sv = value;
      break;
    case 'T':
      word_id = kT;
      if (value > kGrblMaxTool) {
        return violation(col, word, kGrblMaxValue, "tool number above grbl's 255",
                         "use T0 to T255");
      }
      w.t = int_value;
      break;
    case 'X':
      word_id = kX, w.xyz[0] = value, w.axis_words |= 1;
      break;
    case 'Y':
      word_id = kY, w.xyz[1] = value, w.axis_words |= 2;
      break;
    case 'Z':
      word_id = kZ, w.xyz[2] = value, w.axis_words |= 4;
      break;
    default:
      return unsupported(col, word,
                         std::string("the word ") + letter + " is not one grbl 1.1 knows");
  }
  if (w.value_words & bit(word_id)) {
    return violation(col, word, kGrblRepeated,
                     std::string("the word ") + letter + " appears twice in the block",
                     "give each word once");
  }
  if ((bit(word_id) & (bit(kF) | bit(kN) | bit(kP) | bit(kT) | bit(kS))) && value < 0.0) {
    return violation(col, word, kGrblNegative, word + " is negative",
                     "F, N, P, S and T take values of 0 or more");
  }
  w.value_words |= bit(word_id);
  w.word_col[word_id] = col;
  return std::nullopt;
}

// Step 2: the words of the kept line, in order.
std::optional<Violation> read_words(const Kept& k, Words& w, GrblBlock& b) {
  const std::string& s = k.text;
  for (std::size_t i = 0; i < s.size();) {
    const char letter = s[i];
    const int col = k.column[i];
    if (letter < 'A' || letter > 'Z') {
      return violation(col, std::string(1, letter), kGrblExpectedLetter,
                       "'" + std::string(1, letter) + "' is not a word letter",
                       "write words as a letter and a number, e.g. G1 X10.5 (no #, [ ], = or "
                       "a number with two points)");
    }
    std::size_t j = i + 1;
    double value = 0.0;
    if (!grbl_read_float(s, j, value)) {
      return violation(col, s.substr(i, std::min<std::size_t>(j + 1, s.size()) - i), kGrblBadNumber,
                       std::string("the word ") + letter + " has no number",
                       "give the letter its number, e.g. " + std::string(1, letter) + "0");
    }
    const std::string word = s.substr(i, j - i);
    i = j;
    // grbl keeps an 8-bit integer part and the hundredths (uint16) of the fraction.
    const double tr = std::trunc(value);
    const int int_value = static_cast<int>(
        static_cast<std::uint8_t>(static_cast<long long>(std::fmod(tr, 256.0) + 256.0) % 256));
    int mantissa = static_cast<int>(static_cast<std::uint16_t>(
        static_cast<long long>(std::llround(100.0 * (value - int_value))) & 0xFFFF));
    std::optional<Violation> v;
    if (letter == 'G') {
      v = read_g(word, col, int_value, mantissa, w);
    } else if (letter == 'M') {
      v = read_m(word, col, int_value, mantissa, w, b);
    } else {
      v = read_value(letter, value, int_value, col, word, w);
    }
    if (v) return v;
  }
  return std::nullopt;
}

// The word (letter and number as kept) that starts at a column.
std::string word_at(const Kept& k, int col) {
  const std::string& s = k.text;
  const auto it = std::find(k.column.begin(), k.column.end(), col);
  std::size_t i = static_cast<std::size_t>(it - k.column.begin());
  std::size_t j = i + 1;
  double ignored = 0.0;
  if (i < s.size()) grbl_read_float(s, j, ignored);
  return i < s.size() ? s.substr(i, j - i) : std::string();
}

// A step 3 violation at the word concerned, else at column 1.
Violation fail_at(const Kept& k, int code, int col, std::string why, std::string way_out) {
  if (col <= 0) col = k.column[0];
  return violation(col, word_at(k, col), code, std::move(why), std::move(way_out));
}

// Step 3, first part: N, F and S, G4, the plane, inches, G43.1.
std::optional<Violation> check_modes(const Kept& k, const GrblState& state, Words& w, Settled& z) {
  if (w.axis_words && w.axis_command == kNone) w.axis_command = kMotion;
  if ((w.value_words & bit(kN)) && w.n > kGrblMaxLineNumber) {
    return fail_at(k, kGrblLineNumber, w.word_col[kN], "N is above grbl's 10000000",
                   "number the blocks from 0 to 10000000, or leave N out");
  }
  if (w.blk.inverse_time) {
    if (w.axis_command == kMotion && w.blk.motion != 800 && w.blk.motion != 0 &&
        !(w.value_words & bit(kF))) {
      return fail_at(k, kGrblUndefinedFeed, w.motion_col, "a G93 (inverse time) motion without F",
                     "give F on every G93 motion");
    }
  } else if (!state.inverse_time) {
    if (w.value_words & bit(kF)) {
      if (w.blk.inches) w.f *= kMmPerInch;
    } else {
      w.f = state.feed;
    }
  }
  if (!(w.value_words & bit(kS))) w.sv = state.spindle_rpm;
  if (w.non_modal == 40) {
    if (!(w.value_words & bit(kP))) {
      return fail_at(k, kGrblValueMissing, w.non_modal_col, "G4 without P, the dwell in seconds",
                     "write G4 P0.5");
    }
    w.value_words &= ~bit(kP);
  }
  z.a0 = w.blk.plane == 0 ? 0 : w.blk.plane == 1 ? 2 : 1;
  z.a1 = w.blk.plane == 0 ? 1 : w.blk.plane == 1 ? 0 : 2;
  z.alin = w.blk.plane == 0 ? 2 : w.blk.plane == 1 ? 1 : 0;
  if (w.blk.inches) {
    for (int q = 0; q < 3; ++q) {
      if (w.axis_words & (1 << q)) w.xyz[static_cast<std::size_t>(q)] *= kMmPerInch;
    }
  }
  z.tlo = state.tool_length_mm;
  if (w.axis_command == kToolLength) {
    if (!w.g49 && w.axis_words != 4) {
      return fail_at(k, kGrblG43Axis, 0, "G43.1 needs a Z word and no other axis word",
                     "write G43.1 Z<length>");
    }
    z.set_tlo = true;
    z.tlo = w.g49 ? 0.0 : w.xyz[2];
  }
  return std::nullopt;
}

// Step 3: G10, G92, the target in machine coordinates, G28/G30, G53.
std::optional<Violation> check_offsets(const Kept& k, const GrblState& state, Words& w,
                                       Settled& z) {
  std::array<double, 3> block_cs = state.coord_system[static_cast<std::size_t>(w.blk.coord_select)];
  z.target = state.position;
  if (w.non_modal == 100) {
    if (!w.axis_words)
      return fail_at(k, kGrblNoAxisWords, w.non_modal_col, "G10 without axis words",
                     "give X, Y or Z");
    if (!(w.value_words & (bit(kP) | bit(kL)))) {
      return fail_at(k, kGrblValueMissing, w.non_modal_col, "G10 without P and L",
                     "write G10 L2 P1 X… or G10 L20");
    }
    const double pv = std::trunc(w.p);
    if (pv > 6.0) {
      return fail_at(k, kGrblCoordSystem, w.word_col[kP], "G10 P above 6 (grbl has G54 to G59)",
                     "use P0 to P6");
    }
    if (w.l != 20.0) {
      if (w.l != 2.0 || (w.value_words & bit(kR))) {
        return fail_at(k, kGrblUnsupported, w.word_col[kL],
                       w.l == 2.0 ? "G10 L2 with R (rotation) is not supported"
                                  : "G10 with an L other than 2 or 20",
                       "use G10 L2 or G10 L20 without R");
      }
    }
    w.value_words &= ~(bit(kL) | bit(kP));
    const int idx = pv > 0.0 ? static_cast<int>(pv) - 1 : w.blk.coord_select;
    std::array<double, 3> data = state.coord_system[static_cast<std::size_t>(idx)];
    for (std::size_t q = 0; q < 3; ++q) {
      if (!(w.axis_words & (1 << q))) continue;
      data[q] = w.l == 20.0 ? state.position[q] - state.g92[q] - w.xyz[q] -
                                  (q == 2 ? state.tool_length_mm : 0.0)
                            : w.xyz[q];
    }
    z.set_cs = std::make_pair(idx, data);
  } else if (w.non_modal == 920) {
    if (!w.axis_words)
      return fail_at(k, kGrblNoAxisWords, w.non_modal_col, "G92 without axis words",
                     "give X, Y or Z");
    std::array<double, 3> off{};
    for (std::size_t q = 0; q < 3; ++q) {
      off[q] = (w.axis_words & (1 << q)) ? state.position[q] - block_cs[q] - w.xyz[q] -
                                               (q == 2 ? state.tool_length_mm : 0.0)
                                         : state.g92[q];
    }
    z.set_g92 = off;
  } else {
    if (w.axis_command != kToolLength && w.axis_words) {
      for (std::size_t q = 0; q < 3; ++q) {
        if (!(w.axis_words & (1 << q))) {
          z.target[q] = state.position[q];
        } else if (w.non_modal == 530) {
          z.target[q] = w.xyz[q];
        } else if (!w.blk.incremental) {
          z.target[q] =
              w.xyz[q] + block_cs[q] + state.g92[q] + (q == 2 ? state.tool_length_mm : 0.0);
        } else {
          z.target[q] = w.xyz[q] + state.position[q];
        }
      }
    }
    if (w.non_modal == 280 || w.non_modal == 300) {
      z.home = w.non_modal == 280 ? state.g28 : state.g30;
      if (!w.axis_words) w.axis_command = kNone;
    } else if (w.non_modal == 530) {
      if (w.blk.motion != 0 && w.blk.motion != 10) {
        return fail_at(k, kGrblG53Motion, w.non_modal_col, "G53 outside G0 or G1",
                       "use G53 with G0 or G1");
      }
    }
  }
  return std::nullopt;
}

// Step 3: the motion: G80, a feed, arcs (R or I J K, their end on the circle), probes.
std::optional<Violation> check_motion(const Kept& k, const GrblState& state, Words& w, Settled& z) {
  if (w.blk.motion == 800) {
    if (w.axis_words) {
      return fail_at(k, kGrblAxisWordsExist, 0, "axis words with G80 (no motion mode) active",
                     "give G0 or G1 before the axis words");
    }
  } else if (w.axis_command == kMotion) {
    if (w.blk.motion == 0) {
      if (!w.axis_words) w.axis_command = kNone;
    } else {
      if (w.f == 0.0) {
        return fail_at(k, kGrblUndefinedFeed, w.motion_col, "a feed motion without a feed rate",
                       "give F (mm/min) on or before the first G1, G2 or G3");
      }
      if (w.blk.motion == 10) {
        if (!w.axis_words) w.axis_command = kNone;
      } else if (w.blk.motion == 20 || w.blk.motion == 30) {
        if (!w.axis_words)
          return fail_at(k, kGrblNoAxisWords, w.motion_col, "an arc without axis words",
                         "give its end point");
        if (!(w.axis_words & ((1 << z.a0) | (1 << z.a1)))) {
          return fail_at(k, kGrblNoAxisInPlane, w.motion_col,
                         "an arc without an axis word in its plane",
                         "give the end point in the plane (G17: X Y)");
        }
        const auto ua0 = static_cast<std::size_t>(z.a0), ua1 = static_cast<std::size_t>(z.a1);
        const double x = z.target[ua0] - state.position[ua0];
        const double y = z.target[ua1] - state.position[ua1];
        double ci = 0.0, cj = 0.0;
        if (w.value_words & bit(kR)) {
          w.value_words &= ~bit(kR);
          if (z.target == state.position) {
            return fail_at(k, kGrblInvalidTarget, w.word_col[kR], "an R arc ending where it starts",
                           "program a full circle with I J K");
          }
          double rr = w.blk.inches ? w.r * kMmPerInch : w.r;
          double h = 4.0 * rr * rr - x * x - y * y;
          if (h < 0.0) {
            return fail_at(k, kGrblArcRadius, w.word_col[kR],
                           "the arc's radius is shorter than half its chord",
                           "check R against the end point");
          }
          h = -std::sqrt(h) / std::hypot(x, y);
          if (w.blk.motion == 30) h = -h;
          if (rr < 0.0) h = -h;
          ci = 0.5 * (x - y * h);
          cj = 0.5 * (y + x * h);
        } else {
          if (!(w.ijk_words & ((1 << z.a0) | (1 << z.a1)))) {
            return fail_at(k, kGrblNoOffsetsInPlane, w.motion_col,
                           "an arc without a centre offset in its plane",
                           "give I J (G17), I K (G18) or J K (G19), or R");
          }
          w.value_words &= ~(bit(kI) | bit(kJ) | bit(kK));
          if (w.blk.inches) {
            for (auto& v : w.ijk) v *= kMmPerInch;
          }
          ci = w.ijk[ua0];
          cj = w.ijk[ua1];
          const double target_r = std::hypot(x - ci, y - cj);
          const double radius = std::hypot(ci, cj);
          const double dr = std::fabs(target_r - radius);
          if (dr > 0.005 && (dr > 0.5 || dr > 0.001 * radius)) {
            return fail_at(
                k, kGrblInvalidTarget, w.motion_col,
                "the arc's end is not on its circle (off by " + std::to_string(dr) + " mm)",
                "check I J K against the end point");
          }
        }
        z.center = state.position;
        z.center[ua0] += ci;
        z.center[ua1] += cj;
      } else {  // probes
        if (!w.axis_words)
          return fail_at(k, kGrblNoAxisWords, w.motion_col, "a probe without axis words",
                         "give its end point");
        if (z.target == state.position) {
          return fail_at(k, kGrblInvalidTarget, w.motion_col, "a probe to where the tool stands",
                         "give a probe target away from the tool");
        }
      }
    }
  }
  return std::nullopt;
}

// Step 3, last: a word no command of the block used.
std::optional<Violation> check_unused(Words& w) {
  w.value_words &= ~(bit(kN) | bit(kF) | bit(kS) | bit(kT));
  if (w.axis_command != kNone) w.value_words &= ~(bit(kX) | bit(kY) | bit(kZ));
  if (w.value_words) {
    int word_id = 0;
    while (!(w.value_words & bit(word_id))) ++word_id;
    static constexpr char kLetters[] = "FIJKLNPRSTXYZ";
    return violation(
        w.word_col[word_id], std::string(1, kLetters[word_id]), kGrblUnusedWords,
        std::string("the word ") + kLetters[word_id] + " is not used by any command of the block",
        "remove it (grbl takes P only with G4 and G10, R and I J K only with arcs)");
  }
  return std::nullopt;
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

}  // namespace

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

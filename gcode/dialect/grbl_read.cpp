// grbl's step 2 (the model at the top of grbl.cpp): the words of a kept line, read as gcode.c
// reads them: numbers by read_float, G and M codes with their modal groups, value words.
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

#include "gcode/dialect/dialect.hpp"
#include "gcode/dialect/grbl_detail.hpp"

namespace ncd::comms::grbl_detail {

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

namespace {

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

}  // namespace

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

}  // namespace ncd::comms::grbl_detail

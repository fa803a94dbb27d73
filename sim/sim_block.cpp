// The simulated controller's reading of a block (iso/linuxcnc, and grbl without --dialect): its
// words, then what it does (a move, a dwell, spindle, coolant, tool, stops, the end) as a SimBlock.
#include <cctype>
#include <charconv>
#include <cmath>
#include <string>
#include <vector>

#include "core/number_text.hpp"
#include "sim/sim_impl.hpp"

namespace ncd::comms {

namespace {

// Reads a number at text[i] ([+-] digits [. digits] or . digits); advances i. False if none.
bool read_number(std::string_view text, std::size_t& i, double& value) {
  std::size_t j = i;
  bool negative = false;
  if (j < text.size() && (text[j] == '+' || text[j] == '-')) negative = text[j++] == '-';
  const std::size_t start = j;
  bool digits = false;
  while (j < text.size() && std::isdigit(static_cast<unsigned char>(text[j]))) {
    ++j;
    digits = true;
  }
  if (j < text.size() && text[j] == '.') {
    ++j;
    while (j < text.size() && std::isdigit(static_cast<unsigned char>(text[j]))) {
      ++j;
      digits = true;
    }
  }
  if (!digits) return false;
  double v = 0.0;
  const auto r = std::from_chars(text.data() + start, text.data() + j, v);
  if (r.ec != std::errc() || !std::isfinite(v)) return false;
  value = negative ? -v : v;
  i = j;
  return true;
}

}  // namespace

SimParse parse_sim_block(std::string_view text, SimModal& modal, double rapid_mm_per_min) {
  SimParse r;
  const auto fail = [&r](int code, std::string message) {
    r.error = code;
    r.message = std::move(message);
    r.block = SimBlock{};
    return r;
  };
  struct Word {
    char letter;
    double value;
  };
  std::vector<Word> words;
  for (std::size_t i = 0; i < text.size();) {
    const char c = text[i];
    if (c == ' ' || c == '\t') {
      ++i;
    } else if (c == '(') {
      const auto close = text.find(')', i);
      if (close == std::string_view::npos) break;  // an unclosed comment runs to the end
      i = close + 1;
    } else if (c == ';') {
      break;
    } else if (std::isalpha(static_cast<unsigned char>(c))) {
      const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
      ++i;
      while (i < text.size() && (text[i] == ' ' || text[i] == '\t')) ++i;
      double v = 0.0;
      if (!read_number(text, i, v)) {
        return fail(kErrBadNumber, std::string("the word ") + letter + " has no valid number");
      }
      words.push_back({letter, v});
    } else {
      return fail(kErrExpectedLetter, std::string("'") + c + "' is not a word letter");
    }
  }

  SimModal next = modal;
  SimBlock b;
  std::array<std::optional<double>, 3> axis;
  std::optional<double> p_word;
  std::optional<int> motion;  // 0, 1 or 80 given in this block
  bool dwell = false, g64 = false, g43 = false;
  std::optional<double> h_word;
  std::string seen;  // letters that may not repeat
  for (const Word& w : words) {
    const bool integer = w.value == std::floor(w.value);
    if (w.letter != 'G' && w.letter != 'M') {
      if (seen.find(w.letter) != std::string::npos) {
        return fail(kErrRepeatedWord, std::string("the word ") + w.letter + " appears twice");
      }
      seen += w.letter;
    }
    switch (w.letter) {
      case 'N':
        if (!integer) return fail(kErrNotInteger, "N " + text::sig(w.value) + " is not an integer");
        if (w.value < 0.0 || w.value > 99999999.0) {
          return fail(kErrBadLineNumber, "N " + text::sig(w.value) + " is outside 0 … 99999999");
        }
        b.n = static_cast<long>(w.value);
        break;
      case 'G': {
        const long code10 = std::lround(w.value * 10.0);
        if (std::abs(w.value * 10.0 - static_cast<double>(code10)) > 1e-6) {
          return fail(kErrUnsupported, "G" + text::sig(w.value) + " is not a G code");
        }
        if (code10 == 0 || code10 == 10 || code10 == 800) {
          if (motion) return fail(kErrModalGroup, "two motion codes in one block");
          motion = static_cast<int>(code10 / 10);
        } else if (code10 == 40) {
          dwell = true;
          b.dwell = true;
        } else if (code10 == 640) {
          g64 = true;
        } else if (code10 == 430) {
          g43 = true;
        } else if (code10 == 910) {
          return fail(kErrUnsupported,
                      "G91 (incremental) is not supported: send absolute coordinates (G90)");
        } else if (code10 == 200) {
          return fail(kErrUnsupported, "G20 (inch) is not supported: send mm (G21)");
        } else if (code10 == 20 || code10 == 30) {
          return fail(kErrUnsupported, "G2/G3 arcs are not supported: send G1 segments");
        } else if (code10 != 170 && code10 != 210 && code10 != 400 && code10 != 490 &&
                   code10 != 540 && code10 != 610 && code10 != 611 && code10 != 800 &&
                   code10 != 900 && code10 != 940) {
          return fail(kErrUnsupported, "G" + text::sig(w.value) +
                                           " is not supported: use G0 G1 G4, or the setup codes "
                                           "G17 G21 G40 G43 G49 G54 G61 G61.1 G64 G80 G90 G94");
        }
        break;
      }
      case 'M': {
        if (!integer) return fail(kErrNotInteger, "M" + text::sig(w.value) + " is not an integer");
        const int m = static_cast<int>(w.value);
        if (m == 2 || m == 30) {
          b.program_end = true;
        } else if (m == 0) {
          b.pause = true;
        } else if (m == 1) {
          b.optional_stop = true;
        } else if (m == 3 || m == 4 || m == 5) {
          b.spindle = m;
        } else if (m == 6) {
          b.tool_change = true;
        } else if (m == 8 || m == 9) {
          b.coolant = m == 8;
        } else {
          return fail(kErrUnsupported, "M" + std::to_string(m) +
                                           " is not supported: use M0 M1 M2 M3 M4 M5 M6 M8 M9 M30");
        }
        break;
      }
      case 'X':
      case 'Y':
      case 'Z':
        axis[static_cast<std::size_t>(w.letter - 'X')] = w.value;
        break;
      case 'F':
        if (w.value < 0.0) return fail(kErrNegative, "F " + text::sig(w.value) + " is negative");
        next.feed_mm_per_min = w.value;
        break;
      case 'S':
        if (w.value < 0.0) return fail(kErrNegative, "S " + text::sig(w.value) + " is negative");
        b.spindle_rpm = w.value;
        break;
      case 'T':
        if (!integer) return fail(kErrNotInteger, "T " + text::sig(w.value) + " is not an integer");
        if (w.value < 0.0) return fail(kErrNegative, "T " + text::sig(w.value) + " is negative");
        b.tool = static_cast<int>(w.value);
        break;
      case 'P':
        if (w.value < 0.0) return fail(kErrNegative, "P " + text::sig(w.value) + " is negative");
        p_word = w.value;
        break;
      case 'H':
        if (!integer) return fail(kErrNotInteger, "H " + text::sig(w.value) + " is not an integer");
        if (w.value < 0.0) return fail(kErrNegative, "H " + text::sig(w.value) + " is negative");
        h_word = w.value;
        break;
      default:
        return fail(kErrUnsupported, std::string("the word ") + w.letter +
                                         " is not supported: use N G X Y Z F S M T P H");
    }
  }
  // G43 H n: the length of tool n from the controller's table, which this model holds as 0
  // for every tool: the programmed point is the one the blocks drive.
  if (g43 && !h_word) return fail(kErrMissingValue, "G43 needs H, the tool table's entry");
  if (h_word && !g43) return fail(kErrUnsupported, "an H word needs G43 (tool length offset)");
  if (p_word && !dwell && !g64) {
    return fail(kErrUnsupported, "a P word needs G4 (dwell) or G64 (blending tolerance)");
  }
  if (motion) next.motion = *motion;
  if (b.spindle) next.spindle = *b.spindle;
  if (b.program_end) next.spindle = 5;
  const bool has_axis = axis[0] || axis[1] || axis[2];
  if (dwell) {
    if (motion || has_axis) return fail(kErrModalGroup, "G4 with a motion in the same block");
    if (!p_word) return fail(kErrMissingValue, "G4 needs P, the dwell in seconds");
    b.duration_s = *p_word;
  } else if (has_axis) {
    if (next.motion == 80) return fail(kErrUnsupported, "axis words after G80 (no motion mode)");
    for (std::size_t k = 0; k < 3; ++k) b.to[k] = axis[k].value_or(modal.position[k]);
    b.move = true;
    b.g = next.motion;
    b.feed_move = b.g == 1;
    if (b.g == 1) {
      if (next.feed_mm_per_min <= 0.0) {
        return fail(kErrUndefinedFeed, "G1 without a feed: give F in mm/min");
      }
      b.feed_mm_per_min = next.feed_mm_per_min;
    } else {
      b.feed_mm_per_min = rapid_mm_per_min;
    }
    b.duration_s = distance(modal.position, b.to) / (b.feed_mm_per_min / 60.0);
    next.position = b.to;
  }
  modal = next;
  r.block = b;
  return r;
}

}  // namespace ncd::comms

// The simulated controller's reading of a block (iso/linuxcnc, and grbl without --dialect): its
// words, then what it does (a move, a dwell, spindle, coolant, tool, stops, the end) as a SimBlock.
#include <cctype>
#include <charconv>
#include <cmath>
#include <string>
#include <vector>

#include "core/number_text.hpp"
#include "gcode/lexer.hpp"
#include "sim/sim_impl.hpp"

namespace ncd::comms {

namespace {

struct SimWord {
  char letter;  // upper case
  double value;
};

struct SimFailure {
  int code;
  std::string message;
};

// A block's words, read with the project's lexer (gcode/lexer.hpp): a letter, blanks, a number.
// A comment ends nothing but itself; ';' and an unclosed '(' run to the end of the line.
std::optional<SimFailure> sim_words(std::string_view text, std::vector<SimWord>& words) {
  gcode::Lexer lex(text);
  for (gcode::Token t = lex.next(); t.kind != gcode::Token::Kind::End; t = lex.next()) {
    if (t.kind == gcode::Token::Kind::Comment) continue;
    if (t.kind == gcode::Token::Kind::Char) {
      return SimFailure{kErrExpectedLetter,
                        std::string("'") + text[t.at] + "' is not a word letter"};
    }
    const std::optional<double> v = gcode::word_value(text, t);
    if (!v) {
      return SimFailure{kErrBadNumber,
                        std::string("the word ") + t.letter + " has no valid number"};
    }
    words.push_back({t.letter, *v});
  }
  return std::nullopt;
}

// What the words of one block set, before the block is settled.
struct SimRead {
  SimModal next;
  SimBlock b;
  std::array<std::optional<double>, 3> axis;
  std::optional<double> p_word;
  std::optional<int> motion;  // 0, 1 or 80 given in this block
  bool dwell = false, g64 = false, g43 = false;
  std::optional<double> h_word;
  char rotary_letter = 0;  // A or B given
  double rotary_deg = 0.0;
};

std::optional<SimFailure> read_sim_g(const SimWord& w, SimRead& st) {
  switch (w.letter) {
    case 'G': {
      const long code10 = std::lround(w.value * 10.0);
      if (std::abs(w.value * 10.0 - static_cast<double>(code10)) > 1e-6) {
        return SimFailure{kErrUnsupported, "G" + text::sig(w.value) + " is not a G code"};
      }
      if (code10 == 0 || code10 == 10 || code10 == 800) {
        if (st.motion) return SimFailure{kErrModalGroup, "two motion codes in one block"};
        st.motion = static_cast<int>(code10 / 10);
      } else if (code10 == 40) {
        st.dwell = true;
        st.b.dwell = true;
      } else if (code10 == 640) {
        st.g64 = true;
      } else if (code10 == 430) {
        st.g43 = true;
      } else if (code10 == 910) {
        return SimFailure{kErrUnsupported,
                          "G91 (incremental) is not supported: send absolute coordinates (G90)"};
      } else if (code10 == 200) {
        return SimFailure{kErrUnsupported, "G20 (inch) is not supported: send mm (G21)"};
      } else if (code10 == 20 || code10 == 30) {
        return SimFailure{kErrUnsupported, "G2/G3 arcs are not supported: send G1 segments"};
      } else if (code10 != 170 && code10 != 210 && code10 != 400 && code10 != 490 &&
                 code10 != 540 && code10 != 610 && code10 != 611 && code10 != 800 &&
                 code10 != 900 && code10 != 940) {
        return SimFailure{kErrUnsupported,
                          "G" + text::sig(w.value) +
                              " is not supported: use G0 G1 G4, or the setup codes "
                              "G17 G21 G40 G43 G49 G54 G61 G61.1 G64 G80 G90 G94"};
      }
      break;
    }
    default:
      break;
  }
  return std::nullopt;
}

std::optional<SimFailure> read_sim_m(const SimWord& w, bool integer, SimRead& st) {
  switch (w.letter) {
    case 'M': {
      if (!integer)
        return SimFailure{kErrNotInteger, "M" + text::sig(w.value) + " is not an integer"};
      const int m = static_cast<int>(w.value);
      if (m == 2 || m == 30) {
        st.b.program_end = true;
      } else if (m == 0) {
        st.b.pause = true;
      } else if (m == 1) {
        st.b.optional_stop = true;
      } else if (m == 3 || m == 4 || m == 5) {
        st.b.spindle = m;
      } else if (m == 6) {
        st.b.tool_change = true;
      } else if (m == 8 || m == 9) {
        st.b.coolant = m == 8;
      } else {
        return SimFailure{
            kErrUnsupported,
            "M" + std::to_string(m) + " is not supported: use M0 M1 M2 M3 M4 M5 M6 M8 M9 M30"};
      }
      break;
    }
    default:
      break;
  }
  return std::nullopt;
}

std::optional<SimFailure> read_sim_word(const SimWord& w, SimRead& st) {
  const bool integer = w.value == std::floor(w.value);
  switch (w.letter) {
    case 'N':
      if (!integer) {
        return SimFailure{kErrNotInteger, "N " + text::sig(w.value) + " is not an integer"};
      }
      if (w.value < 0.0 || w.value > 99999999.0) {
        return SimFailure{kErrBadLineNumber,
                          "N " + text::sig(w.value) + " is outside 0 … 99999999"};
      }
      st.b.n = static_cast<long>(w.value);
      break;
    case 'G':
      return read_sim_g(w, st);
    case 'M':
      return read_sim_m(w, integer, st);
    case 'X':
    case 'Y':
    case 'Z':
      st.axis[static_cast<std::size_t>(w.letter - 'X')] = w.value;
      break;
    case 'A':
    case 'B':
      if (st.rotary_letter != 0 || (st.next.rotary_axis != 0 && st.next.rotary_axis != w.letter)) {
        return SimFailure{kErrUnsupported, std::string("the word ") + w.letter +
                                               ": this controller has one rotary axis, " +
                                               (st.next.rotary_axis ? st.next.rotary_axis : 'A')};
      }
      st.rotary_letter = w.letter;
      st.rotary_deg = w.value;
      break;
    case 'F':
      if (w.value < 0.0)
        return SimFailure{kErrNegative, "F " + text::sig(w.value) + " is negative"};
      st.next.feed_mm_per_min = w.value;
      break;
    case 'S':
      if (w.value < 0.0)
        return SimFailure{kErrNegative, "S " + text::sig(w.value) + " is negative"};
      st.b.spindle_rpm = w.value;
      break;
    case 'T':
      if (!integer)
        return SimFailure{kErrNotInteger, "T " + text::sig(w.value) + " is not an integer"};
      if (w.value < 0.0)
        return SimFailure{kErrNegative, "T " + text::sig(w.value) + " is negative"};
      st.b.tool = static_cast<int>(w.value);
      break;
    case 'P':
      if (w.value < 0.0)
        return SimFailure{kErrNegative, "P " + text::sig(w.value) + " is negative"};
      st.p_word = w.value;
      break;
    case 'H':
      if (!integer)
        return SimFailure{kErrNotInteger, "H " + text::sig(w.value) + " is not an integer"};
      if (w.value < 0.0)
        return SimFailure{kErrNegative, "H " + text::sig(w.value) + " is negative"};
      st.h_word = w.value;
      break;
    default:
      return SimFailure{kErrUnsupported, std::string("the word ") + w.letter +
                                             " is not supported: use N G X Y Z A B F S M T P H"};
  }
  return std::nullopt;
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
  std::vector<SimWord> words;
  if (auto f = sim_words(text, words)) return fail(f->code, std::move(f->message));
  SimRead st;
  st.next = modal;
  std::string seen;  // letters that may not repeat
  for (const SimWord& w : words) {
    if (w.letter != 'G' && w.letter != 'M') {
      if (seen.find(w.letter) != std::string::npos) {
        return fail(kErrRepeatedWord, std::string("the word ") + w.letter + " appears twice");
      }
      seen += w.letter;
    }
    if (auto f = read_sim_word(w, st)) return fail(f->code, std::move(f->message));
  }
  SimModal& next = st.next;
  SimBlock& b = st.b;
  const auto& axis = st.axis;
  const auto& p_word = st.p_word;
  const auto& motion = st.motion;
  const bool dwell = st.dwell, g64 = st.g64, g43 = st.g43;
  const auto& h_word = st.h_word;
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
  if (st.rotary_letter != 0) {  // an index: the rotary axis alone
    if (dwell || has_axis) {
      return fail(kErrUnsupported, std::string("the word ") + st.rotary_letter +
                                       " with X, Y, Z or G4: this controller indexes its rotary "
                                       "axis in a block of its own");
    }
    if (next.motion == 80) return fail(kErrUnsupported, "axis words after G80 (no motion mode)");
    b.move = true;
    b.g = next.motion;
    b.to = modal.position;
    b.rotary_axis = st.rotary_letter;
    b.rotary_to_deg = st.rotary_deg;
    if (b.g == 1 && next.feed_mm_per_min <= 0.0) {
      return fail(kErrUndefinedFeed, "G1 without a feed: give F in deg/min");
    }
    b.feed_mm_per_min = b.g == 1 ? next.feed_mm_per_min : rapid_mm_per_min;
    b.duration_s = std::abs(st.rotary_deg - modal.rotary_deg) / (b.feed_mm_per_min / 60.0);
    next.rotary_axis = st.rotary_letter;
    next.rotary_deg = st.rotary_deg;
  } else if (dwell) {
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

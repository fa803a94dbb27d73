// Modal state of an NC program (docs/dnc-link.md). A small reader of the words that matter to
// the link: units, distance mode, work offset, tool and length offset, spindle, coolant, feed,
// motion mode and the end point of each block. Arcs end where their X Y Z say; anything the
// reader cannot follow (G28, G30, G53, G92, inverse-time feed) marks the block unknown, and a
// tracker then does not claim to know where the tool is.
#include "gcode/dialect/program_modal.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "gcode/lexer.hpp"

namespace ncd::comms {
namespace {

// The words of one block that act after all are read.
struct BlockWords {
  std::array<std::optional<double>, 3> axis;
  std::optional<int> motion;  // 0 1 2 3, or -1 for G80
  bool dwell = false, m6 = false, known = true;
  std::optional<int> t_word;
  std::optional<double> h_word;  // -1 for a G43 without H: the tool's own length
};

void read_g(long g10, ModalState& s, BlockWords& w) {
  if (g10 == 0 || g10 == 10 || g10 == 20 || g10 == 30) {
    w.motion = static_cast<int>(g10 / 10);
  } else if (g10 == 800) {
    w.motion = -1;
  } else if (g10 == 40) {
    w.dwell = true;
  } else if (g10 == 200 || g10 == 210) {
    s.inch = g10 == 200;
  } else if (g10 == 900 || g10 == 910) {
    s.absolute = g10 == 900;
  } else if (g10 >= 540 && g10 <= 590 && g10 % 10 == 0) {
    s.work_offset = static_cast<int>(g10 / 10);
  } else if (g10 == 490) {
    s.length_offset.reset();
  } else if (g10 == 430) {
    w.h_word = w.h_word.value_or(-1.0);
  } else if (g10 == 280 || g10 == 300 || g10 == 530 || g10 == 920 || g10 == 930) {
    w.known = false;
  }
}

void read_word(char letter, double v, ModalState& s, BlockWords& w) {
  switch (letter) {
    case 'G':
      read_g(std::lround(v * 10.0), s, w);
      break;
    case 'M': {
      const long mc = std::lround(v);
      if (mc == 3 || mc == 4 || mc == 5) s.spindle = static_cast<int>(mc);
      if (mc == 6) w.m6 = true;
      if (mc == 7) s.mist = true;
      if (mc == 8) s.flood = true;
      if (mc == 9) s.mist = s.flood = false;
      break;
    }
    case 'T':
      w.t_word = static_cast<int>(std::lround(v));
      break;
    case 'H':
      w.h_word = v;
      break;
    case 'S':
      s.speed_rpm = v;
      break;
    case 'F':
      s.feed = v;
      break;
    case 'X':
    case 'Y':
    case 'Z':
      w.axis[static_cast<std::size_t>(letter - 'X')] = v;
      break;
    default:
      break;
  }
}

}  // namespace

BlockMotion ProgramModal::apply(std::string_view text) {
  BlockWords w;
  gcode::Lexer lex(text);
  for (gcode::Token t = lex.next(); t.kind != gcode::Token::Kind::End; t = lex.next()) {
    if (t.kind != gcode::Token::Kind::Word) continue;  // comments and stray characters
    if (const auto v = gcode::word_value(text, t)) {
      read_word(t.letter, *v, state_, w);
    } else {
      w.known = false;
    }
  }
  if (w.t_word) {
    if (w.m6 || !state_.tool_changed) state_.tool = w.t_word;
  }
  if (w.m6) state_.tool_changed = true;
  if (w.h_word) {
    state_.length_offset = *w.h_word >= 0.0 ? static_cast<int>(*w.h_word) : state_.tool.value_or(0);
  }
  if (w.motion) state_.motion = *w.motion;
  BlockMotion m;
  m.known = w.known;
  m.dwell = w.dwell;
  const bool has_axis = w.axis[0] || w.axis[1] || w.axis[2];
  m.from_mm = state_.position_mm;
  if (has_axis && !w.dwell && state_.motion >= 0) {
    const double unit = state_.inch ? 25.4 : 1.0;
    for (std::size_t k = 0; k < 3; ++k) {
      if (!w.axis[k]) continue;
      state_.position_mm[k] =
          state_.absolute ? *w.axis[k] * unit : state_.position_mm[k] + *w.axis[k] * unit;
    }
    m.motion = true;
  }
  m.to_mm = state_.position_mm;
  return m;
}

std::vector<std::string> restart_blocks(const ModalState& at, double clearance_z_mm,
                                        std::optional<Dialect> dialect) {
  if (!at.feed) {
    throw InputError(
        "no feed is in force at the restart block: the re-entry moves down at "
        "feed; restart from a later block, after the program's first F");
  }
  const double unit = at.inch ? 25.4 : 1.0;
  const auto x = [&](double mm) { return text::trimmed(mm / unit, 4); };
  std::vector<std::string> out;
  out.push_back("(ncd restart: the modes in force at the restart block)");
  out.push_back(std::string(at.inch ? "G20" : "G21") + " G90 G" + std::to_string(at.work_offset));
  if (at.tool) {
    out.push_back("T" + std::to_string(*at.tool) + (at.tool_changed ? " M6" : ""));
  }
  if (at.length_offset) out.push_back("G43 H" + std::to_string(*at.length_offset));
  out.push_back("G0 Z" + x(clearance_z_mm));
  if (at.spindle != 5) {
    out.push_back((at.speed_rpm ? "S" + text::trimmed(*at.speed_rpm, 4) + " " : std::string()) +
                  "M" + std::to_string(at.spindle));
  }
  if (at.mist) out.push_back("M7");
  if (at.flood) out.push_back("M8");
  const auto& p = at.position_mm;
  out.push_back("G0 X" + x(p[0]) + " Y" + x(p[1]));
  out.push_back("G1 Z" + x(p[2]) + " F" + text::trimmed(*at.feed, 4));
  std::string modes = at.absolute ? "G90" : "G91";
  if (at.motion >= 0) modes += " G" + std::to_string(at.motion);
  out.push_back(modes + " F" + text::trimmed(*at.feed, 4));
  if (dialect) {
    DialectState state;
    for (std::size_t i = 0; i < out.size(); ++i) {
      if (auto v = check_line(*dialect, out[i], state)) {
        v->line = static_cast<long>(i) + 1;
        throw InputError("the restart's line " + std::to_string(i + 1) + " '" + out[i] +
                         "' is not for a " + to_string(*dialect) +
                         " controller: " + describe(*v, *dialect) +
                         "; restart from a block where the modes in force are ones it takes");
      }
    }
  }
  return out;
}

}  // namespace ncd::comms

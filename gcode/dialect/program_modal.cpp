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

namespace ncd::comms {
BlockMotion ProgramModal::apply(std::string_view text) {
  BlockMotion m;
  std::array<std::optional<double>, 3> axis;
  std::optional<int> motion;
  bool dwell = false, m6 = false;
  std::optional<int> t_word;
  std::optional<double> h_word;
  for (std::size_t i = 0; i < text.size();) {
    const char c = text[i];
    if (c == '(') {
      const auto close = text.find(')', i);
      if (close == std::string_view::npos) break;
      i = close + 1;
      continue;
    }
    if (c == ';') break;
    if (!std::isalpha(static_cast<unsigned char>(c))) {
      ++i;
      continue;
    }
    const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    ++i;
    while (i < text.size() && (text[i] == ' ' || text[i] == '\t')) ++i;
    std::size_t j = i;
    if (j < text.size() && (text[j] == '+' || text[j] == '-')) ++j;
    while (j < text.size() &&
           (std::isdigit(static_cast<unsigned char>(text[j])) != 0 || text[j] == '.')) {
      ++j;
    }
    double v = 0.0;
    const char* first = text.data() + i;
    if (first < text.data() + j && *first == '+') ++first;
    const auto r = std::from_chars(first, text.data() + j, v);
    i = j;
    if (r.ec != std::errc()) {
      m.known = false;
      continue;
    }
    const long g10 = std::lround(v * 10.0);
    switch (letter) {
      case 'G':
        if (g10 == 0 || g10 == 10 || g10 == 20 || g10 == 30) {
          motion = static_cast<int>(g10 / 10);
        } else if (g10 == 800) {
          motion = -1;
        } else if (g10 == 40) {
          dwell = true;
        } else if (g10 == 200 || g10 == 210) {
          state_.inch = g10 == 200;
        } else if (g10 == 900 || g10 == 910) {
          state_.absolute = g10 == 900;
        } else if (g10 >= 540 && g10 <= 590 && g10 % 10 == 0) {
          state_.work_offset = static_cast<int>(g10 / 10);
        } else if (g10 == 490) {
          state_.length_offset.reset();
        } else if (g10 == 430) {
          h_word = h_word.value_or(-1.0);
        } else if (g10 == 280 || g10 == 300 || g10 == 530 || g10 == 920 || g10 == 930) {
          m.known = false;
        }
        break;
      case 'M': {
        const long mc = std::lround(v);
        if (mc == 3 || mc == 4 || mc == 5) state_.spindle = static_cast<int>(mc);
        if (mc == 6) m6 = true;
        if (mc == 7) state_.mist = true;
        if (mc == 8) state_.flood = true;
        if (mc == 9) state_.mist = state_.flood = false;
        break;
      }
      case 'T':
        t_word = static_cast<int>(std::lround(v));
        break;
      case 'H':
        h_word = v;
        break;
      case 'S':
        state_.speed_rpm = v;
        break;
      case 'F':
        state_.feed = v;
        break;
      case 'X':
      case 'Y':
      case 'Z':
        axis[static_cast<std::size_t>(letter - 'X')] = v;
        break;
      default:
        break;
    }
  }
  if (t_word) {
    if (m6 || !state_.tool_changed) state_.tool = t_word;
  }
  if (m6) state_.tool_changed = true;
  if (h_word)
    state_.length_offset = *h_word >= 0.0 ? static_cast<int>(*h_word) : state_.tool.value_or(0);
  if (motion) state_.motion = *motion;
  m.dwell = dwell;
  const bool has_axis = axis[0] || axis[1] || axis[2];
  m.from_mm = state_.position_mm;
  if (has_axis && !dwell && state_.motion >= 0) {
    const double unit = state_.inch ? 25.4 : 1.0;
    for (std::size_t k = 0; k < 3; ++k) {
      if (!axis[k]) continue;
      state_.position_mm[k] =
          state_.absolute ? *axis[k] * unit : state_.position_mm[k] + *axis[k] * unit;
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

// The RS-274/NGC interpreter: reading a line into a block. The reading and execution order is in
// interpreter.cpp.
#include "gcode/ngc/interp.hpp"

namespace ncd::toolpath::ngc {

void Interpreter::read_block(const std::string& s, std::size_t i, Block& b) {
  assigns_.clear();
  while (i < s.size()) {
    const char c = s[i];
    if (c == '#') {
      Assign a;
      ++i;
      if (i < s.size() && s[i] == '<') {
        a.name = read_name(s, i);
      } else {
        a.index = param_index(s, i);
      }
      if (i >= s.size() || s[i] != '=') fail("parameter setting without '='; write #1=2");
      ++i;
      a.value = read_value(s, i);
      assigns_.push_back(std::move(a));
      continue;
    }
    if (c == '@' || c == '^') {  // polar coordinates: @ radius, ^ angle
      ++i;
      std::optional<double>& w = c == '@' ? b.polar_radius : b.polar_angle_deg;
      if (w) fail(std::string("word ") + c + " appears twice on the line; keep one");
      w = read_value(s, i);
      continue;
    }
    if (c < 'a' || c > 'z') {
      fail("unexpected character '" + std::string(1, c) + "'; expected a word such as X1.5");
    }
    ++i;
    if (c == 'n') fail("N line number must come first on the line; move it");
    if (c == 'o') fail("an O-word must start the line (after N); put it on its own line");
    const double v = read_value(s, i);
    if (c == 'g') {
      const double scaled = v * 10.0;
      const double code = std::round(scaled);
      if (std::abs(scaled - code) > 1e-3 || code < 0 || code > 9999) {
        fail("G" + text::sig(v) + " is not a G code");
      }
      if (b.ng >= 16) fail("too many G codes on one line; split it");
      b.g[static_cast<std::size_t>(b.ng++)] = static_cast<int>(code);
      continue;
    }
    if (c == 'm') {
      const double code = std::round(v);
      if (std::abs(v - code) > 1e-3 || code < 0 || code > 9999) {
        fail("M" + text::sig(v) + " is not an M code");
      }
      if (b.nm >= 8) fail("too many M codes on one line; split it");
      b.m[static_cast<std::size_t>(b.nm++)] = static_cast<int>(code);
      continue;
    }
    if (b.has(c)) {
      fail("word " + std::string(1, static_cast<char>(c - 'a' + 'A')) +
           " appears twice on the line; keep one");
    }
    b.mask |= 1u << (c - 'a');
    b.val[static_cast<std::size_t>(c - 'a')] = v;
  }
  for (const Assign& a : assigns_) {
    if (a.index) {
      params_[static_cast<std::size_t>(a.index)] = a.value;
      param_given_[static_cast<std::size_t>(a.index)] = true;
    } else if (a.name[0] == '_') {
      globals_[a.name] = a.value;
    } else {
      frames_.back().locals[a.name] = a.value;
    }
  }
}

}  // namespace ncd::toolpath::ngc

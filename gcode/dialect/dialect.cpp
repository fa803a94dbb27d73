// Controller dialects (see dialect.hpp and docs/dnc-link.md, "Dialects"): what each takes,
// the iso and linuxcnc line checks and the program check. grbl's own model of a line is in
// grbl.cpp.
#include "gcode/dialect/dialect.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <exception>
#include <numbers>
#include <vector>

#include "core/error.hpp"
#include "gcode/dialect/dialect_detail.hpp"
#include "gcode/lexer.hpp"
#include "gcode/ngc/interpreter.hpp"

namespace ncd::comms {

using dialect_detail::kGrblKeptChars;
using dialect_detail::violation;

Dialect parse_dialect(std::string_view text) {
  if (text == "iso") return Dialect::iso;
  if (text == "grbl") return Dialect::grbl;
  if (text == "linuxcnc") return Dialect::linuxcnc;
  throw InputError("dialect '" + std::string(text) +
                   "' is unknown: use iso (Fanuc drip feed), grbl (grbl 1.1) or linuxcnc "
                   "(RS-274/NGC)");
}

const char* to_string(Dialect d) {
  switch (d) {
    case Dialect::iso:
      return "iso";
    case Dialect::grbl:
      return "grbl";
    case Dialect::linuxcnc:
      return "linuxcnc";
  }
  return "?";
}

const DialectRules& rules(Dialect d) {
  // Fields: percent, N, EOB, line length, ( ) comments, ; comments, expressions, O-words,
  // M6, G64, G43 H, a rotary axis word.
  static const DialectRules iso{true,  true,  "\n", 0,    true, false,
                                false, false, true, true, true, true};
  static const DialectRules grbl{false, false, "\n",  kGrblKeptChars, true,  true,
                                 false, false, false, false,          false, false};
  // LinuxCNC reads N numbers but needs none; `%` framing keeps rs274 from warning.
  static const DialectRules linuxcnc{true, false, "\n", 0,    true, true,
                                     true, true,  true, true, true, true};
  switch (d) {
    case Dialect::iso:
      return iso;
    case Dialect::grbl:
      return grbl;
    case Dialect::linuxcnc:
      return linuxcnc;
  }
  return linuxcnc;
}

std::string describe(const Violation& v, Dialect d) {
  std::string s;
  if (v.line > 0) s += "line " + std::to_string(v.line) + ", ";
  s += "column " + std::to_string(v.column);
  if (!v.word.empty()) s += ", '" + v.word + "'";
  s += ": " + v.reason;
  if (d == Dialect::grbl && v.grbl_error > 0) {
    s += " (grbl answers error:" + std::to_string(v.grbl_error) + ")";
  }
  s += " in the " + std::string(to_string(d)) + " dialect; " + v.way_out;
  return s;
}

// ---- iso and linuxcnc ----

namespace {

// A word of the ISO common set: a letter and one number with at most one point.
std::optional<Violation> check_iso_word(std::string_view line, const gcode::Token& t) {
  const std::size_t run_end = gcode::number_run_end(line, t);
  const std::string_view run = line.substr(t.number_at, run_end - t.number_at);
  const auto points = std::count(run.begin(), run.end(), '.');
  if (t.digits && points <= 1) return std::nullopt;
  return violation(t.column(), std::string(line.substr(t.at, run_end - t.at)), 0,
                   points > 1 ? "a number with two points" : "an address without a number",
                   "write each word as a letter and one number, e.g. X10.5");
}

std::optional<Violation> check_iso_line(std::string_view raw) {
  std::string_view line = raw;
  while (!line.empty() && (line.back() == '\r' || line.back() == '\n')) line.remove_suffix(1);
  std::size_t first = line.find_first_not_of(" \t");
  if (first == std::string_view::npos || line.substr(first) == "%") return std::nullopt;
  gcode::Lexer lex(line);
  for (gcode::Token t = lex.next(); t.kind != gcode::Token::Kind::End; t = lex.next()) {
    if (t.kind == gcode::Token::Kind::Comment && !t.semicolon) {
      if (!t.closed)
        return violation(t.column(), "(", 0, "a comment without its ')'", "close the comment");
      continue;
    }
    if (t.kind == gcode::Token::Kind::Word) {
      if (auto v = check_iso_word(line, t)) return v;
      continue;
    }
    const char c = line[t.at];
    if (c == '/' && t.at == first) continue;  // block delete
    const char* why = c == '#' || c == '[' || c == ']' || c == '='
                          ? "variables and expressions (Custom Macro B) are not in the ISO "
                            "drip-feed common set"
                      : c == ';' ? "';' is how a listing shows the end of block; ISO code ends "
                                   "a block with LF"
                                 : "a character that is not an address, a number or a comment";
    return violation(t.column(), std::string(1, c), 0, why,
                     "write the program with plain words (the ncd writer's iso dialect)");
  }
  return std::nullopt;
}

std::optional<Violation> check_serial_chars(std::string_view line) {
  for (std::size_t i = 0; i < line.size(); ++i) {
    const auto c = static_cast<unsigned char>(line[i]);
    if ((c < ' ' && c != '\t' && c != '\r') || c >= 0x7F) {
      return violation(static_cast<int>(i) + 1, "", 0,
                       "a control or non-ASCII character (code " + std::to_string(c) + ")",
                       "remove it; the link carries printable ASCII");
    }
  }
  return std::nullopt;
}

}  // namespace

std::optional<Violation> check_line(Dialect d, std::string_view line, DialectState& state) {
  switch (d) {
    case Dialect::grbl:
      return check_grbl_line(line, state.grbl);
    case Dialect::iso:
      if (auto v = check_serial_chars(line)) return v;
      return check_iso_line(line);
    case Dialect::linuxcnc:
      return check_serial_chars(line);
  }
  return std::nullopt;
}

std::optional<Violation> check_program(Dialect d, std::string_view text) {
  DialectState state;
  long number = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find_first_of("\r\n", pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line = text.substr(pos, end - pos);
    ++number;
    if (auto v = check_line(d, line, state)) {
      v->line = number;
      return v;
    }
    pos = end;
    if (pos < text.size() && text[pos] == '\r') {
      ++pos;
      if (pos < text.size() && text[pos] == '\n') ++pos;
    } else if (pos < text.size()) {
      ++pos;
    }
  }
  if (d == Dialect::linuxcnc) {
    try {
      (void)toolpath::interpret_ngc(std::string(text), "program");
    } catch (const std::exception& e) {
      Violation v;
      v.reason = e.what();
      v.way_out = "correct the program until `ncd check` accepts it";
      return v;
    }
  }
  return std::nullopt;
}

}  // namespace ncd::comms
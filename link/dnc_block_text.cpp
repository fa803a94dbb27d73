// The small text helpers of the DNC sender (dnc_block_text.hpp).
#include "link/dnc_block_text.hpp"

#include <cctype>
#include <charconv>
#include <limits>

#include "gcode/lexer.hpp"

namespace ncd::comms::dnc_detail {

// The first token is an N word whose digits follow the letter at once (the lexer,
// gcode/lexer.hpp, reads the words).
bool starts_with_n_word(const std::string& text) {
  const gcode::Token t = gcode::Lexer(text).next();
  return t.kind == gcode::Token::Kind::Word && t.letter == 'N' && t.number_at == t.at + 1 &&
         t.number_at < text.size() && std::isdigit(static_cast<unsigned char>(text[t.number_at]));
}

std::optional<long> n_word(const std::string& text) {
  if (!starts_with_n_word(text)) return std::nullopt;
  const auto p = text.find_first_not_of(" \t") + 1;
  long v = 0;
  const auto r = std::from_chars(text.data() + p, text.data() + text.size(), v);
  if (r.ec != std::errc()) return std::nullopt;
  return v;
}

// The words in order (the lexer); G4's P is its seconds (RS-274/NGC, Fanuc with a decimal
// point). A block with G4 and no P, or a P without G4, waits nothing.
double wait_of_block(std::string_view text, double tool_change_s) {
  gcode::Lexer lex(text);
  bool dwell = false;
  double p_s = 0.0, wait_s = 0.0;
  for (gcode::Token t = lex.next(); t.kind != gcode::Token::Kind::End; t = lex.next()) {
    if (t.kind != gcode::Token::Kind::Word) continue;
    const std::optional<double> v = gcode::word_value(text, t);
    if (!v) continue;
    if (t.letter == 'G' && *v == 4.0) dwell = true;
    if (t.letter == 'P') p_s = *v;
    if (t.letter == 'M' && *v == 6.0) wait_s += tool_change_s;
    if (t.letter == 'M' && (*v == 0.0 || *v == 1.0 || *v == 60.0)) {
      wait_s = std::numeric_limits<double>::infinity();
    }
  }
  if (dwell && p_s > 0.0) wait_s += p_s;
  return wait_s;
}

// A `;` that grbl reads as a comment to the end of the line (not inside `( )`).
bool has_semicolon_comment(std::string_view text) {
  return gcode::has_semicolon_comment(text);
}

}  // namespace ncd::comms::dnc_detail

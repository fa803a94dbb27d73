// The small text helpers of the DNC sender (dnc_block_text.hpp).
#include "link/dnc_block_text.hpp"

#include <cctype>
#include <charconv>

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

// A `;` that grbl reads as a comment to the end of the line (not inside `( )`).
bool has_semicolon_comment(std::string_view text) {
  return gcode::has_semicolon_comment(text);
}

}  // namespace ncd::comms::dnc_detail

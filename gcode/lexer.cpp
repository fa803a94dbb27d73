// The one G-code lexer (the rules at the top of lexer.hpp).
#include "gcode/lexer.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <system_error>

namespace ncd::gcode {

namespace {

bool is_digit(char c) {
  return c >= '0' && c <= '9';
}

// Past the digits from i.
std::size_t skip_digits(std::string_view s, std::size_t i, bool& any) {
  while (i < s.size() && is_digit(s[i])) {
    ++i;
    any = true;
  }
  return i;
}

Token comment(std::string_view s, std::size_t at) {
  Token t;
  t.kind = Token::Kind::Comment;
  t.at = at;
  if (s[at] == ';') {
    t.semicolon = true;
    t.text = s.substr(at + 1);
    t.end = s.size();
    return t;
  }
  const std::size_t close = s.find(')', at + 1);
  t.closed = close != std::string_view::npos;
  t.end = t.closed ? close + 1 : s.size();
  t.text = s.substr(at + 1, (t.closed ? close : s.size()) - at - 1);
  t.nested = t.text.find('(') != std::string_view::npos;
  return t;
}

Token word(std::string_view s, std::size_t at) {
  Token t;
  t.kind = Token::Kind::Word;
  t.at = at;
  t.letter = static_cast<char>(std::toupper(static_cast<unsigned char>(s[at])));
  std::size_t i = at + 1;
  while (i < s.size() && is_blank(s[i])) ++i;
  t.number_at = i;
  if (i < s.size() && (s[i] == '+' || s[i] == '-')) ++i;
  i = skip_digits(s, i, t.digits);
  if (i < s.size() && s[i] == '.') i = skip_digits(s, i + 1, t.digits);
  t.end = i;
  return t;
}

}  // namespace

bool is_blank(char c) {
  return c == ' ' || c == '\t';
}

Token Lexer::next() {
  while (i_ < line_.size() && is_blank(line_[i_])) ++i_;
  Token t;
  if (i_ >= line_.size()) {
    t.at = t.end = line_.size();
    return t;
  }
  const char c = line_[i_];
  if (c == '(' || c == ';') {
    t = comment(line_, i_);
  } else if (std::isalpha(static_cast<unsigned char>(c)) != 0) {
    t = word(line_, i_);
  } else {
    t.kind = Token::Kind::Char;
    t.at = i_;
    t.end = i_ + 1;
  }
  i_ = t.end;
  return t;
}

std::optional<double> word_value(std::string_view line, const Token& word) {
  if (!word.digits) return std::nullopt;
  const char* first = line.data() + word.number_at;
  const char* last = line.data() + word.end;
  if (*first == '+') ++first;
  double v = 0.0;
  const auto r = std::from_chars(first, last, v);
  if (r.ec != std::errc() || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::size_t number_run_end(std::string_view line, const Token& word) {
  std::size_t j = word.number_at;
  if (j < line.size() && (line[j] == '+' || line[j] == '-')) ++j;
  while (j < line.size() && (is_digit(line[j]) || line[j] == '.')) ++j;
  return j;
}

bool has_semicolon_comment(std::string_view line) {
  Lexer lex(line);
  for (Token t = lex.next(); t.kind != Token::Kind::End; t = lex.next()) {
    if (t.kind == Token::Kind::Comment && t.semicolon) return true;
  }
  return false;
}

}  // namespace ncd::gcode

// The RS-274/NGC interpreter: O-word scanning: subroutines and the labels of control flow. The
// reading and execution order is in interpreter.cpp.
#include "gcode/ngc/interp.hpp"

namespace ncd::toolpath::ngc {

// The normalised text of a line (lower case, no blanks, comments out; the lexer, gcode/lexer.hpp,
// says what a comment is) into `out`; the last '( )' comment's text into `comment`. LinuxCNC
// refuses a comment without its ')' and a '(' inside a comment.
void Interpreter::normalise(std::string_view line, std::string& out, std::string* comment,
                            bool* has_comment) {
  const auto blank = [](char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
  };
  const auto lower = [](char c) {
    return c >= 'A' && c <= 'Z' ? static_cast<char>(c - 'A' + 'a') : c;
  };
  // Without '(' or ';' a line has no comment, and the lexer's tokens would cover every
  // character but the blanks: the same text in one pass (most lines of long programs).
  out.resize(line.size());
  std::size_t n = 0;
  bool commented = false;
  for (const char c : line) {
    if (c == '(' || c == ';') {
      commented = true;
      break;
    }
    if (!blank(c)) out[n++] = lower(c);
  }
  out.resize(commented ? 0 : n);
  if (!commented) return;
  gcode::Lexer lex(line);
  for (gcode::Token t = lex.next(); t.kind != gcode::Token::Kind::End; t = lex.next()) {
    if (t.kind == gcode::Token::Kind::Comment) {
      if (t.semicolon) break;
      if (!t.closed) fail("comment '(' is not closed on this line; add ')'");
      if (t.nested) fail("nested '(' inside a comment; remove the inner '('");
      if (comment) {
        *comment = std::string(t.text);
        *has_comment = true;
      }
      continue;
    }
    for (std::size_t i = t.at; i < t.end; ++i) {
      if (!blank(line[i])) out.push_back(lower(line[i]));
    }
  }
}

// O-word of a normalised line (after an optional '/' and N number), or false.
bool Interpreter::parse_oline(const std::string& s, OLine& o) {
  std::size_t i = 0;
  if (i < s.size() && s[i] == '/') ++i;
  if (i < s.size() && s[i] == 'n') {
    ++i;
    while (i < s.size() && (std::isdigit(static_cast<unsigned char>(s[i])) || s[i] == '.')) ++i;
  }
  if (i >= s.size() || s[i] != 'o') return false;
  ++i;
  if (i < s.size() && s[i] == '<') {
    const std::size_t close = s.find('>', i);
    if (close == std::string::npos) fail("O-word name without a closing '>'; write o<name>");
    o.label = s.substr(i + 1, close - i - 1);
    i = close + 1;
  } else {
    const std::size_t b = i;
    while (i < s.size() && std::isdigit(static_cast<unsigned char>(s[i]))) ++i;
    if (i == b) fail("O-word without a number or <name>; write o100 or o<name>");
    // The number as written without its leading zeros (o010 is o10); any length.
    std::size_t z = b;
    while (z + 1 < i && s[z] == '0') ++z;
    o.label = s.substr(z, i - z);
  }
  const std::size_t kb = i;
  while (i < s.size() && std::isalpha(static_cast<unsigned char>(s[i]))) ++i;
  o.keyword = s.substr(kb, i - kb);
  o.args_at = i;
  return true;
}

bool Interpreter::oline_at(std::size_t file, std::size_t line, OLine& o) {
  const std::string_view l = files_[file]->lines[line];
  std::size_t i = 0;
  while (i < l.size() && (l[i] == ' ' || l[i] == '\t')) ++i;
  if (i >= l.size()) return false;
  const char c = l[i];
  if (c != 'o' && c != 'O' && c != 'n' && c != 'N' && c != '/') return false;
  std::string s;
  normalise(l, s, nullptr, nullptr);
  return parse_oline(s, o);
}

// Subroutine definitions of a file: label → line of its "sub".
void Interpreter::scan_subs(std::size_t file) {
  const auto& lines = files_[file]->lines;
  OLine o;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    try {
      if (oline_at(file, i, o) && o.keyword == "sub") subs_.try_emplace(o.label, file, i);
    } catch (const Fail&) {
      // reported when the line is executed
    }
  }
}

// Next line after `from` in the current file with `label` and one of the keywords.
std::size_t Interpreter::seek(const std::string& label, std::initializer_list<const char*> keywords,
                              std::string& found) {
  const auto& lines = files_[cur_file_]->lines;
  OLine o;
  for (std::size_t i = cur_line_ + 1; i < lines.size(); ++i) {
    if (!oline_at(cur_file_, i, o) || o.label != label) continue;
    for (const char* k : keywords) {
      if (o.keyword == k) {
        found = o.keyword;
        return i;
      }
    }
  }
  std::string list;
  for (const char* k : keywords) list += std::string(list.empty() ? "" : " or ") + k;
  fail("o" + label + " has no matching " + list + " after it in the file; add it");
}

}  // namespace ncd::toolpath::ngc

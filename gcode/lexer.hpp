// The one G-code lexer: how every reader in ncd splits a line into words and comments.
//
// RS-274/NGC (LinuxCNC), ISO 6983, Fanuc and grbl agree on the lexical layer of a line:
//  - '(' opens a comment that the first ')' closes. A '(' without its ')' runs to the end of
//    the line; a '(' inside a comment is a nested one. Readers differ in whether either is an
//    error (LinuxCNC: both are; grbl and the simulated controller ignore the rest of the line).
//  - ';' outside a '( )' comment makes the rest of the line a comment.
//  - A word is a letter, optional blanks (space, tab), and a number: [+-] digits [. digits],
//    with at least one digit. A second point ends the number; what follows is the next token.
//  - Anything else outside a comment is a character of its own: a digit or point without a
//    letter, '#', '[', '=', '/', '%', a control character.
// The tokens come in order, blanks between them skipped, with their offsets in the line, so a
// reader can name the column of what it refuses.
//
// What the readers do with the tokens stays theirs, because the controllers differ there:
// LinuxCNC reads expressions and parameters where a number may stand (gcode/ngc/read.cpp,
// expressions.cpp); grbl keeps at most 79 characters and reads numbers as its read_float does
// (gcode/dialect/grbl.cpp); the ISO check refuses what the ISO common set lacks
// (gcode/dialect/dialect.cpp); the link's modal tracker (gcode/dialect/program_modal.cpp), the
// DNC sender (link/) and the simulated controller (sim/) read plain words.
#pragma once

#include <cstddef>
#include <optional>
#include <string_view>

namespace ncd::gcode {

// One token of a line.
struct Token {
  enum class Kind { Word, Comment, Char, End };
  Kind kind = Kind::End;
  std::size_t at = 0;   // offset of its first character in the line (the letter, '(' or ';')
  std::size_t end = 0;  // offset just past it

  // Word: the letter raised to upper case, and its number [number_at, end): sign, digits, at
  // most one point. `digits` is false when no digit was read (a letter without a number).
  char letter = 0;
  std::size_t number_at = 0;
  bool digits = false;

  // Comment: its text between the delimiters.
  std::string_view text;
  bool semicolon = false;  // ';' to the end of the line, else '( )'
  bool closed = true;      // false: a '(' without ')', which runs to the end of the line
  bool nested = false;     // a '(' inside this '( )' comment

  int column() const { return static_cast<int>(at) + 1; }  // 1-based, for messages
};

class Lexer {
 public:
  explicit Lexer(std::string_view line) : line_(line) {}

  // The next token after blanks; Kind::End at the end of the line.
  Token next();

  std::string_view line() const { return line_; }

 private:
  std::string_view line_;
  std::size_t i_ = 0;
};

bool is_blank(char c);  // space or tab: what separates tokens

// The number of a word, or nullopt if it has no digit or is too large for a double.
std::optional<double> word_value(std::string_view line, const Token& word);

// The end of the run of digits and points after a word's sign: past a second point, for
// readers that name the whole malformed number ("X1.2.3").
std::size_t number_run_end(std::string_view line, const Token& word);

// True if the line has a ';' comment (outside any '( )').
bool has_semicolon_comment(std::string_view line);

}  // namespace ncd::gcode

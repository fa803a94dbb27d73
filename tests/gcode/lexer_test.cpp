// The one G-code lexer (gcode/lexer.hpp): worked lines, and a random sweep against a second
// lexer written as regular expressions (the rules of the header, one pattern each).
#include "gcode/lexer.hpp"

#include <gtest/gtest.h>

#include <random>
#include <regex>
#include <string>
#include <vector>

#include "tests/common/seed.hpp"

namespace ncd::gcode {
namespace {

using Kind = Token::Kind;

std::vector<Token> tokens(std::string_view line) {
  std::vector<Token> out;
  Lexer lex(line);
  for (Token t = lex.next(); t.kind != Kind::End; t = lex.next()) out.push_back(t);
  return out;
}

TEST(Lexer, SplitsAWorkedLineIntoWordsAndComments) {
  const std::string line = "n10 G1 x -1.5 (feed in) Y.5;rest (not a comment)";
  const auto t = tokens(line);
  ASSERT_EQ(t.size(), 6u);
  EXPECT_EQ(t[0].letter, 'N');
  EXPECT_EQ(word_value(line, t[0]), 10.0);
  EXPECT_EQ(t[1].letter, 'G');
  EXPECT_EQ(t[2].letter, 'X');
  EXPECT_EQ(t[2].column(), 8);
  EXPECT_EQ(word_value(line, t[2]), -1.5);
  EXPECT_EQ(t[3].kind, Kind::Comment);
  EXPECT_EQ(t[3].text, "feed in");
  EXPECT_FALSE(t[3].semicolon);
  EXPECT_EQ(word_value(line, t[4]), 0.5);
  EXPECT_TRUE(t[5].semicolon);
  EXPECT_EQ(t[5].text, "rest (not a comment)");
  EXPECT_TRUE(has_semicolon_comment(line));
  EXPECT_FALSE(has_semicolon_comment("G1 (a ; inside) X1"));
}

TEST(Lexer, AnUnclosedCommentRunsToTheEndAndANestedOneIsMarked) {
  auto t = tokens("G0 (open ; X1");
  ASSERT_EQ(t.size(), 2u);
  EXPECT_FALSE(t[1].closed);
  EXPECT_EQ(t[1].text, "open ; X1");
  EXPECT_FALSE(has_semicolon_comment("G0 (open ; X1"));
  t = tokens("(a (b) X1");
  ASSERT_EQ(t.size(), 2u);
  EXPECT_TRUE(t[0].closed);
  EXPECT_TRUE(t[0].nested);
  EXPECT_EQ(t[1].letter, 'X');
}

TEST(Lexer, ASecondPointEndsTheNumberAndALetterWithoutDigitsHasNoValue) {
  const std::string line = "X1.2.3 Y+-4 Z. F1e5";
  const auto t = tokens(line);
  ASSERT_EQ(t.size(), 9u);
  EXPECT_EQ(word_value(line, t[0]), 1.2);
  EXPECT_EQ(t[1].kind, Kind::Char);  // the second point
  EXPECT_EQ(t[2].kind, Kind::Char);  // 3
  EXPECT_EQ(number_run_end(line, t[0]), 6u);
  EXPECT_EQ(t[3].letter, 'Y');
  EXPECT_FALSE(t[3].digits);
  EXPECT_EQ(word_value(line, t[3]), std::nullopt);
  EXPECT_EQ(line[t[4].at], '-');
  EXPECT_FALSE(t[6].digits);  // Z.
  EXPECT_EQ(word_value(line, t[7]), 1.0);
  EXPECT_EQ(t[8].letter, 'E');
  const std::string huge = "X1" + std::string(400, '0');
  EXPECT_EQ(word_value(huge, tokens(huge)[0]), std::nullopt);
}

// The second lexer: at each position after blanks, the first of these patterns that matches.
struct RegexToken {
  Kind kind;
  std::size_t at, end;
};

std::vector<RegexToken> regex_tokens(const std::string& line) {
  static const std::regex comment(R"(\([^)]*\)?|;[\s\S]*)");
  static const std::regex word(R"([A-Za-z][ \t]*[+-]?[0-9]*(\.[0-9]*)?)");
  std::vector<RegexToken> out;
  std::size_t i = 0;
  while (true) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i >= line.size()) return out;
    std::smatch m;
    const auto from = line.begin() + static_cast<std::ptrdiff_t>(i);
    const auto flags = std::regex_constants::match_continuous;
    Kind kind = Kind::Char;
    std::size_t length = 1;
    if (std::regex_search(from, line.end(), m, comment, flags)) {
      kind = Kind::Comment;
      length = static_cast<std::size_t>(m.length(0));
    } else if (std::regex_search(from, line.end(), m, word, flags)) {
      kind = Kind::Word;
      length = static_cast<std::size_t>(m.length(0));
    }
    out.push_back({kind, i, i + length});
    i += length;
  }
}

TEST(Lexer, AgreesWithARegularExpressionLexerOnRandomLines) {
  std::mt19937_64 rng(test::seed());
  const std::string alphabet = "GXYZNgxz0123456789.+- \t();#[]=/%\r";
  std::uniform_int_distribution<std::size_t> pick(0, alphabet.size() - 1), length(0, 24);
  for (int n = 0; n < 20000; ++n) {
    std::string line;
    for (std::size_t k = length(rng); k > 0; --k) line += alphabet[pick(rng)];
    const auto got = tokens(line);
    const auto want = regex_tokens(line);
    ASSERT_EQ(got.size(), want.size()) << "line '" << line << "'";
    for (std::size_t k = 0; k < got.size(); ++k) {
      ASSERT_EQ(got[k].kind, want[k].kind) << "line '" << line << "', token " << k;
      ASSERT_EQ(got[k].at, want[k].at) << "line '" << line << "', token " << k;
      ASSERT_EQ(got[k].end, want[k].end) << "line '" << line << "', token " << k;
    }
  }
}

}  // namespace
}  // namespace ncd::gcode

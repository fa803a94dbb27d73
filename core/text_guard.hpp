// Checks on configuration text before a third-party parser sees it (docs/input-ranges.md,
// "Text checks"). toml11 3.7.1 reads past the end of its buffer on a literal string holding
// invalid UTF-8 (`device = '\xFF'`), and both toml11 and JSON parsers recurse (or their callers
// do) once per nesting level, so 100 000 opening brackets overflow the stack. The text is
// therefore checked here, in one pass, without recursion:
//   - it is well-formed UTF-8 (RFC 3629: no overlong forms, no surrogates, nothing above
//     U+10FFFF) and holds no NUL byte;
//   - for TOML, brackets '[' '{' outside strings and comments nest at most kMaxNestingDepth
//     deep, and a dotted key has at most kMaxNestingDepth parts.
// A failure is an InputError naming the file, the line, the column and the byte offset.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include "core/error.hpp"

namespace ncd {

// Deepest nesting of arrays, inline tables or objects (and longest dotted key) read anywhere.
inline constexpr int kMaxNestingDepth = 64;

// "NAME: line L, column C (byte offset B)" of a byte offset into text (1-based line and column,
// columns counted in bytes; 0-based offset).
inline std::string text_position(std::string_view text, std::size_t offset,
                                 const std::string& name) {
  std::size_t line = 1, line_start = 0;
  for (std::size_t i = 0; i < offset && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      line_start = i + 1;
    }
  }
  return name + ": line " + std::to_string(line) + ", column " +
         std::to_string(offset - line_start + 1) + " (byte offset " + std::to_string(offset) + ")";
}

// Offset of the first byte that is not part of well-formed UTF-8, or of the first NUL byte;
// npos when the whole text is valid. `nul` tells which of the two was found.
inline std::size_t find_bad_utf8(std::string_view text, bool& nul) {
  nul = false;
  const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(text[i]); };
  const std::size_t n = text.size();
  std::size_t i = 0;
  while (i < n) {
    const unsigned char c = byte(i);
    if (c == 0) {
      nul = true;
      return i;
    }
    if (c < 0x80) {
      ++i;
      continue;
    }
    std::size_t len = 0;
    unsigned char lo = 0x80, hi = 0xBF;  // allowed range of the second byte
    if (c >= 0xC2 && c <= 0xDF) {
      len = 2;
    } else if (c >= 0xE0 && c <= 0xEF) {
      len = 3;
      if (c == 0xE0) lo = 0xA0;  // no overlong forms
      if (c == 0xED) hi = 0x9F;  // no surrogates U+D800..U+DFFF
    } else if (c >= 0xF0 && c <= 0xF4) {
      len = 4;
      if (c == 0xF0) lo = 0x90;  // no overlong forms
      if (c == 0xF4) hi = 0x8F;  // nothing above U+10FFFF
    } else {
      return i;  // a continuation byte without a lead, 0xC0, 0xC1 or 0xF5..0xFF
    }
    if (i + len > n) return i;
    if (byte(i + 1) < lo || byte(i + 1) > hi) return i;
    for (std::size_t k = 2; k < len; ++k) {
      if (byte(i + k) < 0x80 || byte(i + k) > 0xBF) return i;
    }
    i += len;
  }
  return std::string_view::npos;
}

// Throws InputError unless text is valid UTF-8 without NUL bytes. `kind` names the format
// ("machine file", "service config") for the way out.
inline void require_utf8_text(std::string_view text, const std::string& name,
                              const std::string& kind) {
  bool nul = false;
  const std::size_t at = find_bad_utf8(text, nul);
  if (at == std::string_view::npos) return;
  if (nul) {
    throw InputError(text_position(text, at, name) + ": a NUL byte; a " + kind +
                     " is text: remove it (is this a binary file?)");
  }
  char hex[8];
  static const char* digits = "0123456789ABCDEF";
  const auto b = static_cast<unsigned char>(text[at]);
  hex[0] = '0';
  hex[1] = 'x';
  hex[2] = digits[b >> 4];
  hex[3] = digits[b & 15];
  hex[4] = '\0';
  throw InputError(text_position(text, at, name) + ": byte " + hex + " is not valid UTF-8; a " +
                   kind + " must be UTF-8 text: re-save it as UTF-8 or remove the character");
}

// Offset of the first '[' or '{' of a TOML text that opens nesting level max_depth + 1, or of
// the key part that makes a dotted key longer than max_depth parts; npos when none. Strings
// (basic, literal, multi-line) and comments are skipped, so brackets inside them do not count.
// A table header [a] or [[a]] counts as one or two levels, which stays far below the limit.
inline std::size_t find_toml_too_deep(std::string_view t, int max_depth) {
  const std::size_t n = t.size();
  int depth = 0;
  int key_parts = 1;  // dots seen since the last newline, ',', '{' or '=', plus one
  const auto starts = [&](std::size_t i, std::string_view s) { return t.substr(i, s.size()) == s; };
  for (std::size_t i = 0; i < n; ++i) {
    const char c = t[i];
    if (c == '#') {
      while (i + 1 < n && t[i + 1] != '\n') ++i;
      continue;
    }
    if (c == '"' || c == '\'') {
      const std::string_view triple = c == '"' ? "\"\"\"" : "'''";
      const bool multi = starts(i, triple);
      i += multi ? 3 : 1;
      for (; i < n; ++i) {
        if (c == '"' && t[i] == '\\') {
          ++i;  // an escape: the next byte is not the end of the string
          continue;
        }
        if (!multi && t[i] == '\n') {
          --i;  // an unterminated string: the parser reports it; the newline is read again
          break;
        }
        if (t[i] == c && (!multi || starts(i, triple))) {
          if (multi) i += 2;
          break;
        }
      }
      continue;
    }
    if (c == '[' || c == '{') {
      if (++depth > max_depth) return i;
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    } else if (c == '.' && ++key_parts > max_depth) {
      return i;  // a dotted key (a float has one dot, a date none)
    }
    if (c == '\n' || c == ',' || c == '{' || c == '=') key_parts = 1;
  }
  return std::string_view::npos;
}

// Throws InputError when find_toml_too_deep() finds something.
inline void require_toml_depth(std::string_view text, const std::string& name) {
  const std::size_t at = find_toml_too_deep(text, kMaxNestingDepth);
  if (at == std::string_view::npos) return;
  throw InputError(text_position(text, at, name) + ": nesting or a dotted key deeper than " +
                   std::to_string(kMaxNestingDepth) +
                   " levels; ncd reads at most that many, flatten the value");
}

}  // namespace ncd

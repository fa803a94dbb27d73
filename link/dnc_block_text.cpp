// The small text helpers of the DNC sender (dnc_block_text.hpp).
#include "link/dnc_block_text.hpp"

#include <cctype>
#include <charconv>

namespace ncd::comms::dnc_detail {

bool starts_with_n_word(const std::string& text) {
  const auto p = text.find_first_not_of(" \t");
  return p != std::string::npos && (text[p] == 'N' || text[p] == 'n') && p + 1 < text.size() &&
         std::isdigit(static_cast<unsigned char>(text[p + 1])) != 0;
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
  bool paren = false;
  for (const char c : text) {
    if (paren) {
      paren = c != ')';
    } else if (c == '(') {
      paren = true;
    } else if (c == ';') {
      return true;
    }
  }
  return false;
}

}  // namespace ncd::comms::dnc_detail
